"""Stereo correspondence: which detections of C ≥ 2 cameras image the same particle.

Only the calibration protocol is used (``pixel_to_ray``; docs/ptv.md §3). A candidate
is a set of detections, one per camera in at least ``min_cameras`` cameras, whose rays
all pass within ``tolerance`` of their least-squares point, that point lying inside
the measurement volume (an axis-aligned box). The pipeline measures the tolerance on
the rig and the data (:mod:`ptv.matching.tolerance`); the volume is the illuminated
slab with a margin of about the tolerance.

Candidate search (vectorised, no all-pairs loop). Rays are parametrised along the
box's depth axis ζ (the axis the rays cross most steeply, Z for the paper's rig): a ray
is its crossing point a (2-D) with the mid-plane ζ₀ and its slope s = dxy/dζ. Two rays
meeting within the tolerance at some depth ζ ∈ [ζ₀ − h, ζ₀ + h] have
a₂ − a₁ = −(s₂ − s₁)(ζ − ζ₀) + δ with |δ| ≤ tol·(1 + max|s|). Projected on the mean
direction e of s₁ − s₂ and on its normal, a₂ − a₁ therefore lies in a thin rectangle:
the epipolar segment of ray 1 within the volume, mapped onto the mid-plane. A KD-tree
with the Chebyshev metric in coordinates scaled by the rectangle's half-widths finds
all pairs inside it at once; exact skew distances and closest points then decide.

Resolution of ambiguities, so that every detection is used at most once:

- Two cameras: exactly, as a minimum-cost assignment on the sparse candidate set (cost
  (d/tol)² per pair, d the skew distance; cost 1 per detection left unmatched; see
  ``ptv._assign``).
- More cameras: candidate pairs of camera pairs (enough pairs that every tuple of
  ``min_cameras`` cameras contains one) are extended by the detection of
  each other camera whose ray passes nearest to the pair's point (within the
  tolerance); the tuples are re-triangulated and checked. Tuples are then accepted
  greedily: most cameras first, then by increasing mean (d_c/tol)², skipping any
  that reuses a detection. (The multi-camera assignment is NP-hard; the greedy order
  is the usual practical choice.) The ray that extended a pair may be a stranger's:
  where a camera merged a particle's image with a neighbour's, the one detection
  there is the neighbour's, and the neighbour's own tuple takes it. So each tuple
  turned down (or failing the check) leaves the tuples one camera short of it as
  candidates of the next level (while they keep ``min_cameras``), checked like the
  others: without them, 2-of-3 matching lost a quarter of the particles that only two
  cameras detected on the box rigs (docs/run.md §10).

Matching in two cameras leaves ghosts. Two particles lying (to within the detection
noise) in one epipolar plane give four rays that all meet: the true and the swapped
pairings cost about the same, and noise decides. Measured on the paper's rig (0.1 px
noise, 100 × 100 × 10 mm sheet): ghosts 1 % at 1000 particles, 3 % at 2000, 6 % at
4000; halved at 0.05 px; hardly changed by the tolerance between 50 and 150 µm. A
detection whose partner is lost can also pair with a stranger within the tolerance.
A third camera removes almost all ghosts (< 0.2 % at 4000).
"""

import logging
from collections.abc import Sequence
from dataclasses import dataclass
from itertools import combinations

import numpy as np
from scipy.spatial import cKDTree

from ptv._assign import assign
from ptv.box import check_box
from ptv.camera_model import CameraModel, RayBundle
from ptv.rays import Rays
from ptv.triangulate import closest_points

log = logging.getLogger(__name__)

#: Default stereo tolerance on the ray distances, m (2–3× a ~60 µm calibration error).
DEFAULT_TOLERANCE = 1.5e-4


