"""The energy-flux terms ⟨δu·δa⟩(r) and ⟨δu_L δa_L⟩(r) from tracer pairs (docs/dns.md §13).

For the tracers of one snapshot (positions, velocities and accelerations at one time),
every pair i < j whose separation d = X_j − X_i falls in a bin of |d| = r gives
δu = u_j − u_i, δa = a_j − a_i and, with e = d/r, δu_L = δu·e and δa_L = δa·e. The bin
means of δu·δa, δu_L δa_L and |δu|² are the tracers' flux terms; beside them, the same
terms of a gridded field (``statistics.h5``'s ``du_da``, ``dul_dal`` at the grid's
separations) interpolated in log r at each pair's own r and averaged over the same
pairs, so that both sides weigh the separations inside a bin alike. Pairs are found by
a k-d tree (:class:`scipy.spatial.cKDTree`), apart from the stack's pair kernel.
"""

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree


@dataclass(frozen=True)
class PairFlux:
    """Pair means per separation bin, one snapshot.

    Attributes
    ----------
    edges : ndarray, shape (B + 1,)
        Bin edges in r, m.
    count : ndarray, shape (B,)
        Pairs per bin.
    r : ndarray, shape (B,)
        Mean separation of the bin's pairs, m (NaN where empty).
    du_da, dul_dal : ndarray, shape (B,)
        ⟨δu·δa⟩ and ⟨δu_L δa_L⟩ over the bin's pairs, m²/s³.
    du2 : ndarray, shape (B,)
        ⟨|δu|²⟩ over the bin's pairs, m²/s².
    field_du_da, field_dul_dal : ndarray, shape (B,)
        The field's ⟨δu·δa⟩(r) and ⟨δu_L δa_L⟩(r) at each pair's r, averaged over the
        bin's pairs, m²/s³ (NaN without a field).
    """

    edges: np.ndarray
    count: np.ndarray
    r: np.ndarray
    du_da: np.ndarray
    dul_dal: np.ndarray
    du2: np.ndarray
    field_du_da: np.ndarray
    field_dul_dal: np.ndarray


def _bin_mean(bins: np.ndarray, values: np.ndarray, count: np.ndarray) -> np.ndarray:
    sums = np.bincount(bins, weights=values, minlength=len(count))
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(count > 0, sums / np.maximum(count, 1), np.nan)


def pair_flux(
    position: np.ndarray,
    velocity: np.ndarray,
    acceleration: np.ndarray,
    edges: np.ndarray,
    *,
    field_r: np.ndarray | None = None,
    field_du_da: np.ndarray | None = None,
    field_dul_dal: np.ndarray | None = None,
) -> PairFlux:
    """The flux terms of the tracers' pairs per separation bin (module docstring).

    Parameters
    ----------
    position, velocity, acceleration : ndarray, shape (P, 3)
        X (m), u (m/s) and a (m/s²) of P tracers at one time.
    edges : ndarray, shape (B + 1,)
        Increasing bin edges, m (> 0).
    field_r : ndarray, shape (R,), optional
        Increasing separations of the field's statistics, m.
    field_du_da, field_dul_dal : ndarray, shape (R,), optional
        The field's ⟨δu·δa⟩ and ⟨δu_L δa_L⟩ there, m²/s³ (at the same time as the
        tracers), interpolated linearly in log r (held constant beyond the ends).

    Returns
    -------
    PairFlux
    """
    x = np.asarray(position, dtype=float)
    u = np.asarray(velocity, dtype=float)
    a = np.asarray(acceleration, dtype=float)
    edges = np.asarray(edges, dtype=float)
    if x.ndim != 2 or x.shape[1] != 3 or u.shape != x.shape or a.shape != x.shape:
        raise ValueError(
            f"position, velocity and acceleration must share shape (P, 3), got "
            f"{x.shape}, {u.shape}, {a.shape}"
        )
    if edges.ndim != 1 or len(edges) < 2 or edges[0] <= 0 or np.any(np.diff(edges) <= 0):
        raise ValueError(f"edges must be > 0 and increase strictly, got {edges}")
    n_bins = len(edges) - 1
    pairs = cKDTree(x).query_pairs(edges[-1], output_type="ndarray")
    i, j = (pairs[:, 0], pairs[:, 1]) if len(pairs) else (np.empty(0, int), np.empty(0, int))
    d = x[j] - x[i]
    r = np.sqrt(np.einsum("pc,pc->p", d, d))
    bins = np.searchsorted(edges, r, side="right") - 1
    keep = (bins >= 0) & (bins < n_bins)
    i, j, d, r, bins = i[keep], j[keep], d[keep], r[keep], bins[keep]
    e = d / r[:, None]
    du, da = u[j] - u[i], a[j] - a[i]
    count = np.bincount(bins, minlength=n_bins)
    field = np.full((2, n_bins), np.nan)
    if field_r is not None:
        log_r, log_grid = np.log(r), np.log(np.asarray(field_r, dtype=float))
        for row, values in enumerate((field_du_da, field_dul_dal)):
            at_pairs = np.interp(log_r, log_grid, np.asarray(values, dtype=float))
            field[row] = _bin_mean(bins, at_pairs, count)
    return PairFlux(
        edges=edges,
        count=count,
        r=_bin_mean(bins, r, count),
        du_da=_bin_mean(bins, np.einsum("pc,pc->p", du, da), count),
        dul_dal=_bin_mean(bins, np.einsum("pc,pc->p", du, e) * np.einsum("pc,pc->p", da, e), count),
        du2=_bin_mean(bins, np.einsum("pc,pc->p", du, du), count),
        field_du_da=field[0],
        field_dul_dal=field[1],
    )
