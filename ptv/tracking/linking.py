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

Time-resolved (:func:`track_frames`). Frames τ apart are linked one step at a time with
the same assignment. A track of one point is predicted by the mean displacement over τ
(or stays where it is) and searched within ``radius``; a longer track by constant
velocity, X̂_{f+1} = 2 X_f − X_{f−1}, within ``predicted_radius``, which can be much
smaller: the prediction misses by the acceleration a τ² and the noise of three
positions, not by the whole displacement. Each candidate link is also judged by the
frame after (a look-ahead): the track continued through the candidate at constant
velocity should meet a point there. A particle left unlinked starts a track; a track
that finds no partner is kept alive for up to ``gap`` frames and predicted across them
(gap closing), then ends.

Trajectory test (:func:`trajectory_residuals`). A particle followed from the same X(t)
to every Δt (a shared first frame) has displacements on a smooth curve in Δt; a large
residual about it marks a mislink at some Δt.

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

    Examples
    --------
    At Δt = 1 ms, u′ = 0.2 m/s and 30 µm of position noise: 1 mm for the motion and
    0.15 mm for the noise.

    >>> import ptv
    >>> round(ptv.search_radius(1e-3, u_rms=0.2, sigma_b=30e-6), 9)  # m
    0.00115
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


def _link_step(predicted, radius, targets, continuation=None):
    """One-to-one links from predictions to targets; (i, j, d, ambiguous, candidates).

    ``continuation``, a function of the candidate pairs (i, j) → a cost in [0, 1] each,
    is averaged with (d / r)² into the cost of each candidate link (None: (d / r)² alone).
    """
    i, j, d = _candidates(predicted, radius, targets)
    cost = (d / radius[i]) ** 2
    if continuation is not None and len(i):
        cost = (cost + continuation(i, j)) / 2
    chosen = assign(i, j, cost, (len(predicted), len(targets)))
    chosen = chosen[np.argsort(i[chosen], kind="stable")]
    # Of the links, those whose particle had another candidate (a fraction of the links).
    ambiguous = int(np.sum(np.bincount(i, minlength=len(predicted))[i[chosen]] > 1))
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
        Links whose particle of frame a had more than one candidate within the radius.
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

    Examples
    --------
    Three particles moved 0.2 mm along X, listed in another order in frame b:

    >>> import numpy as np
    >>> import ptv
    >>> frame_a = np.array([[0.0, 0.0, 0.0], [5e-3, 0.0, 0.0], [0.0, 5e-3, 0.0]])  # m
    >>> frame_b = (frame_a + [2e-4, 0.0, 0.0])[[2, 0, 1]]
    >>> links = ptv.link(frame_a, frame_b, radius=1e-3)
    >>> links.index_a, links.index_b
    (array([0, 1, 2]), array([1, 2, 0]))
    >>> links.displacements  # ΔX, m
    array([[0.0002, 0.    , 0.    ],
           [0.0002, 0.    , 0.    ],
           [0.0002, 0.    , 0.    ]])
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
    """Tracks through a sequence of frames, one row per tracked point.

    Every point of every frame belongs to exactly one track (a particle never linked is
    a track of one point). Rows are sorted by track, then frame; the frames of a track
    increase, consecutive unless the tracking closed gaps.

    Attributes
    ----------
    track : ndarray of int, shape (K,)
        Track id, 0 … T − 1, numbered in the order the tracks start (frame, then row).
    frame : ndarray of int, shape (K,)
        Index f of the frame in the sequence, 0 … F − 1.
    index : ndarray of int, shape (K,)
        Row of the point in its frame's input array.
    positions : ndarray, shape (K, 3)
        The points, m, as given.
    n_frames : int
        Frames F of the sequence.
    """

    track: np.ndarray
    frame: np.ndarray
    index: np.ndarray
    positions: np.ndarray
    n_frames: int

    def __post_init__(self) -> None:
        k = len(self.track)
        shapes = [np.shape(a) for a in (self.track, self.frame, self.index, self.positions)]
        if shapes != [(k,), (k,), (k,), (k, 3)]:
            raise ValueError(
                f"track, frame, index (K,) and positions (K, 3) must align, got {shapes}"
            )
        same = np.diff(self.track) == 0
        if k and (self.track[0] != 0 or np.any(np.diff(self.track) > 1)):
            raise ValueError("track ids must run 0 … T − 1 without gaps")
        if np.any(np.diff(self.track) < 0) or np.any(np.diff(self.frame)[same] < 1):
            raise ValueError("rows must be sorted by track, then by increasing frames")

    def __len__(self) -> int:
        return len(self.track)

    @property
    def n_tracks(self) -> int:
        """Number of tracks T."""
        return int(self.track[-1]) + 1 if len(self.track) else 0

    @property
    def lengths(self) -> np.ndarray:
        """Points per track, shape (T,)."""
        return np.bincount(self.track, minlength=self.n_tracks)

    @property
    def links(self) -> int:
        """Links between consecutive points of a track, K − T."""
        return len(self.track) - self.n_tracks


