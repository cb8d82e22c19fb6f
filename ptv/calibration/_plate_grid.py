"""Steps 4 to 6 of finding a plate's dots (:mod:`ptv.calibration.targets`): placing the
three marks (or the single mark and the axes), indexing the dots on the grid from them,
and the grid nodes missed."""

from __future__ import annotations

import itertools
import logging
from collections.abc import Callable

import numpy as np
from scipy.spatial import cKDTree

from ptv.calibration.plate import PlateDescription
from ptv.calibration.polynomial import fit_polynomial2d

log = logging.getLogger("ptv.calibration.targets")

#: Matching tolerance of the indexing, in local pitches.
_MATCH_TOL = 0.3
#: Matching tolerance when scoring a mark assignment, in pitches.
_SCORE_TOL = 0.25
#: Grid steps around the marks scored for a mark assignment.
_SCORE_REACH = 3
#: Fewest matched fraction of the predicted dots around the marks.
_MIN_SCORE = 0.5
#: Mark candidates tried (the largest relative areas), in triples.
_MAX_MARK_CANDIDATES = 6
#: Residual of the final cubic grid fit above which a dot is dropped, in pitches.
_OUTLIER_TOL = 0.25
#: Fewest indexed dots for the gross-outlier check against one smooth cubic grid.
_SMOOTH_GRID_DOTS = 20
#: Index support radius (Chebyshev, grid steps) of the local affine predictions.
_SUPPORT_RADIUS = 2
#: Image direction of each word a single mark's axes are given in (x right, y down).
AXIS_DIRECTIONS = {"right": (1.0, 0.0), "left": (-1.0, 0.0), "up": (0.0, -1.0), "down": (0.0, 1.0)}
#: Largest angle between a given axis direction and the grid direction taken for it,
#: deg: below 45°, so a grid turned by 45° on the image is refused, not guessed.
_AXIS_TOLERANCE_DEG = 40.0
#: Neighbours of the single mark searched for the two lattice directions.
_AXIS_NEIGHBOURS = 8


class MarkersNotFoundError(ValueError):
    """The three marked dots of the plate could not be found or placed."""


class SeedDotsError(ValueError):
    """Seed dots given by the user that no dot answers, or that contradict each other."""


#: A seed dot takes the dot nearest to its pixel within this fraction of a pitch.
_SEED_REACH = 0.4
#: Seed dots further than this (pitches) from the grid of all of them contradict.
_SEED_TOL = 0.3
#: Smallest ratio of the DLT's two least singular values for which four or more seeds
#: fix a homography (below it three of them lie on a line).
_HOMOGRAPHY_RANK_TOL = 1e-9


class NoDotAtSeedError(SeedDotsError):
    """A seed dot with no detected dot within reach of its pixel.

    Attributes
    ----------
    pixel : tuple of float
        The seed's pixel (x, y).
    reach : float
        The search radius, px.
    """

    def __init__(self, message: str, pixel: tuple[float, float], reach: float) -> None:
        super().__init__(message)
        self.pixel = pixel
        self.reach = reach


def _normalising(points: np.ndarray) -> np.ndarray:
    """(3, 3) similarity taking ``points`` (N, 2) to zero mean and mean norm √2."""
    centre = points.mean(axis=0)
    scale = np.sqrt(2.0) / max(np.linalg.norm(points - centre, axis=1).mean(), 1e-12)
    return np.array([[scale, 0, -scale * centre[0]], [0, scale, -scale * centre[1]], [0, 0, 1]])


def _homography(nodes: np.ndarray, pixels: np.ndarray) -> np.ndarray | None:
    """(3, 3) H with pixel ∝ H @ [i, j, 1], the least-squares DLT on normalised points
    (exact for four seeds); None when three of the seeds lie on a line."""
    t_nodes, t_pixels = _normalising(nodes), _normalising(pixels)
    a = np.column_stack([nodes, np.ones(len(nodes))]) @ t_nodes.T
    b = np.column_stack([pixels, np.ones(len(pixels))]) @ t_pixels.T
    zero = np.zeros_like(a)
    rows = np.concatenate(
        [
            np.hstack([a, zero, -b[:, :1] * a]),
            np.hstack([zero, a, -b[:, 1:2] * a]),
        ]
    )
    _, sigma, vt = np.linalg.svd(rows)
    if sigma[7] < _HOMOGRAPHY_RANK_TOL * sigma[0]:  # the solution is not one line
        return None
    return np.linalg.solve(t_pixels, vt[-1].reshape(3, 3) @ t_nodes)


