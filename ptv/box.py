"""Axis-aligned boxes of the PTV stack (matching and analysis volumes): one shape, one
check."""

import numpy as np

__all__ = ["Box", "check_box", "inside_box"]

#: An axis-aligned box: (lower corner, upper corner), m.
Box = tuple[tuple[float, float, float], tuple[float, float, float]]


def check_box(name: str, value) -> Box:
    """``value`` as a :data:`Box` of floats, or a ValueError naming ``name``.

    Parameters
    ----------
    name : str
        What the box is, for the message.
    value : pair of sequences of 3 numbers
        (lower, upper) corners, m; finite, lower < upper on every axis.

    Returns
    -------
    Box
    """
    try:
        lower, upper = (np.asarray(v, dtype=np.float64) for v in value)
    except (TypeError, ValueError):
        raise ValueError(
            f"{name} must be (lower, upper) corners of 3 numbers, got {value!r}"
        ) from None
    if lower.shape != (3,) or upper.shape != (3,):
        raise ValueError(f"{name} corners must have 3 entries each, got {value!r}")
    if not (np.all(np.isfinite(lower)) and np.all(np.isfinite(upper)) and np.all(lower < upper)):
        raise ValueError(f"{name} needs finite corners with lower < upper, got {value!r}")
    return (tuple(float(v) for v in lower), tuple(float(v) for v in upper))  # type: ignore[return-value]


def inside_box(points: np.ndarray, box: Box) -> np.ndarray:
    """Points (..., 3) inside ``box`` = (lower corner, upper corner), m, boundary included."""
    lower, upper = (np.asarray(v) for v in box)
    return np.all((points >= lower) & (points <= upper), axis=-1)
