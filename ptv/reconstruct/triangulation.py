"""Candidate particles from the peaks of several cameras (the triangulation of IPR).

For a subset S of the cameras (all of them, or one fewer in the later iterations):

1. A reference camera r and a search camera s are chosen from S: r is the camera whose
   longest epipolar segment into the others is shortest, s the camera where r's
   epipolar segment is longest (so that along it the other cameras' segments are
   shorter, and an error along s's line moves their predicted pixel less).
2. Each peak of r gives a ray (``pixel_to_ray``), clipped to the measurement volume.
   K points spread evenly along it are projected into every other camera of S (one
   ``project`` call per camera for all peaks): the epipolar polyline.
3. Peaks of s within ``tolerance`` px of r's polyline (a grid search) give a depth on
   the ray; the polylines of the other cameras at that depth give predicted pixels,
   and the nearest peak within ``tolerance`` · (1 + ℓ_v/ℓ_s) (ℓ: epipolar segment
   lengths, the error along s's line carried over) is taken in each. A candidate
   needs a peak in every camera of S.
4. Its peaks' rays are intersected by least squares (as :func:`ptv.triangulate.closest_points`),
   the point is projected into every camera, and it is kept when it lies in the volume
   and every camera of S sees it within ``tolerance`` px of its peak.

All candidates are kept, ghosts included (Wieneke 2013): the shaking and the intensity
threshold of :mod:`ptv.reconstruct.ipr` remove the ghosts, which borrow their light.
"""

import logging
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numba import njit

from ptv.box import Box
from ptv.reconstruct._grid import PointGrid, nearest, segment_pairs
from ptv.reconstruct.mapping import Mappings

logger = logging.getLogger(__name__)


@dataclass(frozen=True, eq=False)
class Candidates:
    """Candidate particles triangulated from peaks.

    Attributes
    ----------
    points : ndarray, shape (M, 3)
        Least-squares points of the matched peaks' rays, m.
    peaks : ndarray of int64, shape (M, C)
        Index of the matched peak in each camera's peak list, −1 for a camera not used.
    xy : ndarray, shape (C, M, 2)
        The points projected into every camera, px (NaN where not imaged).
    error : ndarray, shape (M,)
        Largest distance between the projection and the matched peak over the cameras
        used, px.
    rms : ndarray, shape (M,)
        RMS of those distances over the cameras used, px.
    """

    points: np.ndarray
    peaks: np.ndarray
    xy: np.ndarray
    error: np.ndarray
    rms: np.ndarray

    def __len__(self) -> int:
        return len(self.points)


def empty_candidates(n_cameras: int) -> Candidates:
    """No candidates."""
    return Candidates(
        points=np.empty((0, 3)),
        peaks=np.empty((0, n_cameras), dtype=np.int64),
        xy=np.empty((n_cameras, 0, 2)),
        error=np.empty(0),
        rms=np.empty(0),
    )


def ray_box_range(
    origins: np.ndarray, directions: np.ndarray, box: Box
) -> tuple[np.ndarray, np.ndarray]:
    """Parameters t₀ ≤ t₁ where rays O + t·V cross an axis-aligned box (slab method).

    Parameters
    ----------
    origins, directions : ndarray, shape (N, 3)
        Rays, m and unit vectors.
    box : Box
        (lower, upper) corners, m.

    Returns
    -------
    t0, t1 : ndarray, shape (N,)
        Entry and exit, m along the ray (negative where the origin lies beyond the
        entry: rays of a calibration are lines, their origins anywhere on them); NaN
        for lines that miss the box (or NaN rays).
    """
    lower, upper = (np.asarray(v, dtype=np.float64) for v in box)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        inv = 1.0 / directions
        ta = (lower - origins) * inv
        tb = (upper - origins) * inv
    lo = np.where(np.isnan(ta), -np.inf, np.minimum(ta, tb))
    hi = np.where(np.isnan(tb), np.inf, np.maximum(ta, tb))
    # a direction component of 0 with the origin inside that slab: no constraint
    inside = (origins >= lower) & (origins <= upper)
    parallel = directions == 0
    lo = np.where(parallel, np.where(inside, -np.inf, np.inf), lo)
    hi = np.where(parallel, np.where(inside, np.inf, -np.inf), hi)
    # a ray is a whole line: a calibration's origins may lie inside the volume
    t0 = np.max(lo, axis=1)
    t1 = np.min(hi, axis=1)
    ok = (t1 > t0) & np.isfinite(origins).all(axis=1) & np.isfinite(directions).all(axis=1)
    return np.where(ok, t0, np.nan), np.where(ok, t1, np.nan)


