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
