"""References that share no code with the measurement stack or with the sample truth.

The claims (docs/claims.md) and the checks of ``synptv run`` compare every statistics
estimate with at least one reference computed along a path of its own, so that a bug
in a shared routine cannot cancel between estimate and reference:

- :func:`brute_force_s2`: the sample-truth S2 of the exact velocities over a random
  subsample of every snapshot, each pair formed and binned here in plain NumPy (not by
  ``ptv.stats.pairs``), with the subsampling error estimated from disjoint groups;
- :func:`exact_dll`: D_LL(r) = 4∫E(k) G(kr) dk of a spectrum by Gauss–Legendre
  quadrature in ln k, with G(x) = 1/3 − j₁(x)/x from SciPy's spherical Bessel function
  (not ``simulator.truth``'s trapezoid rule and Taylor series);
- :func:`plateau_epsilon_reference`: the input ε times the finite-Reynolds plateau
  deficit of the ε estimator, (D_LL/C₂)^{3/2}/r maximised or averaged over the plateau
  range of r, with the estimator and C₂ = 2 written here (not ``ptv.stats.dissipation``);
- :func:`intercept_standard_error`: the standard error of the intercept β₀ of the mean
  displacement's line against Δt from the scatter of the snapshot means, by the closed
  form of a weighted line (not ``ptv.stats.mean_displacement``).
"""

from dataclasses import dataclass

import numpy as np
from numpy.polynomial.legendre import leggauss
from scipy.special import spherical_jn

#: C₂ of the ε convention ε = (S2/C₂)^{3/2}/r (docs/statistics.md §5; C_K = 1.52),
#: stated here on its own so that a wrong constant in the stack shows against it.
REFERENCE_C2 = 2.0

#: Quadrature of :func:`exact_dll`: panels per decade of k and Gauss nodes per panel.
_PANELS_PER_DECADE = 40
_NODES = 8