def epipolar_lengths(mappings: Mappings, box: Box) -> np.ndarray:
    """Length of camera a's epipolar segment (through the volume) in camera b, px.

    The ray of camera a through the image of the volume's centre, clipped to the
    volume, projected into b at 33 points.

    Returns
    -------
    ndarray, shape (C, C)
        Lengths; 0 on the diagonal, NaN where the segment is not imaged.
    """
    n = len(mappings)
    centre = 0.5 * (np.asarray(box[0]) + np.asarray(box[1]))
    out = np.zeros((n, n))
    for a in range(n):
        xy = mappings.project(a, centre[None])
        origin, direction = mappings.rays(a, xy)
        t0, t1 = ray_box_range(origin, direction, box)
        if not np.isfinite(t0[0]):
            out[a, :] = np.nan
            continue
        t = np.linspace(t0[0], t1[0], 33)
        pts = origin[0] + t[:, None] * direction[0]
        for b in range(n):
            if b != a:
                seg = mappings.project(b, pts)
                out[a, b] = np.nansum(np.linalg.norm(np.diff(seg, axis=0), axis=1))
    return out


def choose_pair(lengths: np.ndarray, subset: Sequence[int]) -> tuple[int, int]:
    """Reference and search cameras of a subset (module docstring, step 1)."""
    best = None
    for r in subset:
        others = [b for b in subset if b != r]
        longest = max(others, key=lambda b: lengths[r, b])
        key = lengths[r, longest]
        if best is None or key < best[0]:
            best = (key, r, longest)
    assert best is not None
    return best[1], best[2]


def triangulate_candidates(
    mappings: Mappings,
    peaks: Sequence[np.ndarray],
    grids: Sequence[PointGrid],
    rays: Sequence[tuple[np.ndarray, np.ndarray]],
    box: Box,
    *,
    subset: Sequence[int],
    tolerance: float,
    lengths: np.ndarray,
    samples: int = 9,
    chunk: int = 20000,
) -> Candidates:
    """Candidate particles seen by every camera of ``subset`` (module docstring).

    Parameters
    ----------
    mappings : Mappings
        The C cameras.
    peaks : sequence of C ndarray, shape (P_c, 2)
        Peaks of each camera's residual image, px.
    grids : sequence of C PointGrid
        The same peaks bucketed (:func:`ptv.reconstruct._grid.point_grid`).
    rays : sequence of C (origins, directions)
        Each peak's ray, (P_c, 3) m and unit vectors.
    box : Box
        The measurement volume, m.
    subset : sequence of int
        Cameras that must all see a candidate, at least 2 (3 or more against ghosts).
    tolerance : float
        Largest distance between a candidate's projection and its peak, px, > 0.
    lengths : ndarray, shape (C, C)
        Epipolar segment lengths (:func:`epipolar_lengths`), px.
    samples : int
        Points K along each reference ray, >= 2.
    chunk : int
        Reference peaks handled at once (bounds the memory).

    Returns
    -------
    Candidates
    """
    n_cams = len(mappings)
    subset = list(subset)
    ref, search = choose_pair(lengths, subset)
    verify = [c for c in subset if c not in (ref, search)]
    radius = {
        v: tolerance * (1.0 + lengths[ref, v] / max(lengths[ref, search], 1e-9)) for v in verify
    }
    found: list[tuple[np.ndarray, ...]] = []
    origins, directions = rays[ref]
    t0_all, t1_all = ray_box_range(origins, directions, box)
    usable = np.flatnonzero(np.isfinite(t0_all))
    frac = np.linspace(0.0, 1.0, samples)
    n_pairs = 0
    for lo in range(0, len(usable), chunk):
        idx = usable[lo : lo + chunk]
        t = t0_all[idx, None] + frac[None, :] * (t1_all[idx] - t0_all[idx])[:, None]
        pts = origins[idx, None, :] + t[:, :, None] * directions[idx, None, :]
        flat = pts.reshape(-1, 3)
        lines = {
            c: mappings.project(c, flat).reshape(len(idx), samples, 2) for c in subset if c != ref
        }
        g = grids[search]
        li, pi, ki, uu, _ = segment_pairs(
            lines[search], float(tolerance), g.xy, g.order, g.start, g.ncx, g.ncy, g.cell
        )
        n_pairs += len(li)
        keep = np.ones(len(li), dtype=bool)
        matched = {}
        for v in verify:
            a = lines[v][li, ki]
            b = lines[v][li, ki + 1]
            pred = a + uu[:, None] * (b - a)
            gv = grids[v]
            hit, _ = nearest(
                pred,
                np.full(len(pred), radius[v]),
                gv.xy,
                gv.order,
                gv.start,
                gv.ncx,
                gv.ncy,
                gv.cell,
            )
            matched[v] = hit
            keep &= hit >= 0
        ids = np.full((int(keep.sum()), n_cams), -1, dtype=np.int64)
        ids[:, ref] = idx[li[keep]]
        ids[:, search] = pi[keep]
        for v in verify:
            ids[:, v] = matched[v][keep]
        found.append(ids)
    if not found or sum(len(f) for f in found) == 0:
        logger.debug("cameras %s: %d epipolar pairs, no candidate", subset, n_pairs)
        return empty_candidates(n_cams)
    ids = np.concatenate(found)
    # a peak of s near a joint of the polyline may be found on both segments
    key = ids[:, ref] * (len(peaks[search]) + 1) + ids[:, search]
    _, first = np.unique(key, return_index=True)
    ids = ids[np.sort(first)]
    cands = _check(mappings, peaks, rays, ids, subset, box, tolerance)
    logger.debug(
        "cameras %s (reference %d, search %d): %d epipolar pairs, %d matched, %d candidates",
        subset,
        ref,
        search,
        n_pairs,
        len(ids),
        len(cands),
    )
    return cands


