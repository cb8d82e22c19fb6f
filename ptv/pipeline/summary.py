"""``summary.json``: what :func:`ptv.pipeline.double_frame.run_pipeline` measured, as
JSON (SI units; NaN written as null), beside ``results.h5`` (:mod:`ptv.pipeline.results`).

- :func:`summary`: the whole file: the settings as used, per Δt the counts of detections,
  matches and links with their warnings, the statistics (:func:`statistics_summary`) and,
  for a recording, its tracks (:func:`tracks_summary`).
- :func:`thin_data_warnings`: frames whose matches are too few to trust.
"""

import numpy as np

from ptv.pipeline.double_frame import PtvResult, ambiguity_message
from ptv.pipeline.link_radii import radius_at
from ptv.stats.dissipation import Plateau
from ptv.stats.links import RunParticles
from ptv.stats.mean_displacement import MeanDisplacement
from ptv.stats.run_statistics import PtvStatistics
from ptv.tracking.linking import RecordingTracks

__all__ = [
    "FORMAT_NAME",
    "FORMAT_VERSION",
    "THIN_MATCH_FRACTION",
    "plateau_dict",
    "recorded_link_radius",
    "settings_dict",
    "statistics_summary",
    "summary",
    "thin_data_warnings",
    "tracks_summary",
]


#: The format of ``results.h5`` and ``summary.json``, written into both.
FORMAT_NAME = "synptv-ptv-results"
FORMAT_VERSION = 1


def _num(value) -> float | None:
    """A JSON-safe float: None for NaN or inf."""
    if value is None:
        return None
    v = float(value)
    return v if np.isfinite(v) else None


def _list(values) -> list:
    return [_num(v) for v in np.asarray(values, dtype=np.float64).ravel()]


def plateau_dict(plateau: Plateau | None) -> dict | None:
    if plateau is None:
        return None
    return {
        "epsilon": _num(plateau.epsilon),
        "se_epsilon": _num(plateau.se_epsilon),
        "epsilon_paper_caption": _num(plateau.epsilon_paper_caption),
        "method": plateau.method,
        "r_min": plateau.r_min,
        "r_max": plateau.r_max,
        "n_bins": plateau.n_bins,
    }


def _measured(measurement) -> dict | None:
    """A measured setting's ``as_dict()``; None when the settings gave it."""
    return None if measurement is None else measurement.as_dict()


def settings_dict(result: PtvResult) -> dict:
    s, st = result.settings, result.settings.statistics
    return {
        "volume": [list(v) for v in s.volume],
        "tolerance": s.tolerance,
        "min_cameras": s.min_cameras,
        "max_speed": s.max_speed,
        "position_noise": s.position_noise,
        "predicted_radii": None if s.predicted_radii is None else _list(s.predicted_radii),
        "max_acceleration": s.max_acceleration,
        "analysis_volume": [list(v) for v in st.analysis_volume],
        "r_min": st.r_min,
        "r_max": st.r_max,
        "n_bins": st.n_bins,
        # written only when not the default, so that runs before it keep their files
        **({} if st.binning == "start" else {"binning": st.binning}),
        "plateau": list(st.plateau),
        "plateau_method": st.plateau_method,
        "kolmogorov_c2": st.kolmogorov_c2,
        "n_boot": st.n_boot,
        "eulerian_cells": list(st.eulerian_cells),
        "min_cell_count": st.min_cell_count,
        "threshold_sigmas": result.source.detector["threshold_sigmas"],
        "detection": dict(result.source.detector),
        "outlier_threshold": s.outlier_threshold,
        "outlier_neighbours": s.outlier_neighbours,
        "trajectory_threshold": st.trajectory_threshold,
        "snapshots": s.snapshots,
        "seed": st.seed,
    }


#: Below this fraction of the particles seen by the camera that sees fewest, a frame's
#: matches are reported as too few: a calibration of another rig matches by chance (a
#: tenth of them or fewer), a healthy stereo pair 80–90 %, and 35–40 % where each real
#: particle must be seen by all three cameras (examples/myptv).
THIN_MATCH_FRACTION = 0.25


