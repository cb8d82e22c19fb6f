"""Images for another code: hard links (or copies) of the rendered files, or 8-bit versions.

The rendered images hold 12-bit grey levels in 16-bit TIFF files. A code that reads
16-bit images gets the very files (hard links where the file system allows, else
copies). A code that works on 8-bit images only (OpenPTV) gets each set of images
scaled down by one power of two, the smallest that keeps the brightest pixel of the
whole set at or below 255: no pixel clips and all sets of one kind (plates, particles)
share one factor, so their grey levels stay comparable.
"""

import os
import shutil
from collections.abc import Iterable
from pathlib import Path

import numpy as np
import tifffile


def link_or_copy(source: Path, target: Path) -> None:
    """Hard-link ``source`` as ``target`` (its folder created), or copy it across file
    systems."""
    target.parent.mkdir(parents=True, exist_ok=True)
    try:
        os.link(source, target)
    except OSError:
        shutil.copyfile(source, target)


def grey_shift(paths: Iterable[Path]) -> int:
    """The smallest s ≥ 0 with (brightest pixel of every image) >> s ≤ 255.

    Parameters
    ----------
    paths : iterable of Path
        Integer grey-level TIFF images.

    Returns
    -------
    int
        The right shift, bits.
    """
    brightest = 0
    for path in paths:
        brightest = max(brightest, int(tifffile.imread(path).max()))
    shift = 0
    while brightest >> shift > 255:
        shift += 1
    return shift


def write_8bit(source: Path, target: Path, shift: int) -> None:
    """Write the image ``source`` as an 8-bit TIFF ``target``, grey levels >> ``shift``
    (clipped at 255), its folder created."""
    image = tifffile.imread(source).astype(np.int64) >> shift
    target.parent.mkdir(parents=True, exist_ok=True)
    tifffile.imwrite(target, np.clip(image, 0, 255).astype(np.uint8))


def noise_threshold(path: Path, shift: int, sigmas: float = 6.0) -> int:
    """A grey threshold for the 8-bit version of ``path``: its median plus ``sigmas``
    robust standard deviations (1.4826 × the median absolute deviation), at least one
    grey level above the median.

    Parameters
    ----------
    path : Path
        An integer grey-level TIFF image, mostly background.
    shift : int
        The right shift of :func:`write_8bit`.
    sigmas : float
        How many noise σ above the background.

    Returns
    -------
    int
        Grey level, 8-bit.
    """
    image = (tifffile.imread(path).astype(np.int64) >> shift).astype(float)
    median = float(np.median(image))
    sigma = 1.4826 * float(np.median(np.abs(image - median)))
    return int(min(255, max(median + 1.0, np.ceil(median + sigmas * sigma))))
