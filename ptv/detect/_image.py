"""Validation of the images and options handed to the detector (private)."""

import numpy as np

#: dtypes the compiled kernels take as they are (one compilation each); other real
#: dtypes are converted: unsigned integers up to 16 bits to uint16, the rest to float64.
KERNEL_DTYPES = (np.uint16, np.float64)


def check_image(image: object, name: str = "image") -> np.ndarray:
    """Return ``image`` as a C-contiguous 2-D array of a kernel dtype, or raise ValueError.

    Parameters
    ----------
    image : array_like, shape (H, W)
        Camera image: unsigned or signed integers (digital numbers) or floats.
        uint16 and float64 are used as they are, uint8 becomes uint16 and every other
        real dtype becomes float64 (exactly, except 64-bit integers beyond 2⁵³).
    name : str
        Name used in error messages.

    Returns
    -------
    ndarray, shape (H, W)
        The image, not copied when it already has a kernel dtype and is contiguous.

    Raises
    ------
    ValueError
        Not 2-D, no pixels, a non-real dtype (bool, complex, object, strings), or a
        NaN or infinite pixel (the first one is named).
    """
    arr = np.asarray(image)
    if arr.ndim != 2:
        raise ValueError(
            f"{name} must be a 2-D array (rows, columns), got ndim={arr.ndim} "
            f"with shape {arr.shape}"
        )
    if arr.size == 0:
        raise ValueError(f"{name} is empty: shape {arr.shape} has no pixels")
    dt = arr.dtype
    if dt == np.bool_ or not (np.issubdtype(dt, np.integer) or np.issubdtype(dt, np.floating)):
        raise ValueError(f"{name} must hold real numbers (integers or floats), got dtype {dt}")
    if np.issubdtype(dt, np.floating):
        if not (np.isfinite(arr.min()) and np.isfinite(arr.max())):  # NaN propagates
            bad = ~np.isfinite(arr)
            r, c = np.unravel_index(int(np.flatnonzero(bad)[0]), arr.shape)
            raise ValueError(
                f"{name} must be finite; {int(bad.sum())} pixel(s) are NaN or infinite, "
                f"first at (row {r}, column {c}): {arr[r, c]!r}"
            )
    if dt in (np.uint8, np.uint16):
        return np.ascontiguousarray(arr, dtype=np.uint16)
    return np.ascontiguousarray(arr, dtype=np.float64)


def default_saturation(dtype: np.dtype) -> float:
    """Saturation level implied by a dtype: its maximum for integers, +inf for floats."""
    if np.issubdtype(dtype, np.integer):
        return float(np.iinfo(dtype).max)
    return float("inf")


def check_number(name: str, value: object, *, low: float, strict: bool = False) -> float:
    """``value`` as a float, if a finite number ≥ ``low`` (> where ``strict``), else a
    ValueError naming ``name``."""
    ok = isinstance(value, int | float | np.integer | np.floating) and not isinstance(value, bool)
    if ok and np.isfinite(value) and (value > low or (not strict and value == low)):
        return float(value)
    bound = f"> {low:g}" if strict else f">= {low:g}"
    raise ValueError(f"{name} must be a finite number {bound}, got {value!r}")


def check_integer(name: str, value: object, *, low: int) -> int:
    """``value`` as an int, if an integer ≥ ``low``, else a ValueError naming ``name``."""
    if isinstance(value, int | np.integer) and not isinstance(value, bool) and value >= low:
        return int(value)
    raise ValueError(f"{name} must be an integer >= {low}, got {value!r}")


def saturation_level(saturation: float | None, dtype: np.dtype) -> float:
    """The level of a saturated pixel: ``saturation``, or the dtype's default."""
    if saturation is None:
        return default_saturation(dtype)
    if (
        isinstance(saturation, int | float | np.integer | np.floating)
        and not isinstance(saturation, bool)
        and not np.isnan(saturation)
    ):
        return float(saturation)
    raise ValueError(f"saturation must be a number or None, got {saturation!r}")
