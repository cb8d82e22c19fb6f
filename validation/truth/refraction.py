"""Snell's law at a camera's flat windows, recomputed without ``simulator.optics``.

A simulated camera images a point P at a pixel by solving the refraction forward
(``simulator.optics.forward``, Newton on the tangent of the ray leaving the centre).
Here the ray of that pixel is followed back into the water in plain NumPy, from the
angles in each plane of incidence (n_i sin θ_i = n_t sin θ_t, not the simulator's vector
form), with the refractive indices the rig file states, or the physical values written
here when it states none. The ray must pass through P: its distance from P measures how
far the simulator's refraction is from Snell's law with those indices. Only the window
geometry (normal, plane offsets) and the lens (pixel → direction leaving the centre)
are taken from the simulator.
"""

import numpy as np

#: Refractive indices of air, PMMA and water (sodium D line, 20 °C) when a rig file
#: states none.
N_AIR = 1.0
N_PMMA = 1.49
N_WATER = 1.333


def stated_indices(camera_spec: dict, tank_spec: dict | None = None) -> tuple[float, ...]:
    """Indices of air, the window and the water a rig file's camera table states.

    A camera's ``[cameras.window]`` table may give ``n_glass``, ``n_water`` (and
    ``n_air``); a box tank's ``[tank]`` table the glass and water of its walls.
    """
    window = {**(tank_spec or {}), **camera_spec.get("window", {})}
    return (
        float(window.get("n_air", N_AIR)),
        float(window.get("n_glass", N_PMMA)),
        float(window.get("n_water", N_WATER)),
    )


def _refract(direction: np.ndarray, normal: np.ndarray, n_in: float, n_out: float) -> np.ndarray:
    """Directions (N, 3) after a plane of unit normal ``normal`` (along the travel)."""
    cos_in = direction @ normal
    tangential = direction - cos_in[:, None] * normal
    sin_in = np.linalg.norm(tangential, axis=1)
    along = np.divide(
        tangential, sin_in[:, None], out=np.zeros_like(tangential), where=sin_in[:, None] > 0
    )
    sin_out = n_in / n_out * sin_in
    return np.sqrt(1.0 - sin_out**2)[:, None] * normal + sin_out[:, None] * along


def snell_miss(
    centre: np.ndarray,
    directions: np.ndarray,
    normal: np.ndarray,
    offsets: np.ndarray,
    indices: tuple[float, ...],
    points: np.ndarray,
) -> np.ndarray:
    """Distance of each point from its ray after refraction at parallel planes, m.

    Parameters
    ----------
    centre : ndarray, shape (3,)
        Camera centre, m (in the first medium).
    directions : ndarray, shape (N, 3)
        Unit directions of the rays leaving the centre.
    normal : ndarray, shape (3,)
        Unit normal of the planes, pointing from the camera into the water.
    offsets : ndarray, shape (L,)
        Plane k is n̂·X = offsets[k], m, in the order the rays cross them.
    indices : tuple of L + 1 floats
        Refractive index of each medium, camera side first.
    points : ndarray, shape (N, 3)
        The points the rays were aimed at, m (in the last medium).

    Returns
    -------
    ndarray, shape (N,)
        |(P − X) − ((P − X)·d) d| with X, d the ray's last crossing and direction.
    """
    normal = np.asarray(normal, dtype=float)
    position = np.broadcast_to(np.asarray(centre, dtype=float), directions.shape)
    direction = np.asarray(directions, dtype=float)
    for k, offset in enumerate(offsets):
        position = (
            position + ((offset - position @ normal) / (direction @ normal))[:, None] * direction
        )
        direction = _refract(direction, normal, indices[k], indices[k + 1])
    rel = points - position
    return np.linalg.norm(rel - (rel * direction).sum(axis=1)[:, None] * direction, axis=1)
