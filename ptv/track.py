"""Particle tracking: double-frame links at Δt and time-resolved tracks (docs/ptv.md §4).

Double frame (:func:`link`). Each particle at t is predicted at t + Δt (by a mean
displacement, when given) and linked to a particle at t + Δt within the search radius

    r = k_v u′ Δt + k_b σ_b            (:func:`search_radius`),

a Δt-scaled threshold as docs/statistics.md §9 asks (5 u′Δt + 5 σ_b by default): a fixed radius
would cut the tails of the displacement distribution at large Δt and let mismatches in
at small Δt. Ambiguities are resolved one-to-one by the minimum total cost assignment
with cost (d/r)² per link, d the distance from the prediction, and cost 1 per particle
left unlinked (exact; see ``ptv._assign``): the Gaussian log-likelihood choice, which
links as many particles as it can and, among those, minimises the sum of squared
distances.

Time-resolved (:func:`track_frames`). Frames τ apart are linked step by step with the
same assignment: a track of one point is predicted by the mean displacement (radius
``radius``), a longer track by constant velocity, X̂ = 2 X_f − X_{f−1} (radius
``predicted_radius``). Unlinked particles start new tracks; a track that finds no
partner ends (no gap closing).

Skip-frame increments (:func:`skip_pairs`). For Δt = mτ, m ∈ {m_1 … m_K}, the pairs
(X(t), X(t + m τ)) are taken from the same track segments of m_max + 1 frames for every
m, so the particle population — and its selection bias — does not change with Δt.

Selection of the analysis volume (bin by X(t) inside it; docs/statistics.md §2) and mean-flow
subtraction are left to the statistics; nothing here filters or smooths positions.
"""

import logging
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ptv._assign import assign

log = logging.getLogger(__name__)

#: A mean-displacement predictor: positions (N, 3) → mean displacements (N, 3), m; or
#: one constant displacement (3,), m; or None for no mean displacement.
Predictor = Callable[[np.ndarray], np.ndarray] | np.ndarray | Sequence[float] | None


def search_radius(
    dt: float, *, u_rms: float, sigma_b: float = 0.0, k_v: float = 5.0, k_b: float = 5.0
) -> float:
    """Δt-scaled search radius r = k_v u′ Δt + k_b σ_b, m.

    Parameters
    ----------
    dt : float
        Δt, s.
    u_rms : float
        Velocity scale u′ (rms of one component of the fluctuation), m/s.
    sigma_b : float
        Position noise σ_b (rms, one component), m.
    k_v, k_b : float
        Multipliers (docs/ptv.md §4: 5 and 5 by default).

    Returns
    -------
    float
    """
    values = {"dt": dt, "u_rms": u_rms, "sigma_b": sigma_b, "k_v": k_v, "k_b": k_b}
    for name, value in values.items():
        if not (np.isfinite(value) and value >= 0):
            raise ValueError(f"{name} must be finite and >= 0, got {value!r}")
    radius = k_v * u_rms * dt + k_b * sigma_b
    if radius <= 0:
        raise ValueError(f"search radius must come out > 0, got {radius} from {values}")
    return float(radius)


def _frame(name: str, x) -> np.ndarray:
    x = np.asarray(x, dtype=float)
    if x.ndim == 1 and x.size == 0:
        x = x.reshape(0, 3)
    if x.ndim != 2 or x.shape[1] != 3:
        raise ValueError(f"{name} must have shape (N, 3), got {x.shape}")
    if not np.isfinite(x).all():
        raise ValueError(f"{name} holds {np.count_nonzero(~np.isfinite(x))} non-finite values")
    return x


def _radius(name: str, value) -> float:
    if not (np.isfinite(value) and value > 0):
        raise ValueError(f"{name} must be finite and > 0 (m), got {value!r}")
    return float(value)


def _mean_displacement(predictor: Predictor, x: np.ndarray) -> np.ndarray:
    if predictor is None:
        return np.zeros_like(x)
    if callable(predictor):
        d = np.asarray(predictor(x), dtype=float)
        if d.shape != x.shape:
            raise ValueError(
                f"the predictor must return displacements of shape {x.shape}, got {d.shape}"
            )
    else:
        d = np.asarray(predictor, dtype=float)
        if d.shape != (3,):
            raise ValueError(
                f"a constant predictor must be a displacement of shape (3,), got {d.shape}"
            )
        d = np.broadcast_to(d, x.shape)
    if not np.isfinite(d).all():
        raise ValueError("the predictor returned non-finite displacements")
    return d


