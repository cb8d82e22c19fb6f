"""The reference particles of the frames a positions file covers, and its positions
paired with them one-to-one (:mod:`validation.truth.matching`, as ``synptv run`` scores
its own matching).

The frames scored: for each Δt index in the file, snapshots 0 … the largest snapshot
index the file has at that Δt, in each frame (a, b) it has at that Δt; a frame in that
range without a row is scored too (its particles all missed). The reference particles
of a frame are those imaged by at least ``min_cameras`` cameras; a position pairs with
a true particle (any, imaged or not) within one voxel, each counting once. The
positions are first brought into the world frame by the rigid transform that best fits
them to their nearest particles (:func:`validation.truth.matching.align_to_truth`).
"""

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from ptv.box import Box, inside_box
from validation.score.positions import Positions
from validation.truth.matching import align_to_truth, match_frame, reference_particles
from validation.truth.truth_file import TruthFile

#: Snapshots of truth read at a time.
TRUTH_CHUNK = 10


@dataclass(frozen=True, eq=False)
class ScoredFrame:
    """One frame's positions against its truth.

    Attributes
    ----------
    k, m, frame : int
        Δt index, snapshot, frame (0: a, 1: b).
    rows : ndarray of int, shape (N,)
        The frame's rows of the positions file, in file order.
    partner : ndarray of int, shape (N,)
        The particle paired with each position, −1 for a ghost.
    error : ndarray, shape (N, 3)
        Aligned position − its particle, m (NaN for a ghost).
    point_in : ndarray of bool, shape (N,)
        Aligned position inside the analysis volume.
    counts : ndarray of int, shape (6,)
        :meth:`validation.truth.matching.FrameMatch.counts` in the analysis volume.
    found, reference, particle_in : ndarray of bool, shape (P,)
        Per true particle: paired with a position; imaged by enough cameras; inside
        the analysis volume.
    """

    k: int
    m: int
    frame: int
    rows: np.ndarray
    partner: np.ndarray
    error: np.ndarray
    point_in: np.ndarray
    counts: np.ndarray
    found: np.ndarray
    reference: np.ndarray
    particle_in: np.ndarray

    @property
    def tp_in(self) -> np.ndarray:
        """(N,) bool: positions paired with a reference particle of the analysis volume
        (the true positives of the yield)."""
        paired = self.partner >= 0
        scored = self.reference & self.particle_in
        out = np.zeros(len(self.partner), dtype=bool)
        out[paired] = scored[self.partner[paired]]
        return out


@dataclass(frozen=True, eq=False)
class Scored:
    """Every frame scored, and the transform that aligned the positions.

    Attributes
    ----------
    frames : list of ScoredFrame
        In order of (Δt index, snapshot, frame).
    rotation : ndarray, shape (3, 3)
        Positions' frame → world, X_world = R X + t.
    translation : ndarray, shape (3,)
        t, m.
    """

    frames: list[ScoredFrame]
    rotation: np.ndarray
    translation: np.ndarray


def scored_frames(positions: Positions) -> list[tuple[int, int, int]]:
    """The frames (k, m, frame) a positions file covers (module docstring), sorted."""
    keys = []
    for k in np.unique(positions.k):
        at_k = positions.k == k
        last = int(positions.snapshot[at_k].max())
        for frame in np.unique(positions.frame[at_k]):
            keys += [(int(k), m, int(frame)) for m in range(last + 1)]
    return sorted(keys)


def _frame_rows(positions: Positions) -> dict[tuple[int, int, int], np.ndarray]:
    """The rows of each frame, in file order."""
    order = np.lexsort((positions.frame, positions.snapshot, positions.k))  # stable
    key = np.stack([positions.k, positions.snapshot, positions.frame], axis=1)[order]
    starts = np.flatnonzero(np.r_[True, np.any(key[1:] != key[:-1], axis=1)])
    ends = np.r_[starts[1:], len(order)]
    return {tuple(int(v) for v in key[s]): order[s:e] for s, e in zip(starts, ends, strict=True)}


def _truth_frames(
    truth: TruthFile, keys: list[tuple[int, int, int]], min_cameras: int
) -> Iterator[tuple[tuple[int, int, int], np.ndarray, np.ndarray]]:
    """(key, particles (P, 3), reference (P,)) of every frame, reading the truth a chunk
    of :data:`TRUTH_CHUNK` snapshots at a time."""
    snapshots = sorted({m for _, m, _ in keys})
    for m0 in range(snapshots[0], snapshots[-1] + 1, TRUTH_CHUNK):
        wanted = [key for key in keys if m0 <= key[1] < m0 + TRUTH_CHUNK]
        if not wanted:
            continue
        runs = truth.runs(m0, min(m0 + TRUTH_CHUNK, truth.frames))
        for k, m, frame in wanted:
            run = runs[k]
            visible = [run.visible[name][m - m0, frame] for name in truth.rig.camera_names]
            yield (
                (k, m, frame),
                run.positions[m - m0, frame],
                reference_particles(visible, min_cameras),
            )