@dataclass(frozen=True)
class BruteForceS2:
    """Per-snapshot pair sums of a subsample, kept by group.

    Attributes
    ----------
    edges : ndarray, shape (B + 1,)
        Separation bin edges, m.
    count : ndarray of int, shape (M, G, B)
        Pairs per snapshot, group and bin.
    sum_q : ndarray, shape (M, G, B)
        Σ [(u_j − u_i)·e]² over those pairs, m²/s².
    sum_r : ndarray, shape (M, G, B)
        Σ |r| over those pairs, m.
    group_size : ndarray of int, shape (M,)
        Particles per group in each snapshot.
    """

    edges: np.ndarray
    count: np.ndarray
    sum_q: np.ndarray
    sum_r: np.ndarray
    group_size: np.ndarray

    @property
    def s2(self) -> np.ndarray:
        """S2 over every pair of every group, shape (B,), m²/s² (NaN where empty)."""
        with np.errstate(invalid="ignore", divide="ignore"):
            return self.sum_q.sum(axis=(0, 1)) / self.count.sum(axis=(0, 1))

    @property
    def r(self) -> np.ndarray:
        """Mean pair separation per bin, shape (B,), m (NaN where empty)."""
        with np.errstate(invalid="ignore", divide="ignore"):
            return self.sum_r.sum(axis=(0, 1)) / self.count.sum(axis=(0, 1))

    def pooled(self, weights: np.ndarray) -> tuple[float, float]:
        """Σ_b w_b S2_b and its subsampling error (see :meth:`se_s2`).

        Parameters
        ----------
        weights : ndarray, shape (B,)
            Weights of the bins (0 leaves a bin out), 1/(m²/s²) for a dimensionless sum.

        Returns
        -------
        (float, float)
            The weighted sum and its standard error.
        """
        w = np.nan_to_num(np.asarray(weights, dtype=float))
        total, error = self._split(w)
        return float(total), float(error)

    def mean_ratio(self, other: np.ndarray) -> tuple[float, float]:
        """Mean of other/S2 over the bins, weighted by 1/(relative error of S2)², and
        its subsampling error.

        Parameters
        ----------
        other : ndarray, shape (B,)
            Another S2 in the same bins (NaN bins are left out), m²/s².

        Returns
        -------
        (float, float)
            The weighted mean ratio and its standard error.
        """
        other = np.asarray(other, dtype=float)
        s2, se = self.s2, self.se_s2()
        ok = np.isfinite(other) & np.isfinite(s2) & (s2 > 0) & (se > 0)
        if not ok.any():
            raise ValueError("no bin where both S2 are known")
        weight = np.zeros_like(s2)
        weight[ok] = (s2[ok] / se[ok]) ** 2
        weight /= weight.sum()
        ratio = float(np.sum(weight[ok] * other[ok] / s2[ok]))
        gradient = np.zeros_like(s2)
        gradient[ok] = weight[ok] * other[ok] / s2[ok] ** 2  # |∂ratio/∂S2_b|
        return ratio, self.pooled(gradient)[1]

    def se_s2(self) -> np.ndarray:
        """Subsampling error of :attr:`s2` per bin, shape (B,), m²/s².

        The groups are disjoint particle sets of the same snapshots, so each group's S2
        scatters about that of the snapshots' fields independently. The spread of the
        difference between the two halves of the groups (delta method, with the
        snapshots as independent clusters) is twice the error of their mean, which
        :attr:`s2` is (it drops the pairs between groups, so it is that mean).
        """
        b = self.count.shape[2]
        return np.array([self._split(np.eye(b)[i])[1] for i in range(b)])

    def _split(self, w: np.ndarray) -> tuple[float, float]:
        """w·S2 and the standard error of w·S2 from the two halves of the groups."""
        g = self.count.shape[1]
        if g < 2:
            raise ValueError("the subsampling error needs at least two groups")
        halves = (slice(0, g // 2), slice(g // 2, g))
        total = float(np.nansum(w * self.s2))
        z = np.zeros(self.count.shape[0])
        for sign, half in zip((1.0, -1.0), halves, strict=True):
            count = self.count[:, half].sum(axis=1)  # (M, B)
            sum_q = self.sum_q[:, half].sum(axis=1)
            with np.errstate(invalid="ignore", divide="ignore"):
                s2 = sum_q.sum(axis=0) / count.sum(axis=0)
                contribution = (sum_q - s2 * count) / count.sum(axis=0)  # delta method
            z += sign * np.nansum(w * contribution, axis=1)
        m = len(z)
        difference = np.sqrt(m / (m - 1) * np.sum((z - z.mean()) ** 2))
        return total, 0.5 * float(difference)


def _pair_sums(x: np.ndarray, u: np.ndarray, edges: np.ndarray) -> tuple[np.ndarray, ...]:
    """count, Σq, Σr per bin over every pair of one group, written out in NumPy."""
    i, j = np.triu_indices(len(x), 1)
    sep = x[j] - x[i]
    dist = np.sqrt(np.sum(sep * sep, axis=1))
    q = (np.sum((u[j] - u[i]) * sep, axis=1) / dist) ** 2
    b = np.searchsorted(edges, dist, side="right") - 1
    keep = (b >= 0) & (b < len(edges) - 1)
    n = len(edges) - 1
    return (
        np.bincount(b[keep], minlength=n),
        np.bincount(b[keep], weights=q[keep], minlength=n),
        np.bincount(b[keep], weights=dist[keep], minlength=n),
    )


def subsample_sums(
    x: np.ndarray,
    u: np.ndarray,
    edges: np.ndarray,
    *,
    per_group: int,
    groups: int,
    rng: np.random.Generator,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Brute-force pair sums of one snapshot's random, disjoint groups of particles.

    Parameters
    ----------
    x, u : ndarray, shape (P, 3)
        Positions (m) and exact velocities (m/s) of the snapshot's particles.
    edges : ndarray, shape (B + 1,)
        Increasing separation bin edges, m.
    per_group : int
        Particles per group (fewer when the snapshot holds fewer than ``groups`` times
        as many: then its particles are split evenly).
    groups : int
        Groups; pairs are formed within each group.
    rng : numpy.random.Generator
        The subsample.

    Returns
    -------
    (ndarray, ndarray, ndarray, int)
        count, Σq, Σr of shape (groups, B), and the particles per group.
    """
    n = min(per_group, len(x) // groups)
    order = rng.permutation(len(x))[: n * groups].reshape(groups, n)
    sums = [_pair_sums(x[idx], u[idx], edges) for idx in order]
    count, sum_q, sum_r = (np.array([g[k] for g in sums]) for k in range(3))
    return count, sum_q, sum_r, n


def collect(edges: np.ndarray, parts) -> BruteForceS2:
    """A :class:`BruteForceS2` from the :func:`subsample_sums` of every snapshot."""
    parts = list(parts)
    if not parts:
        raise ValueError("no snapshots given")
    count, sum_q, sum_r = (np.array([p[k] for p in parts]) for k in range(3))
    return BruteForceS2(
        edges=np.asarray(edges, dtype=float),
        count=count,
        sum_q=sum_q,
        sum_r=sum_r,
        group_size=np.array([p[3] for p in parts]),
    )


def check_edges(edges: np.ndarray, per_group: int, groups: int) -> np.ndarray:
    """``edges`` as an array after checking them and the group sizes (ValueError)."""
    edges = np.asarray(edges, dtype=float)
    if edges.ndim != 1 or edges.size < 2 or np.any(np.diff(edges) <= 0) or edges[0] <= 0:
        raise ValueError("edges must be increasing separations > 0")
    if groups < 2 or per_group < 2:
        raise ValueError(f"need groups >= 2 and per_group >= 2, got {groups}, {per_group}")
    return edges


def brute_force_s2(
    snapshots,
    edges: np.ndarray,
    *,
    per_group: int = 300,
    groups: int = 2,
    rng: np.random.Generator | int | None = None,
) -> BruteForceS2:
    """Sample-truth S2 of a random subsample of every snapshot, by brute force.

    Parameters
    ----------
    snapshots : iterable of (ndarray (P, 3), ndarray (P, 3))
        Positions (m) and exact velocities (m/s) at t of the particles inside the
        analysis volume, one pair of arrays per independent snapshot.
    edges : ndarray, shape (B + 1,)
        Increasing separation bin edges, m.
    per_group, groups : int
        As for :func:`subsample_sums` (groups ≥ 2: the subsampling error compares them).
    rng : numpy.random.Generator, int or None
        The subsample.

    Returns
    -------
    BruteForceS2
    """
    edges = check_edges(edges, per_group, groups)
    rng = np.random.default_rng(rng)
    return collect(
        edges,
        (
            subsample_sums(x, u, edges, per_group=per_group, groups=groups, rng=rng)
            for x, u in snapshots
        ),
    )


def log_edges(r_min: float, r_max: float, n_bins: int) -> np.ndarray:
    """Logarithmically spaced bin edges r_min (r_max/r_min)^{i/n}, i = 0…n, m."""
    return r_min * (r_max / r_min) ** (np.arange(n_bins + 1) / n_bins)


def exact_dll(spectrum, r: np.ndarray) -> np.ndarray:
    """D_LL(r) = 4∫E(k) G(kr) dk of a spectrum over its support, m²/s².

    Gauss–Legendre quadrature in s = ln k (:data:`_PANELS_PER_DECADE` panels per decade,
    :data:`_NODES` nodes each), G(x) = 1/3 − j₁(x)/x (docs/flow.md §3.1).

    Parameters
    ----------
    spectrum : object
        With ``energy(k)`` (m³/s²) and ``support`` (k_min, k_max), 1/m.
    r : array_like
        Separations, m, > 0 (any shape).

    Returns
    -------
    ndarray
        D_LL, the shape of r.
    """
    r = np.asarray(r, dtype=float)
    k, w = log_quadrature(*spectrum.support)
    x = np.multiply.outer(r.ravel(), k)
    kernel = 1.0 / 3.0 - spherical_jn(1, x) / x
    return (4.0 * kernel @ (w * spectrum.energy(k))).reshape(r.shape)


def log_quadrature(k_lo: float, k_hi: float) -> tuple[np.ndarray, np.ndarray]:
    """Nodes k and weights w with Σ w f(k) ≈ ∫ f dk over [k_lo, k_hi].

    Gauss–Legendre in s = ln k (dk = k ds): :data:`_PANELS_PER_DECADE` panels per
    decade, :data:`_NODES` nodes each.
    """
    panels = max(1, int(np.ceil(_PANELS_PER_DECADE * np.log10(k_hi / k_lo))))
    nodes, weights = leggauss(_NODES)
    bounds = np.linspace(np.log(k_lo), np.log(k_hi), panels + 1)
    half = 0.5 * np.diff(bounds)
    s = (bounds[:-1, None] + half[:, None] * (nodes[None, :] + 1.0)).ravel()
    k = np.exp(s)
    return k, (half[:, None] * weights[None, :]).ravel() * k


def plateau_epsilon_reference(
    dll,
    r: np.ndarray,
    *,
    r_range: tuple[float, float],
    method: str = "max",
    kolmogorov_c2: float = REFERENCE_C2,
) -> float:
    """The ε estimator's plateau on an exact D_LL, m²/s³.

    ε(r) = (D_LL(r)/C₂)^{3/2}/r at the separations ``r`` inside ``r_range``: its
    maximum or its mean, as the stack takes the plateau over its bins. Divided by the
    input ε it is the finite-Reynolds plateau deficit of the estimator
    (docs/flow.md §2.4): what a correct measurement of ε comes out at.

    Parameters
    ----------
    dll : callable(r) -> D_LL(r)
        The exact D_LL, m²/s², computed apart from the stack: :func:`exact_dll` of a
        spectrum, or :func:`modal_dll` of a DNS's modes.
    r : array_like
        Separations, m (e.g. the mean pair separation of each bin; NaN ones are left out).
    r_range : (float, float)
        Plateau range, m.
    method : {"max", "mean"}
        Maximum or mean of ε(r) over the separations in the range.
    kolmogorov_c2 : float
        C₂ (default :data:`REFERENCE_C2`).
    """
    if method not in ("max", "mean"):
        raise ValueError(f"method must be 'max' or 'mean', got {method!r}")
    r = np.asarray(r, dtype=float)
    r = r[np.isfinite(r) & (r >= r_range[0]) & (r <= r_range[1])]
    if not r.size:
        raise ValueError(f"no separation inside the plateau range {r_range}")
    epsilon = (dll(r) / kolmogorov_c2) ** 1.5 / r
    return float(epsilon.max() if method == "max" else epsilon.mean())


def modal_dll(k: np.ndarray, energy: np.ndarray, r: np.ndarray) -> np.ndarray:
    """D_LL(r) = 4 Σ e_k [1/3 − j₁(kr)/(kr)] of a periodic field's modes grouped by |k|
    (energies e_k, m²/s²; wavenumbers k, 1/m), m²/s², the shape of r: the direction
    average of the field's exact structure function (docs/dns.md §9)."""
    r = np.asarray(r, dtype=float)
    x = np.multiply.outer(r.ravel(), np.asarray(k, dtype=float))
    kernel = 1.0 / 3.0 - spherical_jn(1, x) / x
    return (4.0 * kernel @ np.asarray(energy, dtype=float)).reshape(r.shape)


def intercept_standard_error(dt: np.ndarray, snapshot_means) -> np.ndarray:
    """σ of β₀ of the line ⟨ΔX⟩ = αΔt + β₀ through the K run means, per component, m.

    Each run's mean has the standard error s_k = std(snapshot means)/√M_k (snapshots
    are the independent units); with weights w = 1/s_k² the intercept of the weighted
    line has Var β₀ = Σwx²/(Σw Σwx² − (Σwx)²), x = Δt.

    Parameters
    ----------
    dt : ndarray, shape (K,)
        Δt of the runs, s.
    snapshot_means : sequence of K ndarray, shape (M_k, 3)
        Mean displacement of each snapshot of each run, m.

    Returns
    -------
    ndarray, shape (3,)
    """
    se = np.array([np.std(m, axis=0, ddof=1) / np.sqrt(len(m)) for m in snapshot_means])
    w = 1.0 / se**2  # (K, 3)
    x = np.asarray(dt, dtype=float)[:, None]
    s, sx, sxx = w.sum(axis=0), (w * x).sum(axis=0), (w * x * x).sum(axis=0)
    return np.sqrt(sxx / (s * sxx - sx**2))
