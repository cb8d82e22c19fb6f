"""Detection of particle images larger than the detector's own scale, on blocks of
pixels (private; :func:`ptv.detect.detect_particles`, ``diameter``).

The detector's splitting tests, fit windows and starting widths are made for spots of
about :data:`NATIVE_DIAMETER` px (e⁻² diameter, σ ≈ 0.75 px; tested for σ 0.6–1.2 px).
A particle image several times larger is, to them, a broad plateau: noise raises
several maxima on it, which the dip test keeps apart, the 5 × 5 windows of the fits see
only its top, and the model test, whose one-spot model fits badly, splits it again.

Given an expected diameter d, px, the image is summed over b × b blocks,
b = ⌊d / NATIVE_DIAMETER⌋ (1, nothing changes, below 6 px), and the detector runs on
the block sums, where the spot is 3–4.5 blocks across (σ 0.75–1.1 blocks): its own
scale. Summing pixels is exact for the
model the refinement fits: the sum over a block of pixel-integrated Gaussians is the
Gaussian integrated over the block, so the refined centres are unbiased on blocks as
on pixels. Every photo-electron is kept, and the block noise is that of its b² pixels
added (read noise × b, shot noise of the sum), which the detector measures on the
block image as on any image. Every distance of the detector scales with b, and two
particles are split down to about 1.2 blocks apart, 0.4 d, as spots of the native size
are split down to 1.2 px.

Measured on rendered spots peaking at 300 e⁻ over 8 e⁻ of read noise
(tests/ptv/detect/test_detect_diameter.py), d = 10, 15, 20 px: every lone spot one
detection, 2-D rms error 0.056–0.061 px, 1.1–1.2 times the Cramér–Rao bound of the
pixels (the detector at its own scale: 0.14–0.86 px, and 42 % of 20 px spots one
detection); pairs a diameter apart all split, 0.061–0.062 px; half a diameter apart
99–100 % split, 0.12–0.13 px (1.3 times the bound; summing b × b pixels itself raises
the bound by 8–11 % for a lone spot, 17–30 % for two spots half a diameter apart). At
3000 e⁻ the rms errors are 0.014–0.016 px for lone spots, and 92–98 % of the pairs
half a diameter apart are split. The sub-pixel bias on noise-free spots is below
0.001 px. A particle much smaller than d is located on the blocks only (3–5 px spots
with d = 15 px: about 1 px rms).

Back on the image: a block centre (u, v) is the pixel position (b·u + (b − 1)/2,
b·v + (b − 1)/2); size counts the pixels of the particle's blocks (b² per block);
intensity is unchanged (a sum above the background either way); the peak is the
brightest pixel of the b × b pixels around the centre, above the background level per
pixel. A block holding a saturated pixel counts as saturated (its intensity counts the
block as saturated throughout). Where the image size is not a multiple of b, the image
is extended to whole blocks by its background level, so that the light of a particle on
the edge stays where it was; a particle cut by the border (flag EDGE) is fitted on
blocks that reach b times further than pixels, and its centre is biased more than at
the detector's own scale.
"""

import numpy as np

from ptv.detect.background import BackgroundEstimate, estimate_background
from ptv.detect.detections import Detections

#: The particle image diameter the detector is made for, px (e⁻² diameter, σ 0.75 px).
NATIVE_DIAMETER = 3.0


def block_size(diameter: float, shape: tuple[int, int]) -> int:
    """b = ⌊diameter / :data:`NATIVE_DIAMETER`⌋, at least 1.

    Parameters
    ----------
    diameter : float
        Expected particle image diameter, px (e⁻² diameter, σ = diameter/4), > 0.
    shape : (H, W)
        The image's rows and columns.

    Returns
    -------
    int
        Pixels per side of a block.

    Raises
    ------
    ValueError
        ``diameter`` larger than the image's smaller side.
    """
    if diameter > min(shape):
        raise ValueError(
            f"diameter {diameter:g} px is larger than the image ({shape[0]} x {shape[1]} px)"
        )
    return max(1, int(diameter // NATIVE_DIAMETER))


def block_sums(
    img: np.ndarray, block: int, saturation: float, background: BackgroundEstimate
) -> tuple[np.ndarray, float]:
    """The image summed over ``block`` × ``block`` pixels, and its saturation level.

    Parameters
    ----------
    img : ndarray, shape (H, W)
        Image, DN.
    block : int
        b, pixels per side of a block, >= 1.
    saturation : float
        Saturation level of a pixel, DN (inf: none).
    background : BackgroundEstimate
        The image's background: where H or W is not a multiple of b, the image is
        extended to whole blocks by its level there.

    Returns
    -------
    sums : ndarray of float64, shape (⌈H/b⌉, ⌈W/b⌉)
        Block sums, DN; a block holding a pixel at or above ``saturation`` is raised to
        the block's saturation level.
    saturation : float
        b² · ``saturation``, DN.
    """
    rows, cols = img.shape
    full = (rows + -rows % block, cols + -cols % block)
    padded = np.empty(full)
    padded[:rows, :cols] = img
    for r0, c0, c1 in ((rows, 0, full[1]), (0, cols, full[1])):  # below, then right
        r1 = full[0] if r0 else rows
        rr, cc = np.mgrid[r0:r1, c0:c1]
        level = background.at(np.column_stack((cc.ravel(), rr.ravel())))[0]
        padded[r0:r1, c0:c1] = level.reshape(rr.shape)
    shape = (full[0] // block, block, full[1] // block, block)
    sums = padded.reshape(shape).sum(axis=(1, 3))
    summed_saturation = block * block * saturation
    if np.isfinite(saturation):
        hot = (padded >= saturation).reshape(shape).any(axis=(1, 3))
        sums[hot] = np.maximum(sums[hot], summed_saturation)
    return sums, summed_saturation


def block_background(
    background: BackgroundEstimate | None, sums: np.ndarray, block: int, tiles: tuple[int, int]
) -> BackgroundEstimate:
    """The background of the block sums ``sums``: estimated on them in ``tiles`` when
    ``background`` (an estimate made on the image) is None; otherwise that estimate
    with its level × b² and its noise × b (pixel noise independent from pixel to
    pixel)."""
    if background is None:
        return estimate_background(sums, tiles=tiles)
    return BackgroundEstimate(
        background.level * block * block, background.noise * block, sums.shape
    )


def from_blocks(found: Detections, img: np.ndarray, block: int, level: np.ndarray) -> Detections:
    """Detections on block sums as detections on the image (module docstring).

    Parameters
    ----------
    found : Detections
        The N detections on the block sums, in blocks.
    img : ndarray, shape (H, W)
        The image, DN.
    block : int
        b, pixels per side of a block.
    level : ndarray, shape (N,)
        Background level of a block at each detection, DN.

    Returns
    -------
    Detections
        Centres in pixels, sizes in pixels, peaks of the brightest pixel near each
        centre above the background per pixel; same order and flags.
    """
    xy = found.xy * block + 0.5 * (block - 1)
    rows, cols = img.shape
    offsets = np.arange(block) - block // 2
    centre = np.rint(xy).astype(np.int64)
    near_c = np.clip(centre[:, :1] + offsets, 0, cols - 1)
    near_r = np.clip(centre[:, 1:] + offsets, 0, rows - 1)
    brightest = img[near_r[:, :, None], near_c[:, None, :]].reshape(len(xy), -1).max(axis=1)
    return Detections(
        xy=xy,
        intensity=found.intensity,
        peak=brightest - level / (block * block),
        size=found.size * block * block,
        flags=found.flags,
        shape=img.shape,
    )