def predicted_radii(steps, predicted_radius: float, predicted_noise: float = 0.0) -> np.ndarray:
    """Search radius around a constant-velocity prediction ``steps`` frames ahead, m.

    The prediction from a track's last two points, s frames ahead, misses its particle by
    ½aτ²s(s + 1) under a constant acceleration a, and by the noise of three positions,
    σ_b√(2(s² + s + 1)) per component: √6σ_b one frame ahead, growing as
    √((s² + s + 1)/3). So the part ``predicted_noise`` of the one-frame radius is scaled
    by the latter and the rest by s(s + 1)/2 (with no noise part given, the whole
    radius, as the acceleration: never less).

    Parameters
    ----------
    steps : array_like of int
        Frames ahead, s >= 1.
    predicted_radius : float
        The radius one frame ahead, m.
    predicted_noise : float
        Its part from the position noise, m, 0 … ``predicted_radius``.

    Returns
    -------
    ndarray
        Shaped as ``steps``.
    """
    s = np.asarray(steps, dtype=float)
    acceleration = predicted_radius - predicted_noise
    return acceleration * s * (s + 1) / 2 + predicted_noise * np.sqrt((s * s + s + 1) / 3)


def track_frames(
    frames: Sequence[np.ndarray],
    *,
    radius: float,
    predicted_radius: float | None = None,
    predicted_noise: float = 0.0,
    predictor: Predictor = None,
    gap: int = 0,
    lookahead: bool = True,
) -> Tracks:
    """Time-resolved tracking: link the particles of frames τ apart into tracks.

    In each frame every track that has a point in the previous frame, and every track of
    two points or more whose last point is at most ``gap`` frames older (a particle
    missed in between), predicts where its particle is: at constant velocity from its
    last two points where it has them, else at its point plus the mean displacement. The
    predictions are linked one-to-one to the frame's points, each within its radius, at
    the least total cost; a point left over starts a track. The cost of a link is
    (distance / radius)², averaged, with ``lookahead``, with the cost of continuing it one
    frame further (:func:`_continuation`): among close candidates the one whose
    particle is where the track says it goes next wins, as the multi-frame choices of
    four-frame trackers do.

    Parameters
    ----------
    frames : sequence of F ndarray, shape (N_f, 3)
        Particle positions in each frame, m, in any order.
    radius : float
        Search radius, m, of the first link of a track, around its point plus the mean
        displacement (e.g. :func:`search_radius` with Δt = τ).
    predicted_radius : float, optional
        Search radius, m, around the constant-velocity prediction of a track of two
        points or more, one frame ahead; ``radius`` by default. About k (a τ² + √6 σ_b)
        suffices, a the largest acceleration and σ_b the position noise. s frames ahead
        (across a gap) it is scaled as :func:`predicted_radii` scales it.
    predicted_noise : float
        The part of ``predicted_radius`` from the position noise (k√6σ_b), m.
    predictor : callable, array of shape (3,) or None
        Mean displacement over one frame interval τ, as in :func:`link` (None: none).
    gap : int
        Frames a track may miss and still be continued (0: none).
    lookahead : bool
        Weigh each candidate link by how well it continues into the next frame.

    Returns
    -------
    Tracks

    Examples
    --------
    Four particles at constant velocity through six frames, listed in any order in each;
    particle 0 is missed in frame 3. Without gap closing its track breaks in two; with
    ``gap=1`` every track is whole, and each moves by one constant step per frame:

    >>> import numpy as np
    >>> import ptv
    >>> rng = np.random.default_rng(0)
    >>> start = rng.uniform(-5e-3, 5e-3, (4, 3))  # m
    >>> step = rng.normal(0, 2e-4, (4, 3))  # displacement per frame, m
    >>> frames = [start + f * step for f in range(6)]
    >>> frames[3] = frames[3][1:]
    >>> frames = [rng.permutation(points) for points in frames]
    >>> ptv.track_frames(frames, radius=1e-3, predicted_radius=1e-4).n_tracks
    5
    >>> tracks = ptv.track_frames(frames, radius=1e-3, predicted_radius=1e-4, gap=1)
    >>> tracks.n_tracks, tracks.lengths
    (4, array([6, 6, 5, 6]))
    >>> tracks.frame[tracks.track == 2]  # across the missed frame
    array([0, 1, 2, 4, 5])
    >>> def steps(k):  # displacement per frame along track k, m
    ...     on = tracks.track == k
    ...     return np.diff(tracks.positions[on], axis=0) / np.diff(tracks.frame[on])[:, None]
    >>> all(np.allclose(steps(k), steps(k)[0]) for k in range(tracks.n_tracks))
    True
    """
    xs = [_frame(f"frame {f}", x) for f, x in enumerate(frames)]
    r_first = _radius("radius", radius)
    r_next = r_first if predicted_radius is None else _radius("predicted_radius", predicted_radius)
    if not (np.isfinite(predicted_noise) and 0 <= predicted_noise <= r_next):
        raise ValueError(
            f"predicted_noise must be from 0 to the predicted radius (m), got {predicted_noise!r}"
        )
    if not isinstance(gap, int | np.integer) or gap < 0:
        raise ValueError(f"gap must be an integer >= 0 frames, got {gap!r}")
    if not xs:
        return _sorted_tracks([], xs)
    total = sum(len(x) for x in xs)
    last = np.full((total, 3), np.nan)  # per track: its last point,
    velocity = np.full((total, 3), np.nan)  # its displacement per frame (NaN: one point)
    last_frame = np.full(total, -1, dtype=np.int64)  # and the frame of its last point
    labels = [np.arange(len(xs[0]))]
    last[: len(xs[0])], last_frame[: len(xs[0])] = xs[0], 0
    started = len(xs[0])
    for f in range(1, len(xs)):
        alive = np.flatnonzero(
            (last_frame == f - 1) | ((last_frame >= f - 1 - gap) & ~np.isnan(velocity[:, 0]))
        )
        steps = f - last_frame[alive]
        has_velocity = ~np.isnan(velocity[alive, 0])
        predicted = last[alive] + steps[:, None] * np.where(
            has_velocity[:, None], velocity[alive], 0.0
        )
        fresh = ~has_velocity
        predicted[fresh] += _mean_displacement(predictor, last[alive][fresh])
        radii = np.where(has_velocity, predicted_radii(steps, r_next, predicted_noise), r_first)
        continuation = None
        if lookahead and f + 1 < len(xs):
            continuation = _continuation(last[alive], steps, xs[f], xs[f + 1], r_next)
        i, j, _, ambiguous, _ = _link_step(predicted, radii, xs[f], continuation)
        label = np.full(len(xs[f]), -1)
        label[j] = alive[i]
        new = label < 0
        label[new] = started + np.arange(np.count_nonzero(new))
        started += np.count_nonzero(new)
        linked = alive[i]
        velocity[linked] = (xs[f][j] - last[linked]) / (f - last_frame[linked])[:, None]
        last[label], last_frame[label] = xs[f], f
        labels.append(label)
        log.debug(
            "frame %d: %d links (%d across a gap), %d tracks started, %d ambiguous",
            f,
            len(i),
            int(np.count_nonzero(steps[i] > 1)),
            np.count_nonzero(new),
            ambiguous,
        )
    return _sorted_tracks(labels, xs)