def _check(
    mappings: Mappings,
    peaks: Sequence[np.ndarray],
    rays: Sequence[tuple[np.ndarray, np.ndarray]],
    ids: np.ndarray,
    subset: Sequence[int],
    box: Box,
    tolerance: float,
) -> Candidates:
    """Least-squares points of matched peaks, kept where they reproject within tolerance."""
    n_cams = len(mappings)
    m = len(ids)
    origins = np.full((n_cams, m, 3), np.nan)
    directions = np.full((n_cams, m, 3), np.nan)
    for c in subset:
        origins[c] = rays[c][0][ids[:, c]]
        directions[c] = rays[c][1][ids[:, c]]
    points = _intersect(origins, directions)
    lower, upper = (np.asarray(v) for v in box)
    with np.errstate(invalid="ignore"):
        ok = np.all((points >= lower) & (points <= upper), axis=1)
    xy = np.full((n_cams, m, 2), np.nan)
    error = np.zeros(m)
    sq = np.zeros(m)
    for c in range(n_cams):
        xy[c, ok] = mappings.project(c, points[ok])
        if c in subset:
            d = np.linalg.norm(xy[c] - peaks[c][ids[:, c]], axis=1)
            d = np.where(np.isfinite(d), d, np.inf)
            error = np.maximum(error, d)
            sq += d * d
    ok &= error <= tolerance
    rms = np.sqrt(sq / len(subset))
    return Candidates(points=points[ok], peaks=ids[ok], xy=xy[:, ok], error=error[ok], rms=rms[ok])


@njit(cache=True)
def _greedy(order, ids, offsets, max_uses):  # pragma: no cover (compiled)
    uses = np.zeros(offsets[-1], dtype=np.int64)
    keep = np.zeros(len(order), dtype=np.bool_)
    for q in order:
        ok = True
        for c in range(ids.shape[1]):
            k = ids[q, c]
            if k >= 0 and uses[offsets[c] + k] >= max_uses:
                ok = False
                break
        if not ok:
            continue
        keep[q] = True
        for c in range(ids.shape[1]):
            k = ids[q, c]
            if k >= 0:
                uses[offsets[c] + k] += 1
    return keep


