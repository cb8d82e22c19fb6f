"""Results of :func:`ptv.pipeline.double_frame.run_pipeline` on disk: HDF5 arrays and a
JSON summary.

``results.h5`` (format ``synptv-ptv-results``, version :data:`FORMAT_VERSION`; every
dataset has a ``units`` attribute)::

    /                         attrs: format, format_version, dataset, calibration,
                              cameras, settings (JSON)
    /particles/dt<k>          attrs: dt (s), link_radius (m), links_kept
        positions (N, 3) m            X(t) of every link kept (the whole matching volume
                                      from ``synptv ptv``)
        displacements (N, 3) m        ΔX = X(t + Δt) − X(t)
        in_analysis (N,) bool         X(t) inside the analysis volume
        outlier (N,) bool             failed the normalised median test (not in statistics)
        offsets (M + 1,)              rows offsets[i]:offsets[i+1] are snapshot snapshot_ids[i]
                                      (the five above only when the links are kept)
        snapshot_ids (M,)             snapshots kept
        processed (S,)                snapshots processed (kept or skipped)
        detections (S, 2, C)          per snapshot, frame (a, b) and camera
        matches (S, 2)                per snapshot and frame
        links (S,)                    per snapshot
    /positions                the matched points of every frame measured, one row each
                              (absent when the result has none), the layout
                              ``synptv score`` reads:
        dt (N,), snapshot (N,)        Δt index k and snapshot m
        frame (N,) "a" | "b"          frame a (t) or b (t + Δt)
        x, y, z (N,) m                the point, in the calibration's frame
    /tracks                   the tracks through every frame of a time-resolved recording
                              (``synptv ptv --tracks``; absent otherwise), one row per
                              matched point, sorted by track then frame; attrs frame_rate
                              (Hz), radius and predicted_radius (m, the search radii),
                              gap (missed frames a track may close)
        track (K,)                    track id, 0 … T − 1 (every point is in one track)
        frame (K,), time (K,) s       frame number n and n / frame_rate
        x, y, z (K,) m                the point, in the calibration's frame
        frames/number (F,)            the frames tracked, consecutive
        frames/detections (F, C)      particles detected per frame and camera
        frames/matches (F,)           matched points per frame
    /statistics               attrs: errors, method, kolmogorov_c2, analysis_volume
        dt (K,) s, dt_index (K,)      Δt the statistics use
        r (B,) m, r_edges (B + 1,) m
        s2, se_s2 (B,) m²/s²          noise-free S2 (multi-Δt fit)
        noise, se_noise (B,) m²       c2 = N(r)
        chi2_dof (B,), fitted (B,) bool
        raw_s2, se_raw_s2 (B, K) m²/s²  ⟨q⟩_k/Δt_k²
        q (B, K) m²                   ⟨q⟩_k
        n_pairs (B, K)
        epsilon, se_epsilon (B,) m²/s³             (S2/C2)^{3/2}/r
        epsilon_paper_caption (B,) m²/s³           S2^{3/2}/r (no C2)
        plateau                      attrs: epsilon, se_epsilon, epsilon_paper_caption,
                                     r_min, r_max, method, n_bins (absent if none)
        population                   with a shared first frame, the particles of S2:
                                     positions (N, 3) m (X(t)), offsets (S + 1,),
                                     snapshot_ids (S,); attrs trajectory_outliers
        subsets/<name>               used (K,), s2, se_s2, noise, epsilon (B,); plateau attrs
        mean_displacement            dt (K,), mean, se (K, 3) m, count (K,);
                                     velocity, se_velocity (3,) m/s; offset, se_offset,
                                     se_offset_scaled (× Birge ratio) (3,) m; chi2_dof (3,)
        eulerian                     cell_centres (G, 3) m, valid (G,), variance (G, 3) m²/s²,
                                     noise (G, 3) m², mean_velocity (G, 3) m/s,
                                     offset (G, 3) m; attrs u_prime, se_u_prime (m/s),
                                     position_noise (3,) m

``summary.json``: :func:`summary` (SI units; NaN written as null). :func:`load_runs`
reads the links back, so the statistics can be computed again (other bins, other Δt).
``tracks.csv`` (:func:`ptv.pipeline.track_csv.save_tracks_csv`): the rows of ``/tracks``
as text, with the header ``track,frame,time_s,x,y,z`` (x, y, z in m).

Files are written under a temporary name in the target folder and renamed.
"""

import json
import logging
import os
from pathlib import Path

import h5py
import numpy as np