@dataclass(frozen=True, eq=False)
class Matches:
    """Corresponding detections across C cameras and their 3-D points.

    Attributes
    ----------
    indices : ndarray of int, shape (N, C)
        Row n: the detection index in each camera's input list, −1 where that camera
        has no detection in match n.
    points : ndarray, shape (N, 3)
        Least-squares points of the matched rays, m.
    ray_distances : ndarray, shape (N, C)
        Distance of each matched ray to its point, m; NaN where a camera has none.
    ambiguous : ndarray of int, shape (C,)
        Detections of each camera that took part in more than one candidate.
    candidates : int
        Number of candidates before the one-to-one resolution.
    """

    indices: np.ndarray
    points: np.ndarray
    ray_distances: np.ndarray
    ambiguous: np.ndarray
    candidates: int

    def __len__(self) -> int:
        return len(self.indices)


def _check_rays(rays: Sequence[RayBundle]) -> list[tuple[np.ndarray, np.ndarray]]:
    if len(rays) < 2:
        raise ValueError(f"matching needs at least two cameras, got {len(rays)}")
    out = []
    for c, r in enumerate(rays):
        o = np.asarray(r.origins, dtype=float)
        v = np.asarray(r.directions, dtype=float)
        if o.ndim != 2 or o.shape[1] != 3 or v.shape != o.shape:
            raise ValueError(
                f"camera {c}: ray origins and directions must both be (N, 3), "
                f"got {o.shape} and {v.shape}"
            )
        out.append((o, v))
    return out


@dataclass(frozen=True, eq=False)
class _Camera:
    """Valid rays of one camera in the permuted frame (depth axis last)."""

    index: np.ndarray  # (n,) detection indices of the valid rays
    origins: np.ndarray  # (n, 3) original frame
    directions: np.ndarray  # (n, 3) original frame
    a: np.ndarray  # (n, 2) crossing of the mid-plane ζ₀, permuted frame
    s: np.ndarray  # (n, 2) slopes dxy/dζ


def _prepare(o, v, perm, z0, h, lower_p, upper_p, slack) -> _Camera:
    valid = np.isfinite(o).all(axis=1) & np.isfinite(v).all(axis=1)
    op, vp = o[:, perm], v[:, perm]
    with np.errstate(divide="ignore", invalid="ignore"):
        s = vp[:, :2] / vp[:, 2:3]
    valid &= np.isfinite(s).all(axis=1)
    a = op[:, :2] + s * (z0 - op[:, 2:3])
    # Keep rays that cross the box (with slack) somewhere within its depth range.
    reach = np.abs(s) * h + slack
    valid &= np.all((a + reach >= lower_p[:2]) & (a - reach <= upper_p[:2]), axis=1)
    idx = np.flatnonzero(valid)
    return _Camera(idx, o[idx], v[idx], a[idx], s[idx])


def _pair_candidates(c1: _Camera, c2: _Camera, h: float, tol: float, lower, upper):
    """Candidate pairs of two cameras: local indices, skew distances and midpoints."""
    empty = np.empty(0, dtype=np.int64)
    if len(c1.a) == 0 or len(c2.a) == 0:
        return empty, empty, np.empty(0), np.empty((0, 3))
    mean = c1.s.mean(axis=0) - c2.s.mean(axis=0)
    norm = np.hypot(*mean)
    e = mean / norm if norm > 1e-12 else np.array([1.0, 0.0])
    basis = np.array([e, [-e[1], e[0]]])  # rows: along, across
    p1, p2 = c1.s @ basis.T, c2.s @ basis.T
    ds = np.maximum(np.abs(p1.max(0) - p2.min(0)), np.abs(p1.min(0) - p2.max(0)))
    slope = max(np.hypot(*c1.s.T).max(), np.hypot(*c2.s.T).max())
    half = h * ds + tol * (1.0 + slope) * (1.0 + 1e-9) + 1e-12
    q1 = (c1.a @ basis.T) / half
    q2 = (c2.a @ basis.T) / half
    found = cKDTree(q1).sparse_distance_matrix(cKDTree(q2), 1.0, p=np.inf, output_type="ndarray")
    i = found["i"].astype(np.int64)
    j = found["j"].astype(np.int64)
    o1, v1, o2, v2 = c1.origins[i], c1.directions[i], c2.origins[j], c2.directions[j]
    w = o1 - o2
    b = np.einsum("ij,ij->i", v1, v2)
    d = np.einsum("ij,ij->i", v1, w)
    f = np.einsum("ij,ij->i", v2, w)
    denom = 1.0 - b * b
    ok = denom > 1e-12
    denom = np.where(ok, denom, 1.0)
    t1 = (b * f - d) / denom
    t2 = (f - b * d) / denom
    q1p = o1 + t1[:, None] * v1
    q2p = o2 + t2[:, None] * v2
    dist = np.linalg.norm(q1p - q2p, axis=1)
    mid = 0.5 * (q1p + q2p)
    keep = ok & (dist < tol) & np.all((mid >= lower) & (mid <= upper), axis=1)
    return i[keep], j[keep], dist[keep], mid[keep]


