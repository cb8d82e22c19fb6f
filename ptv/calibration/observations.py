"""Dot correspondences of a traverse: what every calibration method is built from."""

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class PlaneObservation:
    """Identified dots of one calibration plane in one camera.

    Attributes
    ----------
    z : float
        Traverse position Z_j, m.
    pixels : ndarray, shape (N, 2)
        Dot centres in the image, px.
    world_xy : ndarray, shape (N, 2)
        Their nominal (X, Y) on the plate, m.

    Examples
    --------
    A 9 × 9 dot plate of 4 mm pitch at three traverse positions, imaged by a known
    camera (a Tsai camera 0.5 m away, turned 20° about Y):

    >>> import numpy as np
    >>> import ptv
    >>> from scipy.spatial.transform import Rotation
    >>> turn = Rotation.from_euler("y", 20, degrees=True).as_matrix()
    >>> camera = ptv.TsaiCalibration(turn, [0, 0, 0.5], focal_length=0.05, kappa1=0.0,
    ...                              sx=1.0, principal_point=(319.5, 239.5),
    ...                              pixel_size=(1e-5, 1e-5))
    >>> ij = np.stack(np.meshgrid(np.arange(-4, 5), np.arange(-4, 5)), axis=-1).reshape(-1, 2)
    >>> xy = 4e-3 * ij
    >>> planes = [
    ...     ptv.PlaneObservation(z, camera.project(np.column_stack([xy, np.full(81, z)])), xy)
    ...     for z in (-2e-3, 0.0, 2e-3)
    ... ]
    >>> planes[1].pixels[40]  # the plate's centre dot, on the optical axis
    array([319.5, 239.5])
    """

    z: float
    pixels: np.ndarray
    world_xy: np.ndarray


def stack_planes(observations: Sequence[PlaneObservation]) -> tuple[np.ndarray, np.ndarray]:
    """All planes as one non-coplanar set of correspondences.

    Returns
    -------
    world : ndarray, shape (N, 3)
        (X, Y, Z_j) of every dot, m.
    pixels : ndarray, shape (N, 2)
        Their image positions, px.

    Raises
    ------
    ValueError
        No planes, arrays that are not (N, 2) alike, or non-finite values (named by plane).
    """
    if len(observations) == 0:
        raise ValueError("no calibration planes given")
    world, pixels = [], []
    for o in observations:
        px = np.asarray(o.pixels, dtype=float)
        xy = np.asarray(o.world_xy, dtype=float)
        if px.ndim != 2 or px.shape[1] != 2 or xy.shape != px.shape:
            raise ValueError(
                f"plane Z = {o.z}: pixels and world_xy must both be (N, 2), "
                f"got {px.shape} and {xy.shape}"
            )
        if not (np.isfinite(px).all() and np.isfinite(xy).all() and np.isfinite(o.z)):
            raise ValueError(f"plane Z = {o.z}: pixels, world_xy or Z contain NaN or inf")
        world.append(np.column_stack([xy, np.full(len(xy), float(o.z))]))
        pixels.append(px)
    return np.concatenate(world), np.concatenate(pixels)