def _candidates(predicted: np.ndarray, radius: np.ndarray, targets: np.ndarray):
    """Pairs (i, j) with |targets[j] − predicted[i]| ≤ radius[i], and their distances."""
    if len(predicted) == 0 or len(targets) == 0:
        empty = np.empty(0, dtype=np.int64)
        return empty, empty, np.empty(0)
    found = cKDTree(predicted).sparse_distance_matrix(
        cKDTree(targets), float(radius.max()), output_type="ndarray"
    )
    i = found["i"].astype(np.int64)
    j = found["j"].astype(np.int64)
    d = found["v"]
    keep = d <= radius[i]
    return i[keep], j[keep], d[keep]


def _link_step(predicted, radius, targets):
    """One-to-one links from predictions to targets; (i, j, d, ambiguous, candidates)."""
    i, j, d = _candidates(predicted, radius, targets)
    ambiguous = int(np.sum(np.bincount(i, minlength=len(predicted)) > 1))
    chosen = assign(i, j, (d / radius[i]) ** 2, (len(predicted), len(targets)))
    chosen = chosen[np.argsort(i[chosen], kind="stable")]
    return i[chosen], j[chosen], d[chosen], ambiguous, len(i)


@dataclass(frozen=True, eq=False)
class Links:
    """Particles linked from frame a (time t) to frame b (t + Δt).

    Attributes
    ----------
    index_a, index_b : ndarray of int, shape (N,)
        Rows of the linked particles in frame a and frame b.
    positions : ndarray, shape (N, 3)
        X(t), m.
    displacements : ndarray, shape (N, 3)
        ΔX = X(t + Δt) − X(t), m.
    ambiguous : int
        Particles of frame a with more than one candidate within the radius.
    candidates : int
        Candidate links before the one-to-one resolution.
    """

    index_a: np.ndarray
    index_b: np.ndarray
    positions: np.ndarray
    displacements: np.ndarray
    ambiguous: int
    candidates: int

    def __len__(self) -> int:
        return len(self.index_a)


def link(frame_a, frame_b, *, radius: float, predictor: Predictor = None) -> Links:
    """Link the particles of two frames one-to-one (double-frame PTV).

    Parameters
    ----------
    frame_a, frame_b : ndarray, shape (N_a, 3) and (N_b, 3)
        Measured particle positions at t and t + Δt, m, in any order.
    radius : float
        Search radius around each prediction, m; see :func:`search_radius`.
    predictor : callable, array of shape (3,) or None
        Mean displacement over Δt: a function of the positions at t (N, 3) → (N, 3),
        or one constant vector, m. The prediction is X(t) + mean displacement.

    Returns
    -------
    Links
        Ordered by ``index_a``.
    """
    a = _frame("frame_a", frame_a)
    b = _frame("frame_b", frame_b)
    r = _radius("radius", radius)
    predicted = a + _mean_displacement(predictor, a) if len(a) else a
    i, j, _, ambiguous, candidates = _link_step(predicted, np.full(len(a), r), b)
    log.debug("linked %d of %d → %d particles (%d ambiguous)", len(i), len(a), len(b), ambiguous)
    return Links(
        index_a=i,
        index_b=j,
        positions=a[i],
        displacements=b[j] - a[i],
        ambiguous=ambiguous,
        candidates=candidates,
    )


@dataclass(frozen=True, eq=False)
class Tracks:
    """Tracks through a sequence of frames, one row per tracked observation.

    Rows are sorted by track, then frame; frames within a track are consecutive.

    Attributes
    ----------
    track : ndarray of int, shape (K,)
        Track id, 0 … T − 1.
    frame : ndarray of int, shape (K,)
        Frame number f (time f τ).
    index : ndarray of int, shape (K,)
        Row of the observation in its frame's input array.
    positions : ndarray, shape (K, 3)
        Measured positions, m.
    n_frames : int
        Number of frames F of the sequence.
    """

    track: np.ndarray
    frame: np.ndarray
    index: np.ndarray
    positions: np.ndarray
    n_frames: int

    def __post_init__(self) -> None:
        k = len(self.track)
        if not (
            np.shape(self.frame) == np.shape(self.index) == (k,)
            and np.shape(self.positions) == (k, 3)
        ):
            raise ValueError(
                f"track, frame, index (K,) and positions (K, 3) must align, got "
                f"{np.shape(self.track)}, {np.shape(self.frame)}, {np.shape(self.index)}, "
                f"{np.shape(self.positions)}"
            )
        if k and not (
            self.track[0] >= 0
            and np.all(np.diff(self.track) >= 0)
            and np.all((np.diff(self.frame) > 0) | (np.diff(self.track) > 0))
        ):
            raise ValueError("tracks must be sorted by track id, then by increasing frame")

    @property
    def n_tracks(self) -> int:
        """Number of tracks T."""
        return int(self.track[-1]) + 1 if len(self.track) else 0

    @property
    def lengths(self) -> np.ndarray:
        """Points per track, shape (T,)."""
        return np.bincount(self.track, minlength=self.n_tracks)

    def ids(self, frame: int, size: int) -> np.ndarray:
        """Track id of each of the ``size`` particles of ``frame`` (−1: none), shape (size,)."""
        out = np.full(size, -1, dtype=np.int64)
        sel = self.frame == frame
        out[self.index[sel]] = self.track[sel]
        return out