def _nearest_rays(cam: _Camera, points: np.ndarray, z0: float, perm, tol: float):
    """For each point, the local index of cam's ray passing nearest (within tol), else −1."""
    n = len(points)
    best = np.full(n, -1, dtype=np.int64)
    dist = np.full(n, np.inf)
    if len(cam.a) == 0 or n == 0:
        return best, dist
    pp = points[:, perm]
    lo, hi = cam.s.min(axis=0), cam.s.max(axis=0)
    centre = pp[:, :2] - 0.5 * (lo + hi) * (pp[:, 2:3] - z0)
    slope = np.hypot(*cam.s.T).max()
    radius = np.abs(pp[:, 2] - z0) * 0.5 * (hi - lo).max() + tol * np.sqrt(1 + slope**2)
    hits = cKDTree(cam.a).query_ball_point(centre, radius * (1 + 1e-9) + 1e-12, p=np.inf)
    counts = np.fromiter((len(x) for x in hits), dtype=np.int64, count=n)
    if counts.sum() == 0:
        return best, dist
    k = np.fromiter((j for x in hits for j in x), dtype=np.int64, count=counts.sum())
    q = np.repeat(np.arange(n), counts)
    offset = points[q] - cam.origins[k]
    along = np.einsum("ij,ij->i", offset, cam.directions[k])
    d = np.linalg.norm(offset - along[:, None] * cam.directions[k], axis=1)
    order = np.lexsort((d, q))
    q, k, d = q[order], k[order], d[order]
    first = np.r_[True, q[1:] != q[:-1]]
    q, k, d = q[first], k[first], d[first]
    near = d < tol
    best[q[near]] = k[near]
    dist[q[near]] = d[near]
    return best, dist


def match_rays(
    rays: Sequence[RayBundle],
    volume,
    *,
    tolerance: float = DEFAULT_TOLERANCE,
    min_cameras: int = 2,
) -> Matches:
    """Match detections of C cameras given their rays.

    Parameters
    ----------
    rays : sequence of C ray bundles
        Rays of every detection of each camera (``origins``, unit ``directions``,
        (N_c, 3), m); NaN rows (outside the calibrated area) are never matched.
    volume : (lower, upper)
        Corners of the axis-aligned measurement box, each of shape (3,), m.
    tolerance : float
        Largest distance of a matched ray from the matched point, m. For two cameras
        it bounds the skew distance between the two rays.
    min_cameras : int
        Fewest cameras a match must use, from 2 (default) to C. Candidates seen by more
        cameras are preferred, so a particle seen by all C is matched with all C.

    Returns
    -------
    Matches
    """
    cams = _check_rays(rays)
    lower, upper = (np.asarray(corner) for corner in check_box("volume", volume))
    if not (np.isfinite(tolerance) and tolerance > 0):
        raise ValueError(f"tolerance must be > 0 (m), got {tolerance!r}")
    n_cam = len(cams)
    if isinstance(min_cameras, bool) or not isinstance(min_cameras, int | np.integer):
        raise ValueError(f"min_cameras must be an integer, got {min_cameras!r}")
    if not 2 <= min_cameras <= n_cam:
        raise ValueError(f"min_cameras must be in [2, {n_cam}], got {min_cameras!r}")

    # Depth axis: the one every ray crosses most steeply.
    steep = [np.nanmin(np.abs(v[np.isfinite(v).all(axis=1)]), axis=0, initial=1.0) for _, v in cams]
    axis = int(np.argmax(np.min(steep, axis=0)))
    perm = [k for k in range(3) if k != axis] + [axis]
    lower_p, upper_p = lower[perm], upper[perm]
    z0 = 0.5 * (lower_p[2] + upper_p[2])
    h = 0.5 * (upper_p[2] - lower_p[2])
    prepared = [_prepare(o, v, perm, z0, h, lower_p, upper_p, 2 * tolerance) for o, v in cams]

    if n_cam == 2:
        return _match_two(prepared, [len(o) for o, _ in cams], h, tolerance, lower, upper)
    return _match_many(
        prepared, [len(o) for o, _ in cams], h, z0, perm, tolerance, lower, upper, min_cameras
    )