def thin_data_warnings(counts: list[dict], *, statistics: bool = True) -> list[str]:
    """Why a run is too thin to measure: one line for the frames at fault, and one per
    Δt without a link.

    Parameters
    ----------
    counts : list of dict
        The ``counts`` entries of :func:`summary`.
    statistics : bool
        Whether the statistics were asked for (a Δt without a link matters only then).

    Returns
    -------
    list of str
        Empty for a healthy run. Frames (a or b of a Δt) are reported when their matches
        are fewer than :data:`THIN_MATCH_FRACTION` of the detections of the camera that
        sees fewest particles (a blank or saturated frame, a calibration of another rig
        or swapped cameras, particles outside the matching volume): the worst named, and
        how many there are; with ``statistics``, each Δt with no link used at all.
    """
    thin = []  # (fraction matched, text)
    for c in counts:
        where = f"Δt = {c['dt'] * 1e3:.4g} ms"
        for frame in ("a", "b"):
            seen = {camera: d[frame] for camera, d in c["detections"].items()}
            fewest = min(seen, key=seen.get)
            matched = c["matches"][frame]
            if matched < THIN_MATCH_FRACTION * seen[fewest] or seen[fewest] == 0:
                per_camera = ", ".join(f"{camera} {n}" for camera, n in seen.items())
                text = (
                    f"{where}, frame {frame}: {matched} matches from {per_camera} detections "
                    f"(camera {fewest} sees fewest)"
                )
                thin.append((matched / max(seen[fewest], 1), text))
    lines = []
    if thin:
        worst = min(thin)[1]
        more = (
            f" (and {len(thin) - 1} more of the {2 * len(counts)} frames)" if len(thin) > 1 else ""
        )
        lines.append(
            f"{worst}{more}: check the images, that the calibration is of this rig, cameras "
            "in the same order, and that the matching volume holds the particles"
        )
    if statistics:
        lines += [
            f"Δt = {c['dt'] * 1e3:.4g} ms: no link used: S2 and ε have no data at this Δt"
            for c in counts
            if c["links_used"] == 0
        ]
    return lines


def summary(result: PtvResult, *, calibration: str | None = None) -> dict:
    """The headline numbers of a run as a JSON-ready dict (SI units, None for NaN).

    Keys: ``dataset``, ``calibration``, ``cameras``, ``settings``, ``dt``, ``counts``
    (per Δt: snapshots processed, kept and skipped, detections per camera and frame,
    matches per frame, links, links in the analysis volume, link radius, ambiguous links
    and their fraction, particle spacing), ``match_tolerance`` and ``link_speed`` (how
    the matching tolerance and max_speed were measured on the data; None where the
    settings gave them), ``warnings`` (an image detector's
    :attr:`~ptv.detect.frames.ImageDetector.warnings`, :func:`thin_data_warnings`
    and :func:`ptv.pipeline.double_frame.ambiguity_message`), and those of
    :func:`statistics_summary` (only ``statistics_dt`` and ``errors``, both None, for a run
    of positions and links only);
    ``tracks`` (:func:`tracks_summary`) for the tracks of a recording.
    """
    counts = [_run_counts(run, result) for run in result.runs]
    ambiguous = [
        ambiguity_message(
            run, result.settings, speed_measured=result.measured.link_speed is not None
        )
        for run in result.runs
    ]
    statistics = (
        {"statistics_dt": None, "errors": None}
        if result.statistics is None
        else statistics_summary(result.statistics)
    )
    tracks = {} if result.recording is None else {"tracks": tracks_summary(result.recording)}
    return {
        "format": FORMAT_NAME,
        "format_version": FORMAT_VERSION,
        "dataset": str(result.source.folder),
        "calibration": calibration,
        "cameras": list(result.cameras),
        "settings": settings_dict(result),
        "dt": [float(v) for v in result.source.dt],
        "statistics_dt": statistics.pop("statistics_dt"),
        "errors": statistics.pop("errors"),
        "counts": counts,
        "match_tolerance": _measured(result.measured.tolerance),
        "link_speed": _measured(result.measured.link_speed),
        "link_prediction": _measured(result.measured.link_prediction),
        # An image detector (ImageDetector) first: what it found wrong with the images
        # explains the thin data after it.
        "warnings": list(getattr(result.source, "warnings", ()))
        + thin_data_warnings(counts, statistics=result.statistics is not None)
        + [line for line in ambiguous if line],
        **tracks,
        **statistics,
    }


