"""Input checks shared by the render modules (private)."""

from numbers import Integral, Real

import numpy as np


def positive_float(name: str, value: object, *, allow_zero: bool = False) -> float:
    """Return ``value`` as a finite float > 0 (or ≥ 0), else raise ValueError naming it."""
    ok = isinstance(value, Real) and not isinstance(value, bool) and np.isfinite(value)
    if ok and (value > 0 or (allow_zero and value == 0)):
        return float(value)
    bound = ">= 0" if allow_zero else "> 0"
    raise ValueError(f"{name} must be a finite number {bound}, got {value!r}")


def finite_float(name: str, value: object) -> float:
    """Return ``value`` as a finite float, else raise ValueError naming it."""
    if isinstance(value, Real) and not isinstance(value, bool) and np.isfinite(value):
        return float(value)
    raise ValueError(f"{name} must be a finite number, got {value!r}")


def image_shape(shape: object) -> tuple[int, int]:
    """Return ``shape`` as ``(rows, cols)`` of positive ints, else raise ValueError."""
    try:
        rows, cols = shape  # type: ignore[misc]
    except (TypeError, ValueError):
        raise ValueError(f"shape must be (rows, cols), got {shape!r}") from None
    for v in (rows, cols):
        if not isinstance(v, Integral) or isinstance(v, bool) or v <= 0:
            raise ValueError(f"shape must be two positive integers (rows, cols), got {shape!r}")
    return int(rows), int(cols)


def real_array(name: str, value: object) -> np.ndarray:
    """Return ``value`` as a float64 array, else raise ValueError naming it."""
    arr = np.asarray(value)
    if arr.dtype == bool or not (
        np.issubdtype(arr.dtype, np.floating) or np.issubdtype(arr.dtype, np.integer)
    ):
        raise ValueError(f"{name} must be real numbers, got dtype {arr.dtype}")
    return arr.astype(np.float64, copy=False)


def first_bad(name: str, arr: np.ndarray, bad: np.ndarray, expected: str) -> ValueError:
    """A ValueError naming the first entry of ``arr`` flagged in ``bad``."""
    idx = np.unravel_index(int(np.flatnonzero(bad)[0]), arr.shape)
    where = int(idx[0]) if len(idx) == 1 else tuple(int(i) for i in idx)
    n_bad = int(np.count_nonzero(bad))
    return ValueError(
        f"{name} must be {expected}; {n_bad} {'entry is' if n_bad == 1 else 'entries are'} "
        f"not, first at index {where}: {arr[idx].item()!r}"
    )