def select_candidates(
    candidates: Candidates,
    n_peaks: Sequence[int],
    *,
    max_uses: int,
    score: np.ndarray | None = None,
) -> np.ndarray:
    """Greedy choice of candidates that use each peak at most ``max_uses`` times.

    Candidates seen by more cameras come first, then by decreasing ``score`` (default:
    increasing rms reprojection error); each is kept when none of its peaks is already
    used ``max_uses`` times. A true particle has a small error and its light in every
    camera, a ghost (made of other particles' peaks) an error spread over the whole
    tolerance and light off its image in some camera, so with few uses per peak most
    ghosts lose their peaks to the true particles. A true particle that loses a peak shared with a
    neighbour (one peak for two images) is found in a later iteration, once the
    neighbour is subtracted from the residual.

    Returns
    -------
    ndarray of bool, shape (M,)
        The candidates kept.
    """
    if len(candidates) == 0:
        return np.zeros(0, dtype=bool)
    used = (candidates.peaks >= 0).sum(axis=1)
    key = candidates.rms if score is None else -np.asarray(score, dtype=np.float64)
    order = np.lexsort((key, -used)).astype(np.int64)
    offsets = np.concatenate([[0], np.cumsum(n_peaks)]).astype(np.int64)
    return _greedy(order, np.ascontiguousarray(candidates.peaks), offsets, int(max_uses))


@njit(cache=True, nogil=True)
def _intersect(origins, directions):  # pragma: no cover (compiled)
    """Least-squares point of C rays (C, M, 3) per column m (NaN rays skipped): the
    solution of Σ_c (I − v vᵀ) P = Σ_c (I − v vᵀ) o (as :func:`ptv.triangulate.closest_points`);
    NaN with fewer than two rays or parallel rays."""
    n_cams, m = origins.shape[0], origins.shape[1]
    out = np.full((m, 3), np.nan)
    a = np.empty((3, 3))
    b = np.empty(3)
    for k in range(m):
        a[:] = 0.0
        b[:] = 0.0
        rays = 0
        for c in range(n_cams):
            vx, vy, vz = directions[c, k, 0], directions[c, k, 1], directions[c, k, 2]
            ox, oy, oz = origins[c, k, 0], origins[c, k, 1], origins[c, k, 2]
            if not (
                np.isfinite(vx)
                and np.isfinite(vy)
                and np.isfinite(vz)
                and np.isfinite(ox)
                and np.isfinite(oy)
                and np.isfinite(oz)
            ):
                continue
            rays += 1
            v = (vx, vy, vz)
            o = (ox, oy, oz)
            for i in range(3):
                for j in range(3):
                    aij = (1.0 if i == j else 0.0) - v[i] * v[j]
                    a[i, j] += aij
                    b[i] += aij * o[j]
        if rays < 2:
            continue
        det = (
            a[0, 0] * (a[1, 1] * a[2, 2] - a[1, 2] * a[2, 1])
            - a[0, 1] * (a[1, 0] * a[2, 2] - a[1, 2] * a[2, 0])
            + a[0, 2] * (a[1, 0] * a[2, 1] - a[1, 1] * a[2, 0])
        )
        scale = a[0, 0] + a[1, 1] + a[2, 2]
        if not abs(det) > 1e-12 * scale * scale * scale:
            continue
        for i in range(3):
            num = 0.0
            # Cramer's rule: replace column i by b
            m00 = b[0] if i == 0 else a[0, 0]
            m01 = b[0] if i == 1 else a[0, 1]
            m02 = b[0] if i == 2 else a[0, 2]
            m10 = b[1] if i == 0 else a[1, 0]
            m11 = b[1] if i == 1 else a[1, 1]
            m12 = b[1] if i == 2 else a[1, 2]
            m20 = b[2] if i == 0 else a[2, 0]
            m21 = b[2] if i == 1 else a[2, 1]
            m22 = b[2] if i == 2 else a[2, 2]
            num = (
                m00 * (m11 * m22 - m12 * m21)
                - m01 * (m10 * m22 - m12 * m20)
                + m02 * (m10 * m21 - m11 * m20)
            )
            out[k, i] = num / det
    return out
