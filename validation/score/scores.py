"""The scores of paired positions: yield, ghosts and position errors per Δt and in
total, and the links of tracks.

In the analysis volume (as ``synptv run`` scores its matching): the yield is the
fraction of the reference particles inside it paired with a position, the ghost
fraction that of the positions inside it paired with no particle; the position error
is aligned position − true particle over the true positives of the yield, per
component (mean and RMS, µm). The same over the whole frames is given as ``sheet``.
The totals count every frame scored, at every Δt (frame a once per Δt that has it).

Links (with track ids): a link is a track's position in frame a and its position in
frame b of one snapshot at one Δt, counted when its frame-a end lies in the analysis
volume. It is correct when both ends are paired with the same particle, wrong
otherwise (another particle, or a ghost at either end). A particle is broken when it is
a reference particle in both frames, inside the analysis volume at t, found in both,
and no correct link joins its two positions.
"""

from collections.abc import Sequence

import numpy as np

from validation.score.positions import Positions
from validation.score.reference import ScoredFrame
from validation.truth.matching import matching_fractions


def _moments_um(error: np.ndarray) -> tuple[dict, dict]:
    """Mean and RMS per component of errors (N, 3) in m, as {x, y, z} in µm (None if
    there are none)."""
    if not len(error):
        return dict.fromkeys("xyz"), dict.fromkeys("xyz")
    mean = np.mean(error, axis=0) * 1e6
    rms = np.sqrt(np.mean(error**2, axis=0)) * 1e6
    return (
        {axis: float(v) for axis, v in zip("xyz", mean, strict=True)},
        {axis: float(v) for axis, v in zip("xyz", rms, strict=True)},
    )


def summarize(frames: Sequence[ScoredFrame]) -> dict:
    """The scores of some frames (module docstring).

    Parameters
    ----------
    frames : sequence of ScoredFrame
        The frames pooled.

    Returns
    -------
    dict
        ``yield``, ``ghost_fraction``, ``position_rms_um`` and ``position_mean_um``
        ({x, y, z}), ``n_reference`` (reference particles in the analysis volume),
        ``n_found`` (positions in it), ``n_true_positive``, ``n_ghost``, ``frames`` and
        ``sheet`` (``yield``, ``ghost_fraction``, ``n_reference``, ``n_found`` over the
        whole frames).

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
    >>> summary = validation.score_summary(scored.frames)
    >>> summary["yield"], summary["ghost_fraction"], summary["n_reference"]
    (1.0, 0.0, 2967)
    >>> {axis: round(rms, 1) for axis, rms in summary["position_rms_um"].items()}  # µm
    {'x': 9.9, 'y': 9.8, 'z': 10.0}
    >>> tmp.cleanup()
    """
    counts = np.sum([f.counts for f in frames], axis=0, dtype=np.int64)
    points = sum(len(f.partner) for f in frames)
    ghosts = sum(int((f.partner < 0).sum()) for f in frames)
    fractions = matching_fractions(counts, points, ghosts)
    error = np.concatenate([f.error[f.tp_in] for f in frames]) if frames else np.empty((0, 3))
    mean, rms = _moments_um(error)
    return {
        "yield": fractions["yield"],
        "ghost_fraction": fractions["ghost_fraction"],
        "position_rms_um": rms,
        "position_mean_um": mean,
        "n_reference": fractions["particles"],
        "n_found": fractions["matches"],
        "n_true_positive": int(counts[1]),
        "n_ghost": int(counts[3]),
        "frames": len(frames),
        "sheet": {
            "yield": fractions["sheet_yield"],
            "ghost_fraction": fractions["sheet_ghost_fraction"],
            "n_reference": int(counts[4]),
            "n_found": points,
        },
    }


def per_dt(frames: Sequence[ScoredFrame], dt: np.ndarray) -> list[dict]:
    """:func:`summarize` of every Δt scored, with ``dt_index`` and ``dt_s``.

    Parameters
    ----------
    frames : sequence of ScoredFrame
        Every frame scored.
    dt : ndarray, shape (K,)
        The dataset's Δt, s.

    Returns
    -------
    list of dict
        One :func:`summarize` per Δt index scored, in order.

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
    >>> per_dt = validation.scores_per_dt(scored.frames, truth.dt)
    >>> [(row["dt_index"], round(row["dt_s"] * 1e3, 3), row["yield"]) for row in per_dt]
    [(0, 0.097, 1.0), (1, 0.194, 1.0), (2, 0.291, 1.0)]
    >>> tmp.cleanup()
    """
    out = []
    for k in sorted({f.k for f in frames}):
        entry = {"dt_index": k, "dt_s": float(dt[k])}
        entry.update(summarize([f for f in frames if f.k == k]))
        out.append(entry)
    return out


def track_scores(positions: Positions, frames: Sequence[ScoredFrame]) -> dict:
    """Correct, wrong and broken links of the tracks (module docstring).

    Parameters
    ----------
    positions : Positions
        The rows, with their track ids.
    frames : sequence of ScoredFrame
        Every frame scored.

    Returns
    -------
    dict
        ``links``, ``correct``, ``wrong``, ``broken`` (counts), ``correct_fraction`` and
        ``wrong_fraction`` (of the links), ``broken_fraction`` (of the particles found
        in both frames), ``found_in_both`` (those particles).

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
    >>> links = validation.track_scores(positions, scored.frames)
    >>> int(links["links"]), int(links["correct"]), int(links["wrong"]), links["broken"]
    (1485, 1485, 0, 0)
    >>> tmp.cleanup()
    """
    by_key = {(f.k, f.m, f.frame): f for f in frames}
    links = correct = broken = both = 0
    for (k, m, frame), a in by_key.items():
        b = by_key.get((k, m, 1))
        if frame != 0 or b is None:
            continue
        ids_b = dict(zip(positions.track[b.rows].tolist(), range(len(b.rows)), strict=True))
        joined = np.zeros(len(a.found), dtype=bool)
        for i, track in enumerate(positions.track[a.rows].tolist()):
            j = ids_b.get(track)
            if j is None:
                continue
            same = a.partner[i] >= 0 and a.partner[i] == b.partner[j]
            if same:
                joined[a.partner[i]] = True
            if a.point_in[i]:
                links += 1
                correct += same
        measurable = a.reference & b.reference & a.particle_in & a.found & b.found
        both += int(measurable.sum())
        broken += int((measurable & ~joined).sum())
    return {
        "links": links,
        "correct": correct,
        "wrong": links - correct,
        "broken": broken,
        "found_in_both": both,
        "correct_fraction": correct / max(links, 1),
        "wrong_fraction": (links - correct) / max(links, 1),
        "broken_fraction": broken / max(both, 1),
    }
