"""S2 and ε from a code's own positions through synptv's multi-Δt statistics, compared
with the truth as ``synptv run``'s error budget compares its rungs.

The positions of frames a and b of each snapshot at each Δt are linked: by their track
ids when the file has tracks, else by synptv's double-frame linker
(:func:`ptv.tracking.linking.link`, radius max_speed·Δt + 5σ_b, max_speed measured on
the file's first snapshots unless the settings give it); a normalised median test flags
mislinks (:func:`ptv.pipeline.double_frame.median_test_outliers`), as for synptv's own links. The
links in the analysis volume go through :func:`ptv.stats.run_statistics.compute_statistics`
(with a shared first frame when the dataset has one and the file gives the same
frame-a positions at every Δt). Then, as in ``synptv run`` (:mod:`validation.run.checks`):
c1 against the sample-truth S2 of the pairs it used, the plateau ε and u′ against the
statistics of the true positions of the same snapshots, each with its paired error and
at the run's false-alarm rate, so that a few snapshots leave a wide tolerance rather
than a false verdict.
"""

from dataclasses import replace

import numpy as np

from ptv.pipeline.double_frame import SnapshotMeasurement, run_particles
from ptv.pipeline.link_radii import link_radius
from ptv.pipeline.resolve import LINK_SPEED_SNAPSHOTS, settings_with_measured_speed
from ptv.pipeline.summary import statistics_summary
from ptv.settings import PipelineSettings
from ptv.stats.links import RunParticles
from ptv.stats.run_statistics import compute_statistics
from ptv.tracking.linking import link
from ptv.tracking.outliers import median_test_outliers
from validation.run.checks import compare_variant
from validation.run.particle_chunks import snapshot_chunks
from validation.run.scenario import ChecksSection
from validation.run.truth_rungs import in_volume, reference_run
from validation.score.noise_prediction import predicted_noise
from validation.score.positions import Positions
from validation.score.reference import Scored
from validation.truth.flow_truth import flow_truth, population_truth
from validation.truth.truth_file import TruthFile


def _pairs(positions: Positions, a: np.ndarray, b: np.ndarray, radius: float | None):
    """Row indices (into ``a`` and ``b``) of the links of one snapshot: by track id when
    ``radius`` is None, else by :func:`ptv.tracking.linking.link`."""
    if radius is None:
        in_b = {t: j for j, t in enumerate(positions.track[b].tolist())}
        pairs = [(i, in_b[t]) for i, t in enumerate(positions.track[a].tolist()) if t in in_b]
        pairs = np.array(pairs, dtype=np.int64).reshape(-1, 2)
        return pairs[:, 0], pairs[:, 1]
    if not len(a) or not len(b):
        return np.empty(0, np.int64), np.empty(0, np.int64)
    links = link(positions.xyz[a], positions.xyz[b], radius=radius)
    return links.index_a, links.index_b


def _with_measured_speed(
    positions: Positions, rows: dict, dt: np.ndarray, settings: PipelineSettings
) -> PipelineSettings:
    """The settings with max_speed measured on the file's first snapshots at its smallest
    scored Δt (as a run measures it on its own)."""
    paired = sorted({k for k, m, frame in rows if frame == 0 and (k, m, 1) in rows})
    if not paired:
        return settings  # nothing to link
    k = min(paired, key=lambda kk: dt[kk])
    snapshots = sorted(m for kk, m, frame in rows if kk == k and frame == 0 and (k, m, 1) in rows)
    pairs = [
        (positions.xyz[rows[(k, m, 0)]], positions.xyz[rows[(k, m, 1)]])
        for m in snapshots[:LINK_SPEED_SNAPSHOTS]
    ]
    return settings_with_measured_speed(settings, pairs, k, float(dt[k]))[0]