def _seed_grid(
    nodes: np.ndarray, pixels: np.ndarray
) -> Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]:
    """The grid the seeds at ``nodes`` (N, 2) and ``pixels`` (N, 2) fix: a homography (a
    plate seen in perspective) from four or more, an affine grid from three or where a
    homography is not fixed. It takes grid nodes (M, 2) to their pixels (M, 2) and the
    smaller grid step at each (M,), px."""
    h = _homography(nodes, pixels) if len(nodes) >= 4 else None
    if h is None:
        design = np.column_stack([nodes, np.ones(len(nodes))])
        fit, *_ = np.linalg.lstsq(design, pixels, rcond=None)
        step = np.linalg.norm(fit[:2], axis=1).min()

        def affine(at: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            return np.column_stack([at, np.ones(len(at))]) @ fit, np.full(len(at), step)

        return affine

    def perspective(at: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        mapped = np.column_stack([at, np.ones(len(at))]) @ h.T
        w = mapped[:, 2:]
        on_grid = mapped[:, :2] / w
        # d(pixel)/d(i, j) = (H[:2, :2] − pixel ⊗ H[2, :2]) / w
        jacobian = (h[None, :2, :2] - on_grid[:, :, None] * h[None, 2:, :2]) / w[:, :, None]
        return on_grid, np.linalg.norm(jacobian, axis=1).min(axis=1)

    return perspective


def _around_seeds(
    pts: np.ndarray,
    tree: cKDTree,
    usable: np.ndarray,
    seed_rows: dict[tuple[int, int], int],
    description: PlateDescription,
) -> dict[tuple[int, int], int]:
    """The seeds and the dots next to them (Chebyshev distance 1) on the grid the seeds'
    dots fix, so that a grid grown from a few far-apart seeds starts from local patches
    rather than from one affine fit of a plate seen in perspective."""
    nodes = np.array(list(seed_rows), dtype=float)
    grid = _seed_grid(nodes, pts[list(seed_rows.values())])
    around = np.unique((nodes[:, None, :] + _NEIGHBOURS[None]).reshape(-1, 2), axis=0)
    around = around[description.in_extent(around.astype(int))]
    around = np.array([n for n in around.tolist() if tuple(int(v) for v in n) not in seed_rows])
    assigned = dict(seed_rows)
    if len(around) == 0:
        return assigned
    predicted, steps = grid(around.reshape(-1, 2))
    distance, rows = tree.query(predicted)
    used = set(assigned.values())
    for k in np.argsort(distance, kind="stable"):
        row = int(rows[k])
        if distance[k] < _MATCH_TOL * steps[k] and usable[row] and row not in used:
            assigned[tuple(int(v) for v in around[k])] = row
            used.add(row)
    return assigned


def _seed_rows(
    pts: np.ndarray,
    tree: cKDTree,
    seeds: dict[tuple[int, int], tuple[float, float]],
    pitch_px: float,
    source: str,
) -> dict[tuple[int, int], int]:
    """The detection each seed dot names: grid index → row in ``pts``.

    Raises
    ------
    SeedDotsError
        Fewer than three seeds or all on a line; two seeds on one dot; five or more
        seeds that no single grid seen in perspective holds (four fix one exactly: a
        wrong index among them shows after the grid is grown, :func:`index_grid`).
    NoDotAtSeedError
        A seed with no dot within ``_SEED_REACH`` of a pitch of its pixel.
    """
    nodes = np.array(list(seeds), dtype=float).reshape(-1, 2)
    pixels = np.array(list(seeds.values()), dtype=float).reshape(-1, 2)
    if len(nodes) < 3 or np.linalg.matrix_rank(np.column_stack([nodes, np.ones(len(nodes))])) < 3:
        raise SeedDotsError(
            f"seed dots for {source}: need at least three, not on one line, got "
            f"{[tuple(int(v) for v in n) for n in nodes]}"
        )
    on_grid, steps = _seed_grid(nodes, pixels)(nodes)
    step = steps.min()
    off = np.linalg.norm(on_grid - pixels, axis=1) / steps
    if off.max() > _SEED_TOL:
        given = ", ".join(
            f"{tuple(int(v) for v in n)} at ({x:.1f}, {y:.1f})"
            for n, (x, y) in zip(nodes, pixels, strict=True)
        )
        raise SeedDotsError(
            f"seed dots for {source} contradict each other: no grid holds {given} (one is "
            f"{off.max():.2f} pitches off; check the indices)"
        )
    distance, rows = tree.query(pixels)
    reach = _SEED_REACH * min(step, pitch_px)
    far = np.flatnonzero(distance > reach)
    if len(far):
        n = far[0]
        x, y = pixels[n]
        raise NoDotAtSeedError(
            f"seed dot {tuple(int(v) for v in nodes[n])} of {source}: no dot within "
            f"{reach:.1f} px of ({x:.1f}, {y:.1f}) (the search radius: {_SEED_REACH} × the "
            f"smaller of the seeds' grid step, {step:.1f} px, and the pitch the dots' size "
            f"gives with target.dot_diameter, {pitch_px:.1f} px)",
            (float(x), float(y)),
            float(reach),
        )
    if len(set(rows.tolist())) < len(rows):
        raise SeedDotsError(f"seed dots for {source}: two seeds name the same dot")
    return {tuple(int(v) for v in n): int(r) for n, r in zip(nodes, rows, strict=True)}


# -- marks ---------------------------------------------------------------------------------
def _affine_from(grid: np.ndarray, pixels: np.ndarray) -> np.ndarray | None:
    """Exact affine (3, 2) with [i, j, 1] @ M = pixel from three correspondences."""
    a = np.column_stack([grid, np.ones(len(grid))])
    if abs(np.linalg.det(a)) < 1e-9:
        return None
    return np.linalg.solve(a, pixels)


def _locate_marks(
    pts: np.ndarray,
    tree: cKDTree,
    candidates: np.ndarray,
    description: PlateDescription,
    pitch_px: float,
    image_size: tuple[int, int],
    source: str,
) -> dict[str, int]:
    """Assign the mark names to three candidate detections (indices into ``pts``)."""
    names = list(description.marks)
    grid = np.array([description.marks[k] for k in names], dtype=float)
    lo = grid.min(axis=0) - _SCORE_REACH
    hi = grid.max(axis=0) + _SCORE_REACH
    ii, jj = np.meshgrid(np.arange(lo[0], hi[0] + 1), np.arange(lo[1], hi[1] + 1))
    nodes = np.column_stack([ii.ravel(), jj.ravel()])
    nodes = nodes[~(nodes[:, None, :] == grid[None]).all(axis=2).any(axis=1)]
    design = np.column_stack([nodes, np.ones(len(nodes))])
    w, h = image_size
    best: tuple[float, dict[str, int]] | None = None
    for triple in itertools.combinations(candidates, 3):
        for perm in itertools.permutations(triple):
            m = _affine_from(grid, pts[list(perm)])
            if m is None:
                continue
            steps = np.linalg.norm(m[:2], axis=1)
            if not (0.4 * pitch_px < steps.min() and steps.max() < 2.5 * pitch_px):
                continue
            pred = design @ m
            inside = (pred[:, 0] >= 0) & (pred[:, 0] <= w - 1) & (pred[:, 1] >= 0)
            inside &= pred[:, 1] <= h - 1
            if inside.sum() < 5:
                continue
            dist, hit = tree.query(pred[inside])
            ok = dist < _SCORE_TOL * steps.min()
            score = len(np.unique(hit[ok])) / inside.sum()
            if best is None or score > best[0]:
                best = (score, dict(zip(names, (int(p) for p in perm), strict=True)))
    if best is None or best[0] < _MIN_SCORE:
        got = "no placement" if best is None else f"at best {best[0]:.0%} of the nearby dots"
        raise MarkersNotFoundError(
            f"markers not found in {source}: {len(candidates)} mark-sized blob(s), but no "
            f"assignment of the marks {description.marks} to them predicts the dot grid "
            f"around them ({got} matched, need {_MIN_SCORE:.0%})"
        )
    log.debug("%s: marks placed, %.0f%% of nearby dots predicted", source, 100 * best[0])
    return best[1]


def _single_mark(
    usable: np.ndarray, relative_area: np.ndarray, description: PlateDescription, source: str
) -> dict[str, int]:
    """The row of a plate's single mark: the one usable blob clearly larger than its
    neighbours (more than √((D_mark/D_dot)²) times their median area)."""
    ratio = description.mark_area_ratio
    mark_like = np.flatnonzero(usable & (relative_area > np.sqrt(ratio)))
    if len(mark_like) != 1:
        raise MarkersNotFoundError(
            f"markers not found in {source}: {len(mark_like)} blob(s) are more than "
            f"{np.sqrt(ratio):.2f}× the area of their neighbours, need the one mark "
            f"(area ratio {ratio:.2f} expected)"
        )
    name = next(iter(description.marks))
    return {name: int(mark_like[0])}


def _axes_start(
    pts: np.ndarray,
    tree: cKDTree,
    usable: np.ndarray,
    mark: int,
    description: PlateDescription,
    source: str,
) -> dict[tuple[int, int], int]:
    """The single mark and one neighbour along each axis, grid index → row in ``pts``.

    The two lattice directions at the mark are its nearest usable neighbour and the
    nearest one at more than 60° from it; +i (+j) is the one of ±either closest to the
    image direction ``description.axes`` names, which must lie within
    :data:`_AXIS_TOLERANCE_DEG`. The neighbour taken is the dot one step along it, or
    one step back where the mark sits on the plate's edge.
    """
    centre = pts[mark]
    k = min(_AXIS_NEIGHBOURS + 1, int(usable.sum()))
    _, rows = tree.query(centre, k=k)
    steps = pts[rows[1:]] - centre
    steps = steps[np.argsort(np.linalg.norm(steps, axis=1), kind="stable")]
    unit = steps / np.linalg.norm(steps, axis=1)[:, None]
    across = np.flatnonzero(np.abs(unit @ unit[0]) < 0.5)
    if len(across) == 0:
        raise MarkersNotFoundError(
            f"markers not found in {source}: the dots around the mark do not form a grid"
        )
    lattice = np.array([steps[0], -steps[0], steps[across[0]], -steps[across[0]]])
    cosine = np.cos(np.radians(_AXIS_TOLERANCE_DEG))
    node = np.array(next(iter(description.marks.values())))
    start = {tuple(int(v) for v in node): mark}
    for axis, word, unit_step in zip("ij", description.axes, ((1, 0), (0, 1)), strict=True):
        direction = np.array(AXIS_DIRECTIONS[word])
        along = lattice @ direction / np.linalg.norm(lattice, axis=1)
        best = int(np.argmax(along))
        if along[best] < cosine:
            angle = np.degrees(np.arccos(np.clip(along[best], -1.0, 1.0)))
            raise MarkersNotFoundError(
                f"markers not found in {source}: no grid direction at the mark points "
                f"{word} (the nearest is {angle:.0f}° off, more than "
                f"{_AXIS_TOLERANCE_DEG:.0f}°): check the target's axes"
            )
        step = lattice[best]
        for sign in (1, -1):
            dist, row = tree.query(centre + sign * step)
            if dist < _MATCH_TOL * np.linalg.norm(step):
                start[tuple(int(v) for v in node + sign * np.array(unit_step))] = int(row)
                break
        else:
            raise MarkersNotFoundError(
                f"markers not found in {source}: no dot next to the mark along axis {axis}"
            )
    return start


# -- indexing ------------------------------------------------------------------------------
def _local_affine(nodes: np.ndarray, pix: np.ndarray, target: np.ndarray) -> np.ndarray | None:
    """Affine (3, 2) index → pixel fitted to indexed nodes near ``target`` (2,)."""
    d = np.abs(nodes - target).max(axis=1)
    sel = d <= _SUPPORT_RADIUS
    if sel.sum() < 4 or np.linalg.matrix_rank(nodes[sel] - nodes[sel].mean(axis=0)) < 2:
        order = np.argsort(np.hypot(*(nodes - target).T), kind="stable")
        sel = order[: max(6, int(sel.sum()))]
        if np.linalg.matrix_rank(nodes[sel] - nodes[sel].mean(axis=0)) < 2:
            sel = order
            if len(sel) < 3 or np.linalg.matrix_rank(nodes - nodes.mean(axis=0)) < 2:
                return None
    a = np.column_stack([nodes[sel], np.ones(len(nodes[sel]))])
    return np.linalg.lstsq(a, pix[sel], rcond=None)[0]


_NEIGHBOURS = np.array([(di, dj) for di in (-1, 0, 1) for dj in (-1, 0, 1) if (di, dj) != (0, 0)])


def _grow(
    pts: np.ndarray,
    tree: cKDTree,
    usable: np.ndarray,
    seeds: dict[tuple[int, int], int],
    description: PlateDescription,
) -> dict[tuple[int, int], int]:
    """Index detections by growing the grid outward from the marks."""
    assigned = dict(seeds)
    used = set(seeds.values())
    while True:
        nodes = np.array(list(assigned), dtype=float)
        pix = pts[list(assigned.values())]
        frontier = {
            (int(a + di), int(b + dj))
            for a, b in assigned
            for di, dj in _NEIGHBOURS
            if (int(a + di), int(b + dj)) not in assigned
        }
        frontier_arr = np.array(sorted(frontier), dtype=float).reshape(-1, 2)
        frontier_arr = frontier_arr[description.in_extent(frontier_arr.astype(int))]
        candidates = []
        for node in frontier_arr:
            m = _local_affine(nodes, pix, node)
            if m is None:
                continue
            pred = np.append(node, 1.0) @ m
            tol = _MATCH_TOL * np.linalg.norm(m[:2], axis=1).min()
            for dist, k in zip(*tree.query(pred, k=3, distance_upper_bound=tol), strict=True):
                if np.isfinite(dist) and usable[k] and k not in used:
                    candidates.append((dist, (int(node[0]), int(node[1])), int(k)))
                    break
        added = 0
        for _, node, k in sorted(candidates):
            if node in assigned or k in used:
                continue
            assigned[node] = k
            used.add(k)
            added += 1
        if added == 0:
            return assigned


def _predict(nodes: np.ndarray, pix: np.ndarray, targets: np.ndarray) -> np.ndarray:
    out = np.full((len(targets), 2), np.nan)
    for t, node in enumerate(targets):
        m = _local_affine(nodes, pix, node)
        if m is not None:
            out[t] = np.append(node, 1.0) @ m
    return out


def _marks(
    pts: np.ndarray,
    tree: cKDTree,
    usable: np.ndarray,
    relative_area: np.ndarray,
    description: PlateDescription,
    pitch_px: float,
    image_size: tuple[int, int],
    source: str,
) -> dict[str, int]:
    """The row in ``pts`` of each mark, among the usable blobs larger than their
    neighbours (by ``relative_area``, largest first)."""
    if not description.marks:
        raise MarkersNotFoundError(
            f"markers not found in {source}: the plate has no marks; give seed dots "
            "(docs/experiment.md §3)"
        )
    ratio = description.mark_area_ratio
    mark_like = np.flatnonzero(usable & (relative_area > np.sqrt(ratio)))
    if len(mark_like) < 3:
        raise MarkersNotFoundError(
            f"markers not found in {source}: {len(mark_like)} blob(s) are more than "
            f"{np.sqrt(ratio):.2f}× the area of their neighbours, need the 3 marks "
            f"(area ratio {ratio:.2f} expected)"
        )
    mark_like = mark_like[np.argsort(-relative_area[mark_like], kind="stable")]
    mark_like = mark_like[:_MAX_MARK_CANDIDATES]
    return _locate_marks(pts, tree, mark_like, description, pitch_px, image_size, source)


def index_grid(
    pts: np.ndarray,
    usable: np.ndarray,
    relative_area: np.ndarray,
    description: PlateDescription,
    dot_area: float,
    image_size: tuple[int, int],
    source: str,
    seeds: dict[tuple[int, int], tuple[float, float]] | None = None,
) -> tuple[np.ndarray, np.ndarray, dict[str, int], np.ndarray]:
    """Place the marks among the ``usable`` blobs larger than their neighbours (by
    ``relative_area``, largest first), the single mark and its axes, or take the dots
    the ``seeds`` name (grid index → pixel, given by the user), grow the grid from them
    over the usable blobs and drop the gross outliers of a cubic grid fit.
    ``dot_area`` is a dot's area, px.

    Returns
    -------
    nodes : ndarray, shape (N, 2), int64
        Grid index (i, j) of each indexed blob.
    det : ndarray, shape (N,), int64
        Its row in ``pts``.
    mark_rows : dict of str to int
        Row in ``pts`` of each mark (none with seeds).
    outliers : ndarray of int64
        Rows in ``pts`` dropped as off the smooth grid.
    """
    tree = cKDTree(np.where(usable[:, None], pts, -1e9))  # usable blobs only (others far)
    pitch_px = 2.0 * np.sqrt(dot_area / np.pi) * description.pitch / description.dot_diameter
    if seeds:
        seed_rows, mark_rows = _seed_rows(pts, tree, seeds, pitch_px, source), {}
        start = _around_seeds(pts, tree, usable, seed_rows, description)
    elif len(description.marks) == 1:
        mark_rows = _single_mark(usable, relative_area, description, source)
        start = _axes_start(pts, tree, usable, *mark_rows.values(), description, source)
    else:
        mark_rows = _marks(
            pts, tree, usable, relative_area, description, pitch_px, image_size, source
        )
        start = {description.marks[name]: k for name, k in mark_rows.items()}
    assigned = _grow(pts, tree, usable, start, description)
    nodes = np.array(list(assigned), dtype=np.int64)
    det = np.array(list(assigned.values()), dtype=np.int64)
    outliers = np.empty(0, dtype=np.int64)
    if seeds and len(det) < min(_SMOOTH_GRID_DOTS, int(usable.sum())):
        raise SeedDotsError(
            f"seed dots for {source} contradict each other: the grid grown from them stops "
            f"at {len(det)} of the {int(usable.sum())} dots found (check the indices)"
        )
    # Gross-outlier check against one smooth cubic of the whole grid.
    if len(det) >= _SMOOTH_GRID_DOTS:
        poly = fit_polynomial2d(nodes.astype(float), pts[det], degree=3)
        resid = np.linalg.norm(poly(nodes.astype(float)) - pts[det], axis=1)
        step = np.linalg.norm(poly.jacobian(nodes.astype(float)), axis=1).min(axis=1)
        bad = resid > _OUTLIER_TOL * step
        if seeds:
            _check_seeds_on_grid(det, bad, seed_rows, source)
        is_mark = np.isin(det, list(mark_rows.values()))
        if np.any(bad & is_mark):
            raise MarkersNotFoundError(
                f"markers not found in {source}: a mark lies off the grid fitted to the dots"
            )
        if bad.any():
            log.warning("%s: %d dot(s) off the smooth grid dropped", source, int(bad.sum()))
            outliers = det[bad]
            nodes, det = nodes[~bad], det[~bad]
    return nodes, det, mark_rows, outliers


def _check_seeds_on_grid(
    det: np.ndarray,
    off_grid: np.ndarray,
    seed_rows: dict[tuple[int, int], int],
    source: str,
) -> None:
    """Refuse seeds whose dot the grid grown from them puts off its smooth fit: four
    seeds fix a perspective grid exactly, so a wrong index among them shows only here.

    Raises
    ------
    SeedDotsError
        Naming the seeds off the grid.
    """
    bad_rows = set(det[off_grid].tolist())
    wrong = [ij for ij, row in seed_rows.items() if row in bad_rows]
    if wrong:
        raise SeedDotsError(
            f"seed dots for {source} contradict each other: no smooth grid grown from them "
            f"holds {', '.join(str(ij) for ij in wrong)} (check the indices)"
        )


def missing_nodes(
    nodes: np.ndarray,
    pix: np.ndarray,
    description: PlateDescription,
    dot_area: float,
    margin: int,
    image_size: tuple[int, int],
) -> np.ndarray:
    """Grid nodes that should be on the image, whole, but were not found."""
    found = {tuple(n) for n in nodes.tolist()}
    if description.extent is None:
        lo, hi = nodes.min(axis=0), nodes.max(axis=0)
    else:
        lo = np.maximum(nodes.min(axis=0) - 2, [description.extent[0][0], description.extent[1][0]])
        hi = np.minimum(nodes.max(axis=0) + 2, [description.extent[0][1], description.extent[1][1]])
    ii, jj = np.meshgrid(np.arange(lo[0], hi[0] + 1), np.arange(lo[1], hi[1] + 1))
    cand = np.column_stack([ii.ravel(), jj.ravel()])
    cand = np.array([c for c in cand.tolist() if tuple(c) not in found], dtype=np.int64).reshape(
        -1, 2
    )
    if len(cand) == 0:
        return cand
    cheb = np.abs(cand[:, None, :] - nodes[None]).max(axis=2).min(axis=1)
    cand = cand[cheb <= 2]
    pred = _predict(nodes.astype(float), pix, cand.astype(float))
    reach = np.sqrt(dot_area / np.pi) + margin + 1
    w, h = image_size
    inside = np.isfinite(pred).all(axis=1)
    inside &= (pred[:, 0] >= reach) & (pred[:, 0] <= w - 1 - reach)
    inside &= (pred[:, 1] >= reach) & (pred[:, 1] <= h - 1 - reach)
    return cand[inside]