def track_frames(
    frames: Sequence[np.ndarray],
    *,
    radius: float,
    predicted_radius: float | None = None,
    predictor: Predictor = None,
) -> Tracks:
    """Time-resolved tracking: link frames τ apart into tracks.

    Parameters
    ----------
    frames : sequence of F ndarray, shape (N_f, 3)
        Measured positions in each frame, m, in any order.
    radius : float
        Search radius of a track's first link, around X + mean displacement, m
        (e.g. :func:`search_radius` with Δt = τ).
    predicted_radius : float, optional
        Search radius around the constant-velocity prediction of a longer track, m;
        ``radius`` by default. About k·(a′τ² + √6 σ_b) suffices.
    predictor : callable, array of shape (3,) or None
        Mean displacement over one frame interval τ, as in :func:`link`.

    Returns
    -------
    Tracks
    """
    xs = [_frame(f"frame {f}", x) for f, x in enumerate(frames)]
    r0 = _radius("radius", radius)
    r1 = r0 if predicted_radius is None else _radius("predicted_radius", predicted_radius)
    if not xs:
        return _tracks([], [], [], [], 0)
    # Active tracks: ids, the row of their last point in the current frame, previous point.
    ids = np.arange(len(xs[0]))
    rows = np.arange(len(xs[0]))
    previous = np.full((len(xs[0]), 3), np.nan)
    next_id = len(xs[0])
    obs_track, obs_frame, obs_index = [ids], [np.zeros(len(ids), dtype=np.int64)], [rows]
    for f in range(1, len(xs)):
        current = xs[f - 1][rows]
        first = np.isnan(previous[:, 0])
        predicted = current.copy()
        if first.any():
            predicted[first] += _mean_displacement(predictor, current[first])
        predicted[~first] = 2 * current[~first] - previous[~first]
        r = np.where(first, r0, r1)
        i, j, _, ambiguous, _ = _link_step(predicted, r, xs[f])
        new = np.setdiff1d(np.arange(len(xs[f])), j, assume_unique=True)
        new_ids = next_id + np.arange(len(new))
        next_id += len(new)
        ids = np.concatenate([ids[i], new_ids])
        previous = np.concatenate([current[i], np.full((len(new), 3), np.nan)])
        rows = np.concatenate([j, new])
        obs_track.append(ids)
        obs_frame.append(np.full(len(ids), f, dtype=np.int64))
        obs_index.append(rows)
        log.debug("frame %d: %d links, %d new tracks, %d ambiguous", f, len(i), len(new), ambiguous)
    positions = [xs[f][rows] for f, rows in enumerate(obs_index)]
    return _tracks(obs_track, obs_frame, obs_index, positions, len(xs))


def _tracks(track, frame, index, positions, n_frames) -> Tracks:
    if not track:
        empty = np.empty(0, dtype=np.int64)
        return Tracks(empty, empty, empty, np.empty((0, 3)), n_frames)
    track = np.concatenate(track).astype(np.int64)
    frame = np.concatenate(frame).astype(np.int64)
    index = np.concatenate(index).astype(np.int64)
    positions = np.concatenate(positions).reshape(-1, 3)
    order = np.lexsort((frame, track))
    return Tracks(track[order], frame[order], index[order], positions[order], n_frames)


