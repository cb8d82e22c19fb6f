"""Checks of option values shared by the settings of the PTV stack (private)."""

import numpy as np


def positive(name: str, value) -> float:
    """``value`` as a float if it is a finite real number > 0, else a ValueError naming
    ``name`` (booleans are not numbers here)."""
    ok = isinstance(value, int | float | np.integer | np.floating) and not isinstance(value, bool)
    if not (ok and np.isfinite(value) and value > 0):
        raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
    return float(value)