from ptv.pipeline.double_frame import MatchedPoints, PtvResult, ambiguity_message
from ptv.pipeline.options import radius_at
from ptv.pipeline.track_csv import temporary_path
from ptv.stats.dissipation import Plateau
from ptv.stats.links import RunParticles
from ptv.stats.mean_displacement import MeanDisplacement
from ptv.stats.run_statistics import PtvStatistics
from ptv.tracking.linking import RecordingTracks

__all__ = [
    "FORMAT_NAME",
    "FORMAT_VERSION",
    "load_runs",
    "save_results",
    "statistics_summary",
    "summary",
    "tracks_summary",
]

log = logging.getLogger(__name__)

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


def _plateau_dict(plateau: Plateau | None) -> dict | None:
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


def _settings_dict(result: PtvResult) -> dict:
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
    :attr:`~ptv.pipeline.frames.ImageDetector.warnings`, :func:`thin_data_warnings`
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
        "settings": _settings_dict(result),
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
        entry = {"dt": [float(v) for v in st.dt[sub.used]], "plateau": _plateau_dict(sub.plateau)}
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
            "plateau": _plateau_dict(st.plateau),
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


def _link_radius(run: RunParticles, result: PtvResult) -> float | None:
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
        "link_radius": _link_radius(run, result),
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


def _put(group: h5py.Group, name: str, data, units: str | None = None) -> None:
    ds = group.create_dataset(name, data=np.asarray(data))
    if units is not None:
        ds.attrs["units"] = units


def _put_plateau(group: h5py.Group, plateau: Plateau | None) -> None:
    if plateau is None:
        return
    g = group.create_group("plateau")
    for key, value in _plateau_dict(plateau).items():
        g.attrs[key] = np.nan if value is None else value
    g.attrs["units"] = "epsilon: m^2/s^3; r_min, r_max: m"


def _put_matched(group: h5py.Group, matched: MatchedPoints) -> None:
    """The matched points as the columns of ``/positions`` (module docstring)."""
    _put(group, "dt", matched.k, "dt index")
    _put(group, "snapshot", matched.snapshot, "snapshot index")
    _put(group, "frame", np.array([b"a", b"b"], dtype="S1")[matched.frame])
    for axis, column in zip("xyz", matched.positions.T, strict=True):
        _put(group, axis, column, "m")


def _put_tracks(group: h5py.Group, recording: RecordingTracks) -> None:
    """The tracks of a recording in ``/tracks`` (module docstring)."""
    group.attrs["frame_rate"] = recording.frame_rate
    group.attrs["radius"] = recording.radius
    group.attrs["predicted_radius"] = recording.predicted_radius
    group.attrs["gap"] = recording.gap
    group.attrs["joins"] = recording.joins
    if recording.miss_noise is not None:
        group.attrs["miss_noise"] = recording.miss_noise
    group.attrs["units"] = "frame_rate: Hz; radius, predicted_radius: m"
    _put(group, "track", recording.tracks.track, "track id")
    _put(group, "frame", recording.frame_number, "frame number")
    _put(group, "time", recording.time, "s")
    for axis, column in zip("xyz", recording.tracks.positions.T, strict=True):
        _put(group, axis, column, "m")
    frames = group.create_group("frames")
    _put(frames, "number", recording.numbers, "frame number")
    _put(frames, "detections", recording.detections, "count (frame, camera)")
    _put(frames, "matches", recording.matches, "count")


def _write_h5(path: Path, result: PtvResult, calibration: str | None, links: bool) -> None:
    with h5py.File(path, "w") as f:
        f.attrs["format"] = FORMAT_NAME
        f.attrs["format_version"] = FORMAT_VERSION
        f.attrs["dataset"] = str(result.source.folder)
        f.attrs["calibration"] = calibration or ""
        f.attrs["cameras"] = json.dumps(list(result.cameras))
        f.attrs["settings"] = json.dumps(_settings_dict(result))
        for run in result.runs:
            g = f.create_group(f"particles/dt{run.k}")
            g.attrs["dt"] = run.dt
            radius = _link_radius(run, result)
            g.attrs["link_radius"] = np.nan if radius is None else radius
            g.attrs["links_kept"] = links
            if links:
                _put(g, "positions", run.positions, "m")
                _put(g, "displacements", run.displacements, "m")
                _put(g, "in_analysis", run.in_analysis)
                _put(g, "outlier", run.outlier)
                _put(g, "offsets", run.offsets, "row index")
            _put(g, "snapshot_ids", run.snapshot_ids)
            _put(g, "processed", run.processed)
            _put(g, "detections", run.detections, "count (snapshot, frame a/b, camera)")
            _put(g, "matches", run.matches, "count (snapshot, frame a/b)")
            _put(g, "links", run.links, "count")
        if result.matched is not None:
            _put_matched(f.create_group("positions"), result.matched)
        if result.recording is not None:
            _put_tracks(f.create_group("tracks"), result.recording)
        if result.statistics is not None:
            _put_statistics(f.create_group("statistics"), result)