def _empty(n_cam: int, ambiguous=None, candidates: int = 0) -> Matches:
    return Matches(
        indices=np.empty((0, n_cam), dtype=np.int64),
        points=np.empty((0, 3)),
        ray_distances=np.empty((0, n_cam)),
        ambiguous=np.zeros(n_cam, dtype=np.int64) if ambiguous is None else ambiguous,
        candidates=candidates,
    )


def _match_two(prepared, sizes, h, tol, lower, upper) -> Matches:
    c1, c2 = prepared
    i, j, dist, mid = _pair_candidates(c1, c2, h, tol, lower, upper)
    ambiguous = np.array(
        [
            int(np.sum(np.bincount(i, minlength=len(c1.index)) > 1)),
            int(np.sum(np.bincount(j, minlength=len(c2.index)) > 1)),
        ]
    )
    if len(i) == 0:
        return _empty(2, ambiguous)
    chosen = assign(i, j, (dist / tol) ** 2, (len(c1.index), len(c2.index)))
    indices = np.column_stack([c1.index[i[chosen]], c2.index[j[chosen]]])
    log.debug(
        "matched %d of %d × %d detections (%d candidates, %s ambiguous)",
        len(chosen),
        sizes[0],
        sizes[1],
        len(i),
        ambiguous.tolist(),
    )
    half = 0.5 * dist[chosen]
    return Matches(
        indices=indices,
        points=mid[chosen],
        ray_distances=np.column_stack([half, half]),
        ambiguous=ambiguous,
        candidates=len(i),
    )


def _match_many(prepared, sizes, h, z0, perm, tol, lower, upper, min_cameras) -> Matches:
    n_cam = len(prepared)
    tuples = []
    # A tuple of at least min_cameras cameras misses at most C − min_cameras of them,
    # so it holds two of the first C − min_cameras + 2: seeding from their pairs suffices.
    for a, b in combinations(range(n_cam - min_cameras + 2), 2):
        i, j, _, mid = _pair_candidates(prepared[a], prepared[b], h, tol, lower, upper)
        local = np.full((len(i), n_cam), -1, dtype=np.int64)
        local[:, a], local[:, b] = i, j
        for k in range(n_cam):
            if k not in (a, b):
                local[:, k], _ = _nearest_rays(prepared[k], mid, z0, perm, tol)
        tuples.append(local)
    local = np.concatenate(tuples) if tuples else np.empty((0, n_cam), dtype=np.int64)
    local = local[np.sum(local >= 0, axis=1) >= min_cameras]
    if len(local) == 0:
        return _empty(n_cam)
    check = _TupleCheck(prepared, tol, lower, upper)
    local = np.unique(local, axis=0)
    good, d, points = check(local)
    used = local >= 0
    ambiguous = np.array(
        [
            int(np.sum(np.bincount(local[good & used[:, c], c], minlength=len(cam.index)) > 1))
            for c, cam in enumerate(prepared)
        ]
    )
    if not good.any():
        return _empty(n_cam, ambiguous)
    chosen, d, points = _accept(local, good, d, points, check, min_cameras)
    indices = np.full_like(chosen, -1)
    for c, cam in enumerate(prepared):
        has = chosen[:, c] >= 0
        indices[has, c] = cam.index[chosen[has, c]]
    log.debug(
        "matched %d tuples from %d candidates (%s ambiguous) of %s detections",
        len(chosen),
        int(good.sum()),
        ambiguous.tolist(),
        sizes,
    )
    return Matches(
        indices=indices,
        points=points,
        ray_distances=np.where(chosen >= 0, d, np.nan),
        ambiguous=ambiguous,
        candidates=int(good.sum()),
    )


