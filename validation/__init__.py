"""Where truth and estimate meet: scenarios, runs, scores, studies, claims, the CLI.

``validation`` drives the simulator (``simulator``) and the PTV stack (``ptv``) and
compares what the stack measures with what the simulator knows; ``synptv`` is its
command line (``validation.cli``).

The names below are the public API, importable as ``validation.<name>``; each is loaded
on first use, so ``import validation`` stays cheap. Units are SI (m, s, m/s) except
pixels (px) and the µm of the position errors the scores report.

Scenarios and runs (docs/run.md)
    scenario_presets      the names of the scenarios shipped with synptv
    load_scenario         a scenario by preset name or TOML file, checked, its PTV
                          ranges following its rig and flow
    Scenario              flow, rig, calibration, particles, sensor, PTV analysis, checks
    run_scenario          every stage of ``synptv run``: render, detect, calibrate, PTV,
                          truth (validation.run.experiment.run_stages)

Scoring against the truth (docs/score.md)
    TruthFile             a rendered dataset's truth.h5, read a range of snapshots at a time
    write_sample_truth    the truth.h5 of a simulated sample as a rig's cameras see it
                          (no images): a dataset to score positions against
    read_positions        another code's 3-D positions from a CSV or HDF5 file
    check_positions       those rows checked against the dataset: indices, units, tracks
    score_positions       the positions aligned with the truth and paired, frame by frame
    score_summary         yield, ghosts and position errors of scored frames
                          (validation.score.scores.summarize)
    scores_per_dt         the same for each Δt (validation.score.scores.per_dt)
    track_scores          correct, wrong and broken links of the positions' track ids
    score_statistics      S2, ε and u′ from the positions, checked against the truth
    read_tracks           a time-resolved code's tracks from a CSV file
    TrackPoints           tracks, one row per point: track id, frame, position
    TrueTrajectories      a recording's truth, one row per particle and frame
    trajectory_scores     tracked fraction, fragmentation, mislinks and errors of tracks

Studies (docs/study.md)
    StudySettings         what a study takes beyond its scenario: noise levels, sizes
    run_study             one parameter swept over a scenario: table, CSV and figure

Claims (docs/claims.md)
    ClaimContext          the runs the claims share, at one size (quick or full)
    run_claims            the paper's claims measured against the truth
    ClaimResult           one claim's value, tolerance and verdict

A rendered dataset's truth beside another code's positions (what ``synptv score``
computes; the CSV has the header ``dt,snapshot,frame,x,y,z``)::

    import validation

    truth = validation.TruthFile("my-dataset")
    positions = validation.read_positions("positions.csv")
    validation.check_positions(positions, n_dt=len(truth.dt), snapshots=truth.frames,
                               sheet=truth.rig.sheet)
    box = ((-0.035, -0.035, -0.004), (0.035, 0.035, 0.004))  # analysis volume, m
    scored = validation.score_positions(positions, truth, voxel=1e-4, min_cameras=2,
                                        box=box)
    print(validation.score_summary(scored.frames)["yield"])

Every name's docstring has examples on small inputs; the packages hold the rest
(``validation.run``: rendering datasets; ``validation.export``: OpenPTV and MyPTV
layouts; ``validation.truth``: the reference values the checks compare with).
"""

from importlib import import_module

#: Public name → (module, name there). Kept out of the namespace until first use: the
#: names import the PTV stack and the simulator, about two seconds together.
_EXPORTS = {
    # scenarios and runs
    "scenario_presets": ("validation.run.scenario", "scenario_presets"),
    "load_scenario": ("validation.run.scenario", "load_scenario"),
    "Scenario": ("validation.run.scenario", "Scenario"),
    "run_scenario": ("validation.run.experiment", "run_stages"),
    # scoring against the truth
    "TruthFile": ("validation.truth.truth_file", "TruthFile"),
    "write_sample_truth": ("validation.truth.truth_file", "write_sample_truth"),
    "read_positions": ("validation.score.positions", "read_positions"),
    "check_positions": ("validation.score.positions", "check_positions"),
    "score_positions": ("validation.score.reference", "score_positions"),
    "score_summary": ("validation.score.scores", "summarize"),
    "scores_per_dt": ("validation.score.scores", "per_dt"),
    "track_scores": ("validation.score.scores", "track_scores"),
    "score_statistics": ("validation.run.score_statistics", "score_statistics"),
    "read_tracks": ("validation.score.track_file", "read_tracks"),
    "TrackPoints": ("validation.score.trajectories", "TrackPoints"),
    "TrueTrajectories": ("validation.score.trajectories", "TrueTrajectories"),
    "trajectory_scores": ("validation.score.trajectories", "trajectory_scores"),
    # studies
    "StudySettings": ("validation.studies.study", "StudySettings"),
    "run_study": ("validation.studies.study", "run_study"),
    # claims
    "ClaimContext": ("validation.claims", "ClaimContext"),
    "run_claims": ("validation.claims", "run_claims"),
    "ClaimResult": ("validation.claims", "ClaimResult"),
}

__all__ = list(_EXPORTS)


def __getattr__(name: str) -> object:
    """The public object ``name``, imported from its module on first use (PEP 562)."""
    try:
        module, attribute = _EXPORTS[name]
    except KeyError:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}") from None
    value = getattr(import_module(module), attribute)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    """The module's names and the public ones not loaded yet (for ``dir`` and ``help``)."""
    return sorted(set(globals()) | set(__all__))