@dataclass(frozen=True, eq=False)
class SkipPairs:
    """Increments at Δt = m τ over the same track segments for every m.

    Attributes
    ----------
    skips : ndarray of int, shape (K,)
        m_1 < … < m_K.
    positions : ndarray, shape (P, 3)
        X(t) at the start of each segment, m.
    displacements : ndarray, shape (P, K, 3)
        X(t + m_k τ) − X(t), m (the layout ``ptv.stats`` expects).
    track : ndarray of int, shape (P,)
        Track of each segment.
    frame : ndarray of int, shape (P,)
        Start frame of each segment.
    """

    skips: np.ndarray
    positions: np.ndarray
    displacements: np.ndarray
    track: np.ndarray
    frame: np.ndarray

    def __len__(self) -> int:
        return len(self.positions)


def skip_pairs(tracks: Tracks, skips: Sequence[int], *, stride: int = 1) -> SkipPairs:
    """Pairs (X(t), X(t + mτ)) for every skip m from the same track segments.

    A segment is m_max + 1 consecutive points of one track; every m uses every
    segment, so the starting points X(t) — and the population — are identical for
    all m (docs/ptv.md §4). Tracks shorter than m_max + 1 contribute nothing.

    Parameters
    ----------
    tracks : Tracks
        Output of :func:`track_frames`.
    skips : sequence of int
        The skips m ≥ 1 (Δt = m τ); sorted and made unique.
    stride : int
        Start a segment every ``stride`` frames along a track (1: every frame, the
        segments overlapping; m_max + 1: disjoint segments).

    Returns
    -------
    SkipPairs
    """
    m = np.unique(np.asarray(skips))
    if m.ndim != 1 or m.size == 0 or not np.issubdtype(m.dtype, np.integer) or m[0] < 1:
        raise ValueError(f"skips must be integers >= 1, got {skips!r}")
    if not isinstance(stride, int | np.integer) or stride < 1:
        raise ValueError(f"stride must be an integer >= 1, got {stride!r}")
    m_max = int(m[-1])
    k = len(tracks.track)
    start = np.arange(max(k - m_max, 0))
    end = start + m_max
    ok = (tracks.track[end] == tracks.track[start]) & (
        tracks.frame[end] == tracks.frame[start] + m_max
    )
    if len(start):
        first = np.r_[True, tracks.track[1:] != tracks.track[:-1]]
        track_start = np.maximum.accumulate(np.where(first, np.arange(k), 0))
        ok &= (tracks.frame[start] - tracks.frame[track_start[start]]) % stride == 0
    start = start[ok]
    x0 = tracks.positions[start]
    ends = tracks.positions[start[:, None] + m[None, :]]
    return SkipPairs(
        skips=m.astype(np.int64),
        positions=x0,
        displacements=ends - x0[:, None, :],
        track=tracks.track[start],
        frame=tracks.frame[start],
    )


def trajectory_residuals(dt, displacements) -> np.ndarray:
    """RMS residual of each particle's displacements about a smooth path in Δt.

    For a particle followed from the same X(t) to every Δt_k (a shared first frame, or
    the skip-frame pairs of one track), the displacements lie on
    ΔX_k = c + u Δt_k + ½ a Δt_k² up to the position noise of each end (the constant c
    absorbs the noise of the shared start). The Δt³ term, ~0.1 µm at Δt ≈ 0.2 τ_η,
    leaves a residual of a few nm after the quadratic fit; a link to the wrong particle
    at one Δt leaves one far above the noise.

    Parameters
    ----------
    dt : array_like, shape (K,)
        Time separations, s, K ≥ 4 (three parameters per component).
    displacements : array_like, shape (P, K, 3)
        ΔX of P particles at every Δt, m.

    Returns
    -------
    ndarray, shape (P,)
        sqrt(mean over k and components of the squared residual), m.
    """
    dt = np.asarray(dt, dtype=float)
    d = np.asarray(displacements, dtype=float)
    if dt.ndim != 1 or dt.size < 4:
        raise ValueError(f"need at least 4 Δt values for a trajectory fit, got {dt.size}")
    if d.ndim != 3 or d.shape[1:] != (dt.size, 3):
        raise ValueError(f"displacements must have shape (P, {dt.size}, 3), got {d.shape}")
    design = np.stack([np.ones_like(dt), dt, dt**2], axis=1)
    y = d.transpose(1, 0, 2).reshape(dt.size, -1)
    coef, *_ = np.linalg.lstsq(design, y, rcond=None)
    residual = (y - design @ coef).reshape(dt.size, len(d), 3)
    return np.sqrt(np.mean(residual**2, axis=(0, 2)))