def link_runs(
    positions: Positions, scored: Scored, dt: np.ndarray, settings: PipelineSettings
) -> list[RunParticles]:
    """The links of every Δt whose frames a and b are both scored (module docstring).

    Parameters
    ----------
    positions : Positions
        The rows (with track ids to link by them).
    scored : Scored
        The frames scored (their rows).
    dt : ndarray, shape (K,)
        The dataset's Δt, s.
    settings : PipelineSettings
        Link radius, median test, analysis volume.

    Returns
    -------
    list of RunParticles
        One per Δt with both frames, positions in the file's own frame.
    """
    rows = {(f.k, f.m, f.frame): f.rows for f in scored.frames}
    if positions.track is None and settings.max_speed is None:
        settings = _with_measured_speed(positions, rows, dt, settings)
    runs = []
    for k in sorted({key[0] for key in rows}):
        snapshots = sorted(m for kk, m, frame in rows if kk == k and frame == 0)
        measured = []
        for m in snapshots:
            if (k, m, 1) not in rows:
                continue
            a, b = rows[(k, m, 0)], rows[(k, m, 1)]
            radius = None if positions.track is not None else link_radius(dt[k], settings)
            i, j = _pairs(positions, a, b, radius)
            x, d = positions.xyz[a[i]], positions.xyz[b[j]] - positions.xyz[a[i]]
            outlier = np.zeros(len(x), dtype=bool)
            if settings.outlier_threshold is not None:
                outlier = median_test_outliers(
                    x,
                    d,
                    threshold=settings.outlier_threshold,
                    noise=settings.position_noise,
                    neighbours=settings.outlier_neighbours,
                )
            measured.append(
                SnapshotMeasurement(
                    k=k,
                    m=m,
                    detections=np.zeros((2, 1), dtype=np.int64),  # a file has no detections
                    matches=np.array([len(a), len(b)]),
                    links=len(x),
                    positions=x,
                    displacements=d,
                    outlier=outlier,
                )
            )
        if measured:
            runs.append(run_particles(k, float(dt[k]), measured, 1, settings))
    return runs


def _shares_first_frame(positions: Positions, scored: Scored) -> bool:
    """Whether every snapshot's frame-a positions are the same at every Δt."""
    first: dict[int, np.ndarray] = {}
    for f in scored.frames:
        if f.frame != 0:
            continue
        x = positions.xyz[f.rows]
        x = x[np.lexsort(x.T[::-1])]
        if f.m in first and not np.array_equal(first[f.m], x):
            return False
        first.setdefault(f.m, x)
    return True


def _exact_summary(
    truth: TruthFile, runs: list[RunParticles], settings: PipelineSettings, shared: bool
) -> dict | None:
    """The statistics of the true positions of the very snapshots the file's links came
    from (every particle in the analysis volume), as a summary whose bootstrap pairs with
    the file's: what ε and u′ are judged against. None where a Δt keeps fewer than two
    snapshots."""
    exact = []
    for run in runs:
        ids = run.snapshot_ids.tolist()
        per_snapshot = []
        for m in ids:
            positions = truth.runs(m, m + 1)[run.k].positions[0]
            per_snapshot.append(in_volume(positions[0], positions[1], settings))
        exact.append(reference_run(run.k, run.dt, ids, per_snapshot, 1))
    statistics_settings = replace(settings.statistics, trajectory_threshold=None)
    try:
        found = compute_statistics(exact, statistics_settings, shared_first_frame=shared)
    except ValueError:
        return None
    if found.bootstrap is None:
        return None
    return statistics_summary(found)