def _put_statistics(s: h5py.Group, result: PtvResult) -> None:
    """The statistics of a run in the ``/statistics`` group (module docstring)."""
    st = result.statistics
    sf = st.structure
    s.attrs["errors"] = st.errors
    s.attrs["method"] = sf.method
    s.attrs["kolmogorov_c2"] = st.profile.kolmogorov_c2
    s.attrs["analysis_volume"] = np.asarray(result.settings.statistics.analysis_volume)
    _put(s, "dt", st.dt, "s")
    _put(s, "dt_index", st.dt_index)
    _put(s, "n_snapshots", st.n_snapshots)
    _put(s, "r", sf.r, "m")
    _put(s, "r_edges", st.bins.edges, "m")
    _put(s, "s2", sf.s2, "m^2/s^2")
    _put(s, "se_s2", sf.se_s2, "m^2/s^2")
    _put(s, "noise", sf.noise, "m^2")
    _put(s, "se_noise", sf.se_noise, "m^2")
    _put(s, "chi2_dof", sf.chi2_dof)
    _put(s, "fitted", sf.fitted)
    _put(s, "raw_s2", sf.raw_s2, "m^2/s^2")
    _put(s, "se_raw_s2", sf.se_raw_s2, "m^2/s^2")
    _put(s, "q", sf.raw_s2 * st.dt**2, "m^2")
    _put(s, "n_pairs", sf.n_pairs, "pairs")
    _put(s, "epsilon", st.profile.epsilon, "m^2/s^3")
    _put(s, "se_epsilon", st.profile.se_epsilon, "m^2/s^3")
    _put(s, "epsilon_paper_caption", st.profile.epsilon_paper_caption, "m^2/s^3")
    _put_plateau(s, st.plateau)
    if st.population is not None:
        g = s.create_group("population")
        g.attrs["trajectory_outliers"] = st.population.trajectory_outliers
        sizes = [len(x) for x in st.population.positions]
        _put(g, "snapshot_ids", st.population.snapshot_ids)
        _put(g, "offsets", np.concatenate([[0], np.cumsum(sizes)]), "row index")
        positions = st.population.positions
        _put(g, "positions", np.concatenate(positions) if positions else np.empty((0, 3)), "m")
    for name, sub in st.subsets.items():
        g = s.create_group(f"subsets/{name}")
        _put(g, "used", sub.used)
        _put(g, "s2", sub.structure.s2, "m^2/s^2")
        _put(g, "se_s2", sub.structure.se_s2, "m^2/s^2")
        _put(g, "noise", sub.structure.noise, "m^2")
        _put(g, "epsilon", sub.profile.epsilon, "m^2/s^3")
        _put_plateau(g, sub.plateau)
    md = st.mean_displacement
    g = s.create_group("mean_displacement")
    _put(g, "dt", md.dt, "s")
    _put(g, "mean", md.mean, "m")
    _put(g, "se", md.se, "m")
    _put(g, "count", md.count, "links")
    _put(g, "velocity", md.fit.c1, "m/s")
    _put(g, "se_velocity", md.fit.se_c1, "m/s")
    _put(g, "offset", md.fit.c2, "m")
    _put(g, "se_offset", md.fit.se_c2, "m")
    _put(g, "se_offset_scaled", md.se_offset_scaled, "m")
    _put(g, "chi2_dof", md.fit.chi2_dof)
    g = s.create_group("eulerian")
    _put(g, "cell_centres", st.grid.centres, "m")
    _put(g, "valid", st.eulerian.valid)
    _put(g, "variance", st.eulerian.variance, "m^2/s^2")
    _put(g, "noise", st.eulerian.noise, "m^2")
    _put(g, "mean_velocity", st.eulerian.mean_velocity, "m/s")
    _put(g, "offset", st.eulerian.offset, "m")
    up = st.u_prime
    g.attrs["u_prime"] = np.nan if up is None else up.value
    g.attrs["se_u_prime"] = np.nan if up is None else up.se
    g.attrs["position_noise"] = st.position_noise
    g.attrs["units"] = "u_prime, se_u_prime: m/s; position_noise: m"