def tracks_summary(recording: RecordingTracks) -> dict:
    """The tracks of a recording in numbers (JSON-ready).

    Keys: ``frames`` (first and last frame number tracked), ``frame_rate`` (Hz),
    ``radius`` and ``predicted_radius`` (m), ``gap`` (missed frames a track may close),
    ``joins`` (tracks joined by :func:`ptv.tracking.stitching.stitch_tracks`),
    ``miss_noise`` (m, the noise of the first pass's predictions, or None),
    ``points`` (matched points, all frames),
    ``points_per_frame`` (their mean), ``tracks``, ``links``, ``mean_length`` (points
    per track; None without tracks), ``length_histogram``: ``edges`` 1, 2, 4, … and the
    ``count`` of tracks whose length L has edges[i] <= L < edges[i + 1].
    """
    tracks = recording.tracks
    lengths = tracks.lengths
    top = int(lengths.max()) if lengths.size else 1
    edges = 2 ** np.arange(int(np.log2(top)) + 2)
    count, _ = np.histogram(lengths, bins=edges)
    return {
        "frames": [int(recording.numbers[0]), int(recording.numbers[-1])],
        "frame_rate": recording.frame_rate,
        "radius": recording.radius,
        "predicted_radius": recording.predicted_radius,
        "gap": recording.gap,
        "joins": recording.joins,
        "miss_noise": recording.miss_noise,
        "points": len(tracks),
        "points_per_frame": len(tracks) / len(recording.numbers),
        "tracks": tracks.n_tracks,
        "links": tracks.links,
        "mean_length": len(tracks) / tracks.n_tracks if tracks.n_tracks else None,
        "length_histogram": {"edges": edges.tolist(), "count": count.tolist()},
    }


def statistics_summary(st: PtvStatistics) -> dict:
    """The statistics of a run as a JSON-ready dict (SI units, None for NaN).

    Keys: ``statistics_dt`` (the Δt used, s), ``errors`` (how the errors were
    estimated), ``u_prime``, ``epsilon`` (plateau of (S2/C2)^{3/2}/r and of the paper's
    S2^{3/2}/r), ``subsets`` (their plateau ε and its ratio to the all-Δt value),
    ``mean_displacement`` (the linearity check), ``population`` (the particles of S2
    with a shared first frame), ``noise`` (median c2 over fitted bins, σ_b per
    component from the Eulerian fit), ``structure_function`` (r, S2, its error, c2 and
    its error, the raw ⟨q⟩/Δt² per Δt (K lists of B), χ²/dof, fitted bins).
    """
    eps_all = st.plateau.epsilon if st.plateau is not None else np.nan
    subsets = {}
    for name, sub in st.subsets.items():
        entry = {"dt": [float(v) for v in st.dt[sub.used]], "plateau": plateau_dict(sub.plateau)}
        if sub.plateau is not None and np.isfinite(eps_all):
            entry["epsilon_ratio_to_all"] = _num(sub.plateau.epsilon / eps_all)
            entry["se_epsilon_ratio_to_all"] = _paired_ratio_se(sub.plateau, st.plateau)
        subsets[name] = entry
    sf = st.structure
    noise = sf.noise[sf.fitted]
    up = st.u_prime
    return {
        "statistics_dt": [float(v) for v in st.dt],
        "errors": st.errors,
        "u_prime": None
        if up is None
        else {
            "value": _num(up.value),
            "se": _num(up.se),
            "per_component": _list(up.per_component),
            "n_cells": up.n_cells,
            "se_snapshots": _num(up.se_snapshots),
        },
        "epsilon": {
            "plateau": plateau_dict(st.plateau),
            "kolmogorov_c2": st.profile.kolmogorov_c2,
            "note": "epsilon = (S2/C2)^(3/2)/r; epsilon_paper_caption = S2^(3/2)/r "
            "(the paper's Fig. 6 caption, no C2): C2^(3/2) times larger",
        },
        "subsets": subsets,
        "mean_displacement": _mean_displacement_dict(st.mean_displacement),
        "population": None
        if st.population is None
        else {
            "snapshots": len(st.population.snapshot_ids),
            "particles": st.population.count,
            "trajectory_outliers": st.population.trajectory_outliers,
        },
        "noise": {
            "c2_median": _num(np.median(noise)) if noise.size else None,
            "c2_fitted_bins": int(noise.size),
            "position_noise_eulerian": _list(st.position_noise),
        },
        "structure_function": {
            "r": _list(sf.r),
            "s2": _list(sf.s2),
            "se_s2": _list(sf.se_s2),
            "noise": _list(sf.noise),
            "se_noise": _list(sf.se_noise),
            "raw_s2": [_list(row) for row in sf.raw_s2.T],
            "chi2_dof": _list(sf.chi2_dof),
            "fitted": [bool(v) for v in sf.fitted],
            "method": sf.method,
        },
        "bootstrap": _bootstrap_dict(st),
    }