def score_statistics(
    positions: Positions,
    scored: Scored,
    truth: TruthFile,
    settings: PipelineSettings,
    *,
    voxel: float,
) -> dict:
    """S2, ε, c1 and their checks against truth from the positions (module docstring).

    Parameters
    ----------
    positions : Positions
        The rows.
    scored : Scored
        The frames scored and the alignment with the truth.
    truth : TruthFile
        The dataset's truth.
    settings : PipelineSettings
        Linking and statistics settings.
    voxel : float
        Association radius of the measured and true particles, m.

    Returns
    -------
    dict
        ``computed`` False with a ``reason`` when the positions do not allow it (no Δt
        with both frames, fewer than two Δt with links); else ``linked_by``,
        ``shared_first_frame``, ``links_used`` per Δt, the checks of
        :func:`validation.run.checks.compare_variant` (``c1``, ``epsilon``, ``c2``,
        ``raw_s2``, ``mean_linear``, ``subsets``, ``c1_over_truth``; ``c1_reference``:
        which sample truth c1 is compared with), ``sample_truth`` (the sample truth and
        exact D_LL, :class:`validation.truth.flow_truth.FlowTruth`), ``population`` and
        ``summary`` (:func:`ptv.pipeline.summary.statistics_summary`).

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
    >>> import ptv
    >>> settings = ptv.PipelineSettings(statistics=ptv.StatisticsSettings(analysis_volume=box))
    >>> result = validation.score_statistics(positions, scored, truth, settings, voxel=1e-4)
    >>> result["computed"], result["linked_by"]
    (True, 'tracks')
    >>> epsilon = result["epsilon"]  # the plateau ε against the truth of the same snapshots
    >>> epsilon["passed"], bool(abs(epsilon["relative_to_exact_rung"]) < epsilon["tolerance"])
    (True, True)
    >>> tmp.cleanup()
    """
    runs = link_runs(positions, scored, truth.dt, settings)
    if not runs:
        return {
            "computed": False,
            "reason": "no statistics: the file has no snapshot with positions in both "
            "frames a and b at any Δt",
        }
    shared = truth.shared_first_frame and _shares_first_frame(positions, scored)
    chunks = snapshot_chunks(truth.frames)
    parameters, exact = truth.flow()
    reference = flow_truth(
        truth.snapshots_at_t(chunks), parameters, exact, settings.statistics
    ).as_dict()
    # The file's statistics and the true positions' draw in the blocks the sample
    # truth's snapshots ask, so that their replicates always pair (as synptv run's rungs).
    block = reference["snapshot_correlation"]["block"]
    settings = replace(settings, statistics=replace(settings.statistics, snapshot_block=block))
    try:
        statistics = compute_statistics(runs, settings.statistics, shared_first_frame=shared)
    except ValueError as err:
        return {"computed": False, "reason": f"no statistics: {err}"}
    exact_summary = _exact_summary(truth, runs, settings, shared)
    population = None
    if statistics.population is not None:
        replicates = None
        if statistics.bootstrap is not None and statistics.structure.s2_boot is not None:
            replicates = (statistics.bootstrap, statistics.structure.s2_boot)
        population = population_truth(
            statistics.population,
            truth,
            chunks,
            settings.statistics,
            radius=voxel,
            rotation=scored.rotation,
            translation=scored.translation,
            replicates=replicates,
        ).as_dict()
    lower, upper = (np.asarray(v) for v in settings.statistics.analysis_volume)
    noise = None
    if population is not None and all(
        v is not None for row in population["displacement_noise_m"] for v in row
    ):
        noise = predicted_noise(population, settings.statistics.bins, upper - lower)
    checks = ChecksSection()
    summary = statistics_summary(statistics)
    compared = compare_variant(
        summary,
        reference,
        check_range=(
            checks.c1_r_min_eta * parameters.eta,
            checks.c1_r_max_l_int * parameters.L_int,
        ),
        noise=noise,
        population=population,
        exact=exact_summary,
    )
    compared["c1_reference"] = compared.pop("truth")
    boot = summary.get("bootstrap") or {}
    return {
        "computed": True,
        "effective_snapshots": (boot.get("correlation") or {}).get("effective_snapshots"),
        "linked_by": "tracks" if positions.track is not None else "synptv's linker",
        "shared_first_frame": shared,
        "links_used": {str(run.k): int(run.used.sum()) for run in runs},
        **compared,
        "sample_truth": reference,
        "population": population,
        "summary": summary,
    }