@dataclass(frozen=True, eq=False)
class _TupleCheck:
    """Re-triangulates tuples of local ray indices with all their cameras and checks
    them: every ray within the tolerance of the point, the point inside the volume."""

    prepared: list
    tol: float
    lower: np.ndarray
    upper: np.ndarray

    def __call__(self, local: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(good (T,) bool, ray distances (T, C) m, points (T, 3) m) of tuples (T, C)."""
        n_cam = len(self.prepared)
        origins = np.full((n_cam, len(local), 3), np.nan)
        directions = np.full((n_cam, len(local), 3), np.nan)
        for c, cam in enumerate(self.prepared):
            has = local[:, c] >= 0
            origins[c, has] = cam.origins[local[has, c]]
            directions[c, has] = cam.directions[local[has, c]]
        tri = closest_points(origins, directions)
        d = tri.ray_distances.T  # (T, C)
        good = (
            np.all((local < 0) | (d < self.tol), axis=1)
            & np.isfinite(tri.points).all(axis=1)
            & np.all((tri.points >= self.lower) & (tri.points <= self.upper), axis=1)
        )
        return good, d, tri.points


def _accept(local, good, d, points, check: _TupleCheck, min_cameras: int):
    """Accept tuples greedily, most cameras first, then by increasing mean (d_c/tol)²,
    skipping any that reuses a detection; the tuples one camera short of each tuple
    turned down (or failing the check) join the next level, checked, as fallbacks.

    Parameters
    ----------
    local : ndarray of int, shape (T, C)
        Candidate tuples of local ray indices, −1 where a camera has none.
    good : ndarray of bool, shape (T,)
        Those that passed the check.
    d : ndarray, shape (T, C)
        Ray distances to their points, m.
    points : ndarray, shape (T, 3)
        Their points, m.
    check : _TupleCheck
        Checks the fallbacks.
    min_cameras : int
        Fewest cameras of a tuple.

    Returns
    -------
    (ndarray of int (N, C), ndarray (N, C), ndarray (N, 3))
        The accepted tuples in lexicographic order, their ray distances (m) and
        points (m).
    """
    n_cam = local.shape[1]
    taken = [np.zeros(len(cam.index), dtype=bool) for cam in check.prepared]
    n_used = np.sum(local >= 0, axis=1)
    fallback = (np.empty((0, n_cam), dtype=np.int64), np.empty(0, dtype=bool))
    fallback += (np.empty((0, n_cam)), np.empty((0, 3)))
    kept = []
    for k in range(n_cam, min_cameras - 1, -1):
        level = n_used == k
        rows, ok, dist, point = (
            np.concatenate([x[level], f])
            for x, f in zip((local, good, d, points), fallback, strict=True)
        )
        cost = np.nansum(np.where(rows >= 0, (dist / check.tol) ** 2, 0.0), axis=1) / k
        accept = np.zeros(len(rows), dtype=bool)
        for t in np.argsort(cost, kind="stable"):
            row = rows[t]
            if not ok[t] or any(row[c] >= 0 and taken[c][row[c]] for c in range(n_cam)):
                continue
            for c in range(n_cam):
                if row[c] >= 0:
                    taken[c][row[c]] = True
            accept[t] = True
        kept.append((rows[accept], dist[accept], point[accept]))
        if k > min_cameras:
            short = _free(_one_camera_short(rows[~accept]), taken)
            fallback = (short, *check(short))
    rows, dist, point = (np.concatenate(x) for x in zip(*kept, strict=True))
    order = np.lexsort(rows.T[::-1])
    return rows[order], dist[order], point[order]


def _one_camera_short(rows: np.ndarray) -> np.ndarray:
    """The distinct tuples (T', C) made by dropping one used camera from tuples (T, C)."""
    parts = []
    for c in range(rows.shape[1]):
        has = rows[:, c] >= 0
        part = rows[has].copy()
        part[:, c] = -1
        parts.append(part)
    return np.unique(np.concatenate(parts), axis=0)


def _free(rows: np.ndarray, taken: Sequence[np.ndarray]) -> np.ndarray:
    """The tuples (T, C) none of whose detections is ``taken`` (per camera, bool)."""
    free = np.ones(len(rows), dtype=bool)
    for c, used in enumerate(taken):
        has = rows[:, c] >= 0
        free[has] &= ~used[rows[has, c]]
    return rows[free]


def match(
    cameras: Sequence[CameraModel],
    pixels: Sequence[np.ndarray],
    volume,
    *,
    tolerance: float = DEFAULT_TOLERANCE,
    min_cameras: int = 2,
) -> Matches:
    """Match the detections of C ≥ 2 calibrated cameras.

    Parameters
    ----------
    cameras : sequence of C CameraModel
        Calibrations offering ``pixel_to_ray``.
    pixels : sequence of C ndarray, shape (N_c, 2)
        Detected particle image centres of each camera, px, in any order.
    volume : (lower, upper)
        Corners of the axis-aligned measurement box (e.g. the illuminated slab plus a
        margin of about the tolerance), each of shape (3,), m.
    tolerance : float
        Largest distance of a matched ray from the matched point, m (2–3× the
        calibration error).
    min_cameras : int
        Fewest cameras a match must use, from 2 (default) to C.

    Returns
    -------
    Matches
        ``indices`` refer to the rows of ``pixels``.

    Examples
    --------
    Two Tsai cameras 0.5 m away, turned ±20° about Y, see 30 particles in a 1 cm cube;
    the second lists its detections in another order. Every particle is matched with
    its own images, at its own position:

    >>> import numpy as np
    >>> import ptv
    >>> from scipy.spatial.transform import Rotation
    >>> def camera(angle):  # 0.5 m from the origin, turned ``angle`` degrees about Y
    ...     turn = Rotation.from_euler("y", angle, degrees=True).as_matrix()
    ...     return ptv.TsaiCalibration(turn, [0, 0, 0.5], focal_length=0.05, kappa1=0.0,
    ...                                sx=1.0, principal_point=(319.5, 239.5),
    ...                                pixel_size=(1e-5, 1e-5))
    >>> cameras = [camera(-20), camera(20)]
    >>> rng = np.random.default_rng(0)
    >>> points = rng.uniform(-5e-3, 5e-3, (30, 3))  # m
    >>> order = rng.permutation(30)
    >>> pixels = [cameras[0].project(points), cameras[1].project(points)[order]]
    >>> volume = ((-0.01, -0.01, -0.01), (0.01, 0.01, 0.01))  # m
    >>> matches = ptv.match(cameras, pixels, volume, tolerance=1e-5)
    >>> len(matches), bool(np.all(order[matches.indices[:, 1]] == matches.indices[:, 0]))
    (30, True)
    >>> bool(np.allclose(matches.points, points[matches.indices[:, 0]], rtol=0, atol=1e-12))
    True
    """
    if len(cameras) != len(pixels):
        raise ValueError(
            f"need one pixel array per camera, got {len(cameras)} cameras and "
            f"{len(pixels)} pixel arrays"
        )
    if len(cameras) < 2:
        raise ValueError(f"matching needs at least two cameras, got {len(cameras)}")
    rays = []
    for c, (cam, xy) in enumerate(zip(cameras, pixels, strict=True)):
        xy = np.asarray(xy, dtype=float)
        if xy.ndim != 2 or xy.shape[1] != 2:
            raise ValueError(f"camera {c}: pixels must have shape (N, 2), got {xy.shape}")
        if len(xy):
            rays.append(cam.pixel_to_ray(xy))
        else:  # no detections: no need to ask the calibration
            rays.append(Rays(np.empty((0, 3)), np.empty((0, 3))))
    return match_rays(rays, volume, tolerance=tolerance, min_cameras=min_cameras)
