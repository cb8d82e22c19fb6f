"""Real images before detection: dark particles, and backgrounds that are not flat.

The detector (:func:`ptv.detect.detect_particles`) looks for bright spots over a smooth
background. Laboratory images often break that:

- **dark particles**: back-lit (shadowgraph) recordings show particles darker than the
  bright background. :func:`invert` turns them bright: I' = top − I, with ``top`` the
  saturation level (or the image type's maximum).
- **a background with structure**: reflections, scratches, the window's frame, an
  uneven sheet. Two removals:

  - the **temporal median** of the sequence (:func:`median_background`): per pixel, the
    median of frames spread over the recording; particles move, so they are rare at any
    pixel and drop out, while everything fixed stays and is subtracted. Best when the
    camera and the background do not move.
  - a **morphological top-hat** (:func:`tophat`): the image minus its grey opening by a
    disc of radius r, which removes everything wider than the disc and keeps the
    particles (choose r above the largest particle image radius, a few px). Works on a
    single frame and follows a background that changes in time, but keeps whatever is
    as narrow as a particle in some direction: a thin scratch, a small reflection.

After either removal the background is ~0 and the detector measures its noise as usual.

A temporal median assumes the particles move: one that stays on its pixels in more
than half of the frames stays in the median, and subtracting it erases the particle
from the frames. :func:`particles_left_by_median` counts the particle images of one of its
frames before and after the median is subtracted, so that a recording of slow particles (they
move less than their size between the frames the median is taken from) is said, rather
than read as a failed calibration downstream.
"""

from collections.abc import Sequence

import cv2
import numpy as np

from ptv.detect.background import BackgroundEstimate, estimate_background
from ptv.detect.locate import detect_particles

__all__ = ["invert", "median_background", "particles_left_by_median", "tophat"]


def invert(image: np.ndarray, top: float | None = None) -> np.ndarray:
    """Dark particles made bright: ``top`` − image, as float32.

    Parameters
    ----------
    image : ndarray, shape (H, W)
        Grey image, DN.
    top : float or None
        The level that becomes 0 (the saturation level; None: the image type's maximum
        for integers, the image's maximum for reals).

    Returns
    -------
    ndarray of float32, shape (H, W)
    """
    if top is None:
        dtype = np.asarray(image).dtype
        top = np.iinfo(dtype).max if np.issubdtype(dtype, np.integer) else float(np.max(image))
    return (np.float32(top) - np.asarray(image, dtype=np.float32)).astype(np.float32)


def tophat(image: np.ndarray, radius: int) -> np.ndarray:
    """White top-hat by a disc: the image minus its grey opening, as float32.

    Parameters
    ----------
    image : ndarray, shape (H, W)
        Grey image with bright particles, DN.
    radius : int
        Disc radius, px, >= 1: structures wider than 2·radius + 1 px are removed.

    Returns
    -------
    ndarray of float32, shape (H, W)
    """
    if isinstance(radius, bool) or not isinstance(radius, int | np.integer) or radius < 1:
        raise ValueError(f"tophat radius must be an integer >= 1 px, got {radius!r}")
    disc = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius + 1, 2 * radius + 1))
    # The image is extended by replicating its edges: a sloping background then ends in
    # a plateau that the opening follows (OpenCV's own border handling leaves the
    # opening flat over the last r pixels, and the top-hat makes a ramp there).
    pad = 2 * radius
    padded = cv2.copyMakeBorder(
        np.asarray(image, dtype=np.float32), pad, pad, pad, pad, cv2.BORDER_REPLICATE
    )
    return cv2.morphologyEx(padded, cv2.MORPH_TOPHAT, disc)[pad:-pad, pad:-pad]


def median_background(frames: Sequence[np.ndarray]) -> np.ndarray:
    """Per-pixel median of frames of one camera, float32, shape (H, W).

    Raises
    ------
    ValueError
        Fewer than 3 frames (a median of two is their mean and keeps every particle at
        half its brightness), or frames of different shapes.
    """
    if len(frames) < 3:
        raise ValueError(f"a temporal median needs at least 3 frames, got {len(frames)}")
    shapes = {np.shape(f) for f in frames}
    if len(shapes) != 1:
        raise ValueError(f"frames of different shapes {sorted(shapes)}")
    return np.median(np.stack(frames), axis=0).astype(np.float32)


def particles_left_by_median(
    median: np.ndarray,
    frame: np.ndarray,
    *,
    radius: int,
    threshold_sigmas: float,
    diameter: float | None = None,
) -> tuple[int, int]:
    """Particle images of one of a temporal median's frames, before and after the median
    is subtracted.

    Before: the frame top-hat filtered (disc ``radius``, px), which removes its smooth
    background and keeps particle-sized structure, fixed (a glint, a scratch) or not.
    After: the frame minus the median, as the detection sees it. Moving particles stay
    and the fixed structure goes; particles that stood still through most of the
    median's frames go with it.

    Parameters
    ----------
    median : ndarray, shape (H, W)
        The temporal median, particles bright, DN.
    frame : ndarray, shape (H, W)
        One of the frames it was taken from, particles bright, DN.
    radius : int
        Top-hat disc radius, px (above the particle image radius).
    threshold_sigmas : float
        Detection threshold, noise σ.
    diameter : float, optional
        Expected particle image diameter, px (:func:`ptv.detect.detect_particles`).

    Returns
    -------
    (int, int)
        Detections on the frame before, and after, the median is subtracted.
    """
    removed = tophat(frame, radius)
    # The noise of the frame before the top-hat: a top-hat of noise is skewed, and its
    # pixel differences understate its upper tail, where the threshold lies.
    level = estimate_background(removed).level
    background = BackgroundEstimate(level, estimate_background(frame).noise, removed.shape)
    before = detect_particles(
        removed, threshold_sigmas=threshold_sigmas, background=background, diameter=diameter
    )
    after = detect_particles(
        np.asarray(frame, dtype=np.float32) - median,
        threshold_sigmas=threshold_sigmas,
        diameter=diameter,
    )
    return len(before), len(after)