def save_results(
    result: PtvResult,
    folder: str | os.PathLike,
    *,
    calibration: str | None = None,
    links: bool = True,
) -> tuple[Path, Path]:
    """Write ``results.h5`` and ``summary.json`` into ``folder`` (created if needed).

    Parameters
    ----------
    result : PtvResult
        What :func:`ptv.pipeline.double_frame.run_pipeline` returned.
    folder : path-like
        Output folder.
    calibration : str, optional
        The calibration file used, recorded in both files.
    links : bool
        Write every link's X(t) and ΔX (False: only the counts and the statistics, for
        runs whose link tables would take gigabytes).

    Returns
    -------
    (Path, Path)
        The two files.

    Examples
    --------
    A dataset folder written here: two cameras (Tsai, ±20° about Y) image 12 particles
    moving at 0.2 m/s along X, one frame pair at each of Δt = 1 and 2 ms.
    Its positions and links, saved:

    >>> import json, pathlib, tempfile
    >>> import numpy as np
    >>> import tifffile
    >>> import ptv
    >>> from scipy.spatial.transform import Rotation
    >>> def camera(angle):  # 0.5 m from the origin, turned ``angle`` degrees about Y
    ...     turn = Rotation.from_euler("y", angle, degrees=True).as_matrix()
    ...     return ptv.TsaiCalibration(turn, [0, 0, 0.5], focal_length=0.05, kappa1=0.0,
    ...                                sx=1.0, principal_point=(63.5, 63.5),
    ...                                pixel_size=(1e-5, 1e-5))
    >>> rig = {"left": camera(-20), "right": camera(20)}
    >>> rows, cols = np.mgrid[:128, :128]
    >>> def image(points, camera):  # spots of σ = 1 px and 2000 DN on 100 ± 2 DN
    ...     xy = camera.project(points)
    ...     spots = [np.exp(-((cols - x) ** 2 + (rows - y) ** 2) / 2) for x, y in xy]
    ...     noise = np.random.default_rng(0).normal(0, 2, rows.shape)
    ...     return (100 + 2000 * np.sum(spots, axis=0) + noise).astype(np.uint16)
    >>> tmp = tempfile.TemporaryDirectory()
    >>> folder = pathlib.Path(tmp.name)
    >>> x = np.random.default_rng(2).uniform(-4e-3, 4e-3, (12, 3))  # particles at t, m
    >>> u = np.array([0.2, 0.0, 0.0])  # their velocity, m/s
    >>> spec = {"cameras": {name: {"image_size": [128, 128]} for name in rig},
    ...         "dt": [1e-3, 2e-3], "frames_per_dt": 1,
    ...         "particle_images": "{camera}_{k}_{m}_{a|b}.tif"}
    >>> _ = (folder / "experiment.json").write_text(json.dumps(spec))
    >>> for k, dt in enumerate(spec["dt"]):  # one frame pair per Δt
    ...     for name, cam in rig.items():
    ...         tifffile.imwrite(folder / f"{name}_{k}_0_a.tif", image(x, cam))
    ...         tifffile.imwrite(folder / f"{name}_{k}_0_b.tif", image(x + u * dt, cam))
    >>> _ = ptv.save_calibrations(folder / "tsai.h5", rig)
    >>> settings = ptv.PipelineSettings(volume=((-6e-3,) * 3, (6e-3,) * 3),
    ...                                 tolerance=1e-4, max_speed=0.5)
    >>> detector = ptv.ImageDetector(ptv.open_dataset(folder))
    >>> calibrations = ptv.load_calibrations(folder / "tsai.h5")
    >>> result = ptv.run_pipeline(detector, calibrations, settings, statistics=False)
    >>> paths = ptv.save_results(result, folder / "out")
    >>> [path.name for path in paths]
    ['results.h5', 'summary.json']
    >>> json.loads(paths[1].read_text())["dt"]  # s
    [0.001, 0.002]
    >>> tmp.cleanup()
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    h5_path, json_path = folder / "results.h5", folder / "summary.json"
    text = json.dumps(summary(result, calibration=calibration), indent=2, allow_nan=False)
    tmp_h5, tmp_json = temporary_path(folder, h5_path.name), temporary_path(folder, json_path.name)
    try:
        _write_h5(tmp_h5, result, calibration, links)
        tmp_json.write_text(text + "\n")
        os.replace(tmp_h5, h5_path)
        os.replace(tmp_json, json_path)
    finally:
        tmp_h5.unlink(missing_ok=True)
        tmp_json.unlink(missing_ok=True)
    log.info("results written to %s and %s", h5_path, json_path)
    return h5_path, json_path


def load_runs(path: str | os.PathLike) -> list[RunParticles]:
    """The links of every Δt saved in a results.h5, as the statistics take them.

    Parameters
    ----------
    path : path-like
        A ``results.h5`` written with its links (:func:`save_results`, ``links=True``).

    Returns
    -------
    list of RunParticles
        One per Δt, in the order of the file's ``dt<k>`` groups.

    Raises
    ------
    ValueError
        Not a results file, or one written without its links.

    Examples
    --------
    A dataset folder written here: two cameras (Tsai, ±20° about Y) image 12 particles
    moving at 0.2 m/s along X, one frame pair at each of Δt = 1 and 2 ms.
    Its links, saved and read back as :func:`ptv.compute_statistics` takes them:

    >>> import json, pathlib, tempfile
    >>> import numpy as np
    >>> import tifffile
    >>> import ptv
    >>> from scipy.spatial.transform import Rotation
    >>> def camera(angle):  # 0.5 m from the origin, turned ``angle`` degrees about Y
    ...     turn = Rotation.from_euler("y", angle, degrees=True).as_matrix()
    ...     return ptv.TsaiCalibration(turn, [0, 0, 0.5], focal_length=0.05, kappa1=0.0,
    ...                                sx=1.0, principal_point=(63.5, 63.5),
    ...                                pixel_size=(1e-5, 1e-5))
    >>> rig = {"left": camera(-20), "right": camera(20)}
    >>> rows, cols = np.mgrid[:128, :128]
    >>> def image(points, camera):  # spots of σ = 1 px and 2000 DN on 100 ± 2 DN
    ...     xy = camera.project(points)
    ...     spots = [np.exp(-((cols - x) ** 2 + (rows - y) ** 2) / 2) for x, y in xy]
    ...     noise = np.random.default_rng(0).normal(0, 2, rows.shape)
    ...     return (100 + 2000 * np.sum(spots, axis=0) + noise).astype(np.uint16)
    >>> tmp = tempfile.TemporaryDirectory()
    >>> folder = pathlib.Path(tmp.name)
    >>> x = np.random.default_rng(2).uniform(-4e-3, 4e-3, (12, 3))  # particles at t, m
    >>> u = np.array([0.2, 0.0, 0.0])  # their velocity, m/s
    >>> spec = {"cameras": {name: {"image_size": [128, 128]} for name in rig},
    ...         "dt": [1e-3, 2e-3], "frames_per_dt": 1,
    ...         "particle_images": "{camera}_{k}_{m}_{a|b}.tif"}
    >>> _ = (folder / "experiment.json").write_text(json.dumps(spec))
    >>> for k, dt in enumerate(spec["dt"]):  # one frame pair per Δt
    ...     for name, cam in rig.items():
    ...         tifffile.imwrite(folder / f"{name}_{k}_0_a.tif", image(x, cam))
    ...         tifffile.imwrite(folder / f"{name}_{k}_0_b.tif", image(x + u * dt, cam))
    >>> _ = ptv.save_calibrations(folder / "tsai.h5", rig)
    >>> settings = ptv.PipelineSettings(volume=((-6e-3,) * 3, (6e-3,) * 3),
    ...                                 tolerance=1e-4, max_speed=0.5)
    >>> detector = ptv.ImageDetector(ptv.open_dataset(folder))
    >>> calibrations = ptv.load_calibrations(folder / "tsai.h5")
    >>> result = ptv.run_pipeline(detector, calibrations, settings, statistics=False)
    >>> h5, _ = ptv.save_results(result, folder / "out")
    >>> runs = ptv.load_runs(h5)
    >>> [(run.k, run.dt, len(run.positions)) for run in runs]
    [(0, 0.001, 12), (1, 0.002, 12)]
    >>> all(np.array_equal(a.displacements, b.displacements) for a, b in zip(runs, result.runs))
    True
    >>> tmp.cleanup()
    """
    with h5py.File(path, "r") as f:
        if f.attrs.get("format") != FORMAT_NAME:
            raise ValueError(f"{path}: not a {FORMAT_NAME} file")
        groups = sorted(f["particles"], key=lambda name: int(name.removeprefix("dt")))
        runs = []
        for name in groups:
            g = f["particles"][name]
            if not g.attrs.get("links_kept", True) or "positions" not in g:
                raise ValueError(f"{path}: written without its links (links_kept false)")
            runs.append(
                RunParticles(
                    k=int(name.removeprefix("dt")),
                    dt=float(g.attrs["dt"]),
                    **{
                        key: g[key][:]
                        for key in (
                            "positions",
                            "displacements",
                            "offsets",
                            "snapshot_ids",
                            "detections",
                            "matches",
                            "links",
                            "processed",
                            "in_analysis",
                            "outlier",
                        )
                    },
                )
            )
    return runs
