"""Reading grey images: 8- and 16-bit TIFF and PNG, and camera masks.

TIFF files are read by tifffile (any integer or real grey image); PNG files by OpenCV,
unchanged (8 or 16 bits). A colour image is refused: a PTV camera records grey levels.
Errors name the file.
"""

from pathlib import Path

import cv2
import numpy as np
import tifffile

from ptv.errors import DatasetError

__all__ = ["ImageError", "read_image", "read_mask"]

#: File suffixes read, lower case.
SUFFIXES = (".tif", ".tiff", ".png")


class ImageError(DatasetError):
    """An image file that cannot be used (the message names the file)."""


def read_image(path: str | Path) -> np.ndarray:
    """A grey image, shape (H, W), as stored (DN).

    Parameters
    ----------
    path : path-like
        A ``.tif``, ``.tiff`` or ``.png`` file.

    Returns
    -------
    ndarray, shape (H, W)
        Grey levels, DN, in the file's type (8- or 16-bit integers, or reals for TIFF).

    Raises
    ------
    FileNotFoundError
        No such file.
    ImageError
        An unknown suffix, an unreadable file, or not a 2-D grey image.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> import numpy as np
    >>> import tifffile
    >>> import ptv
    >>> tmp = tempfile.TemporaryDirectory()
    >>> path = pathlib.Path(tmp.name) / "frame.tif"
    >>> tifffile.imwrite(path, np.arange(12, dtype=np.uint16).reshape(3, 4))
    >>> image = ptv.read_image(path)
    >>> image.shape, image.dtype, int(image[2, 3])  # (H, W), as stored, DN
    ((3, 4), dtype('uint16'), 11)
    >>> tmp.cleanup()
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"image {path} is missing")
    suffix = path.suffix.lower()
    if suffix not in SUFFIXES:
        raise ImageError(f"{path}: images must be TIFF or PNG ({', '.join(SUFFIXES)})")
    try:
        if suffix == ".png":
            image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
            if image is None:
                raise ValueError("OpenCV could not decode it")
        else:
            image = tifffile.imread(path)
    except Exception as err:  # the readers raise many kinds on a corrupt file
        kind = "PNG" if suffix == ".png" else "TIFF"
        raise ImageError(f"{path}: not readable as a {kind} image ({err})") from None
    if image.ndim != 2:
        raise ImageError(f"{path}: expected a 2-D grey image, got shape {image.shape}")
    return image


def read_mask(path: str | Path, shape: tuple[int, int]) -> np.ndarray:
    """A camera mask: True where the image is used (pixels ≠ 0), shape ``shape`` (H, W).

    Raises
    ------
    ImageError
        The mask is not of the camera's size, or masks out every pixel.
    """
    mask = read_image(path) != 0
    if mask.shape != tuple(shape):
        raise ImageError(
            f"{path}: mask of {mask.shape[1]} × {mask.shape[0]} px, but the camera's images "
            f"are {shape[1]} × {shape[0]} px"
        )
    if not mask.any():
        raise ImageError(f"{path}: the mask is 0 everywhere: nothing would be detected")
    return mask