def _continuation(start, steps, here, ahead, radius: float):
    """The cost of continuing each candidate link one frame further.

    A track whose last point ``start[i]`` (``steps[i]`` frames back) is linked to
    ``here[j]`` predicts its particle at constant velocity one frame further; the cost
    is (d / ``radius``)² for the nearest point of ``ahead`` at d from that prediction,
    1 where none lies within ``radius`` (the constant-velocity radius one frame ahead).

    Parameters
    ----------
    start : ndarray, shape (A, 3)
        The last point of each track searching, m.
    steps : ndarray of int, shape (A,)
        Frames from that point to this frame.
    here, ahead : ndarray, shape (N, 3) and (M, 3)
        The points of this frame and of the next, m.
    radius : float
        m.

    Returns
    -------
    callable
        (i, j) candidate pairs, ndarray of int, shape (E,) each → costs in [0, 1], (E,).
    """
    tree = cKDTree(ahead) if len(ahead) else None

    def cost(i, j):
        if tree is None:
            return np.ones(len(i))
        x = here[j]
        predicted = x + (x - start[i]) / steps[i, None]
        d, _ = tree.query(predicted, distance_upper_bound=radius)
        return np.minimum((d / radius) ** 2, 1.0)

    return cost


def _sorted_tracks(labels: list[np.ndarray], xs: list[np.ndarray]) -> Tracks:
    """:class:`Tracks` from the track id of every row of every frame."""
    if not labels or not sum(len(x) for x in xs):
        empty = np.empty(0, dtype=np.int64)
        return Tracks(empty, empty, empty, np.empty((0, 3)), len(xs))
    track = np.concatenate(labels).astype(np.int64)
    frame = np.concatenate([np.full(len(x), f, dtype=np.int64) for f, x in enumerate(xs)])
    index = np.concatenate([np.arange(len(x), dtype=np.int64) for x in xs])
    order = np.lexsort((frame, track))
    return Tracks(track[order], frame[order], index[order], np.concatenate(xs)[order], len(xs))


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


