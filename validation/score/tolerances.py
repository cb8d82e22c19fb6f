"""How a check of a run turns a false-alarm rate into a tolerance.

A statistical check compares a measured value with its reference and allows the method's
allowance (what the stack may add, a number from physics) plus a multiple of the
difference's standard error: the two-sided Student quantile that an honest sample
exceeds with probability :data:`FALSE_ALARM`, with the effective number of independent
snapshots less one as its degrees of freedom (:mod:`ptv.stats.resampling`). Where two
measurements of the same snapshots were bootstrapped with the same draws, the standard
error is that of their paired difference (the sampling both share cancels); else both
errors add in quadrature (docs/claims.md §4).
"""

import numpy as np
from scipy.stats import norm, t

#: How often a statistical check may fail an honest run, each check, two-sided: its
#: tolerance is the method's allowance plus the Student quantile of this rate times the
#: check's standard error (:func:`false_alarm_z`).
FALSE_ALARM = 1e-3


def float_array(values) -> np.ndarray:
    """A JSON list of numbers (None for NaN) as a float array."""
    return np.array([np.nan if v is None else v for v in values], dtype=float)


def false_alarm_z(dof: float | None, *, tests: int = 1, rate: float = FALSE_ALARM) -> float:
    """How many standard errors a check allows: the two-sided Student quantile that a
    deviation of an honest sample exceeds with probability ``rate``, shared by ``tests``
    values checked at once (Bonferroni: each at rate/tests).

    Parameters
    ----------
    dof : float or None
        Degrees of freedom of the standard error: the effective number of independent
        snapshots less one (None or ∞: the normal quantile).
    tests : int
        Values that must all hold (the bins of a profile).
    rate : float
        The check's false-alarm rate.

    Returns
    -------
    float
        z, in standard errors: the Student quantile with ``dof`` degrees of freedom, or
        the normal one.
    """
    p = 1.0 - rate / (2 * max(int(tests), 1))
    if dof is None or not np.isfinite(dof):
        return float(norm.ppf(p))
    return float(t.ppf(p, max(float(dof), 1.0)))


def snapshot_dof(*summaries: dict | None) -> float | None:
    """Degrees of freedom of a standard error from the bootstrap over snapshots.

    Parameters
    ----------
    *summaries : dict or None
        summary.json contents (``bootstrap.correlation.effective_snapshots``); None or
        a summary without a bootstrap is passed over.

    Returns
    -------
    float or None
        The fewest effective independent snapshots of their bootstraps, less one; None
        where no summary has a bootstrap.
    """
    found = [
        s["bootstrap"]["correlation"]["effective_snapshots"]
        for s in summaries
        if s is not None and s.get("bootstrap")
    ]
    return min(found) - 1.0 if found else None


def pairs_with(summary: dict, other: dict | None) -> bool:
    """Whether two summaries' bootstrap replicates drew the same snapshots.

    Parameters
    ----------
    summary, other : dict, dict or None
        summary.json contents (their ``bootstrap`` sections).

    Returns
    -------
    bool
        True where both have a bootstrap with the same replicate count, seed, block and
        snapshots in every stratum.
    """
    a = summary.get("bootstrap")
    b = None if other is None else other.get("bootstrap")
    if not a or not b:
        return False
    return all(a[key] == b[key] for key in ("replicates", "seed", "block", "snapshot_ids"))


def paired_ratio(
    value: float, se: float, reps: list | None, base: float, se_base: float, base_reps: list | None
) -> tuple[float, float, bool]:
    """value/base − 1 and its standard error: the spread of the ratio over replicates
    drawn alike (paired), else the two errors in quadrature (unpaired, larger where the
    two share their sample).

    Parameters
    ----------
    value, se : float
        The measurement and its standard error.
    reps : list of float or None
        Its bootstrap replicates (None: unpaired).
    base, se_base, base_reps :
        The same of the reference.

    Returns
    -------
    (float, float, bool)
        The relative difference, its standard error, and whether it is paired.
    """
    ratio = value / base - 1.0
    if reps is not None and base_reps is not None:
        r = float_array(reps) / float_array(base_reps)
        if np.isfinite(r).all():
            return ratio, float(np.std(r, ddof=1)), True
    return ratio, float(np.hypot(se / value, se_base / base) * value / base), False