def score_positions(
    positions: Positions, truth: TruthFile, *, voxel: float, min_cameras: int, box: Box
) -> Scored:
    """Align the positions with the truth and pair them, frame by frame.

    Parameters
    ----------
    positions : Positions
        The rows (checked against the dataset).
    truth : TruthFile
        The dataset's truth.
    voxel : float
        Pairing distance, m.
    min_cameras : int
        Cameras a reference particle is imaged by, at least.
    box : Box
        The analysis volume.

    Returns
    -------
    Scored

    Examples
    --------
    The particles' truth of a dataset, written here as ``synptv render`` writes it (4
    snapshots of KS tracers in the paper-stereo rig's sheet at three Δt), and another
    code's positions: the true ones with 10 µm of noise, a track id each.

    >>> import json, pathlib, tempfile
    >>> import numpy as np
    >>> import simulator, validation
    >>> rig, preset = simulator.load_rig("paper-stereo"), simulator.flow_preset("lem-10hz")
    >>> flow = simulator.KSFlow(simulator.PopeSpectrum(preset.parameters), n_modes=50)
    >>> sample = simulator.shared_start(flow, preset.dt[:3], particles=300, snapshots=4,
    ...                                 region=rig.sheet, rng=0)
    >>> tmp = tempfile.TemporaryDirectory()
    >>> folder = pathlib.Path(tmp.name)
    >>> _ = validation.write_sample_truth(folder, rig, sample, preset.parameters)
    >>> rng = np.random.default_rng(1)
    >>> with open(folder / "positions.csv", "w") as f:  # the truth with 10 µm of noise
    ...     print("dt,snapshot,frame,x,y,z,track", file=f)
    ...     for k, run in enumerate(sample.runs):
    ...         for m, frame, p in np.ndindex(run.positions.shape[:3]):
    ...             x, y, z = run.positions[m, frame, p] + rng.normal(0.0, 10e-6, 3)
    ...             print(f"{k},{m},{'ab'[frame]},{x:.9f},{y:.9f},{z:.9f},{p}", file=f)
    >>> truth = validation.TruthFile(folder)
    >>> positions = validation.read_positions(folder / "positions.csv", tracks=True)
    >>> box = ((-0.035, -0.035, -0.004), (0.035, 0.035, 0.004))  # analysis volume, m
    >>> scored = validation.score_positions(positions, truth, voxel=1e-4, min_cameras=2,
    ...                                     box=box)
    >>> len(scored.frames)  # 3 Δt × 4 snapshots × frames a and b
    24
    >>> frame = scored.frames[0]
    >>> frame.k, frame.m, frame.frame, int((frame.partner >= 0).sum()), len(frame.rows)
    (0, 0, 0, 324, 324)
    >>> bool(np.allclose(scored.rotation, np.eye(3), atol=1e-4))  # no frame to correct
    True
    >>> tmp.cleanup()
    """
    keys = scored_frames(positions)
    rows = _frame_rows(positions)
    empty = np.empty(0, dtype=np.int64)

    def frames():
        for key, particles, _ in _truth_frames(truth, keys, min_cameras):
            yield positions.xyz[rows.get(key, empty)], particles

    rotation, translation = align_to_truth(frames)
    scored = []
    for key, particles, reference in _truth_frames(truth, keys, min_cameras):
        at = rows.get(key, empty)
        match = match_frame(
            positions.xyz[at],
            particles,
            reference,
            voxel=voxel,
            rotation=rotation,
            translation=translation,
        )
        paired = match.partner >= 0
        error = np.full((len(at), 3), np.nan)
        error[paired] = match.points[paired] - particles[match.partner[paired]]
        scored.append(
            ScoredFrame(
                *key,
                rows=at,
                partner=match.partner,
                error=error,
                point_in=inside_box(match.points, box),
                counts=match.counts(box),
                found=match.found,
                reference=match.reference,
                particle_in=inside_box(particles, box),
            )
        )
    scored.sort(key=lambda s: (s.k, s.m, s.frame))
    return Scored(scored, rotation, translation)