@dataclass(frozen=True, eq=False)
class RecordingTracks:
    """The tracks through consecutive frames of a recording.

    Attributes
    ----------
    numbers : ndarray of int, shape (F,)
        Frame numbers n of the frames tracked (``tracks.frame`` indexes them).
    frame_rate : float
        Frames per second, Hz; frame n was taken at n / frame_rate.
    detections : ndarray of int, shape (F, C)
        Particles detected per frame and camera.
    tracks : Tracks
        Every matched point of every frame, with its track.
    radius, predicted_radius : float
        The search radii used (:func:`ptv.pipeline.time_resolved.track_radii`), m.
    gap : int
        Missed frames a track could close (:func:`track_frames`).
    joins : int
        Tracks joined after the frame-by-frame tracking
        (:func:`ptv.tracking.stitching.stitch_tracks`).
    miss_noise : float or None
        The noise of the first pass's predictions, m (None with too few of them); twice
        it sets the second pass's radius where that is below the settings' noise
        (:func:`ptv.pipeline.time_resolved.track_points`).
    """

    numbers: np.ndarray
    frame_rate: float
    detections: np.ndarray
    tracks: Tracks
    radius: float
    predicted_radius: float
    gap: int = 0
    joins: int = 0
    miss_noise: float | None = None

    @property
    def frame_number(self) -> np.ndarray:
        """Frame number n of every tracked point, shape (K,)."""
        return self.numbers[self.tracks.frame]

    @property
    def time(self) -> np.ndarray:
        """Time n / frame_rate of every tracked point, s, shape (K,)."""
        return self.frame_number / self.frame_rate

    @property
    def matches(self) -> np.ndarray:
        """Matched points per frame, shape (F,)."""
        return np.bincount(self.tracks.frame, minlength=len(self.numbers))