def _paired_ratio_se(part: Plateau, whole: Plateau | None) -> float | None:
    """Standard error of one plateau ε over another refitted on the same bootstrap
    replicates (None without replicates)."""
    if whole is None or part.replicates is None or whole.replicates is None:
        return None
    return _num(np.std(part.replicates / whole.replicates, ddof=1))


def _bootstrap_dict(st: PtvStatistics) -> dict | None:
    """The bootstrap every estimate shares (:class:`ptv.stats.resampling.SnapshotBootstrap`):
    how it drew the snapshots, and the replicates of the plateau ε and of u′, which pair
    with those of another measurement of the same snapshots (None: errors from the pairs)."""
    boot = st.bootstrap
    if boot is None:
        return None
    eps, up = (getattr(v, "replicates", None) for v in (st.plateau, st.u_prime))
    return {
        "replicates": boot.replicates,
        "seed": boot.seed,
        "block": boot.block,
        "correlation": boot.correlation.as_dict(),
        "snapshot_ids": [[int(m) for m in ids] for ids in boot.snapshot_ids],
        "epsilon_plateau": None if eps is None else _list(eps),
        "u_prime": None if up is None else _list(up),
    }


def recorded_link_radius(run: RunParticles, result: PtvResult) -> float | None:
    """The link radius of a run, m (None for links not made by distance, as the exact
    trajectories' of a simulation)."""
    if result.settings.max_speed is None:
        return None
    return radius_at(run.k, run.dt, result.settings)


def _run_counts(run: RunParticles, result: PtvResult) -> dict:
    """What one Δt's run processed and found (an entry of ``summary["counts"]``)."""
    return {
        "k": run.k,
        "dt": run.dt,
        "snapshots_processed": len(run.processed),
        "snapshots_kept": len(run.snapshot_ids),
        "snapshots_skipped": [int(m) for m in run.skipped],
        "detections": {
            cam: {"a": int(run.detections[:, 0, c].sum()), "b": int(run.detections[:, 1, c].sum())}
            for c, cam in enumerate(result.cameras)
        },
        "matches": {"a": int(run.matches[:, 0].sum()), "b": int(run.matches[:, 1].sum())},
        "links": int(run.links.sum()),
        "outliers": int(run.outlier.sum()),
        "links_in_analysis_volume": int(run.in_analysis.sum()),
        "links_used": int(run.used.sum()),
        "link_radius": recorded_link_radius(run, result),
        "ambiguous_links": None if run.ambiguous is None else int(run.ambiguous.sum()),
        "ambiguity": _num(run.ambiguity),
        "particle_spacing": (
            None
            if run.spacing is None or not np.isfinite(run.spacing).any()
            else float(np.nanmedian(run.spacing))
        ),
    }


def _mean_displacement_dict(md: MeanDisplacement) -> dict:
    """The mean displacement against Δt, its linear fit and the offset test."""
    return {
        "dt": _list(md.dt),
        "mean": [_list(row) for row in md.mean],
        "se": [_list(row) for row in md.se],
        "velocity": _list(md.fit.c1),
        "se_velocity": _list(md.fit.se_c1),
        "offset": _list(md.fit.c2),
        "se_offset": _list(md.fit.se_c2),
        "se_offset_scaled": _list(md.se_offset_scaled),
        "chi2_dof": _list(md.fit.chi2_dof),
        "offset_test": dict(zip(("statistic", "limit"), md.offset_test(), strict=True)),
    }
