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

``summary.json``: :func:`ptv.pipeline.summary.summary` (SI units; NaN as null). :func:`load_runs`
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

from ptv.pipeline.double_frame import MatchedPoints, PtvResult
from ptv.pipeline.summary import (
    FORMAT_NAME,
    FORMAT_VERSION,
    plateau_dict,
    recorded_link_radius,
    settings_dict,
    summary,
)
from ptv.pipeline.track_csv import temporary_path
from ptv.stats.dissipation import Plateau
from ptv.stats.links import RunParticles
from ptv.tracking.linking import RecordingTracks

__all__ = ["FORMAT_NAME", "FORMAT_VERSION", "load_runs", "save_results"]

log = logging.getLogger(__name__)


def _put(group: h5py.Group, name: str, data, units: str | None = None) -> None:
    ds = group.create_dataset(name, data=np.asarray(data))
    if units is not None:
        ds.attrs["units"] = units


def _put_plateau(group: h5py.Group, plateau: Plateau | None) -> None:
    if plateau is None:
        return
    g = group.create_group("plateau")
    for key, value in plateau_dict(plateau).items():
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
        f.attrs["settings"] = json.dumps(settings_dict(result))
        for run in result.runs:
            g = f.create_group(f"particles/dt{run.k}")
            g.attrs["dt"] = run.dt
            radius = recorded_link_radius(run, result)
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
    Its positions and links, saved and read back:

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
    >>> runs = ptv.load_runs(paths[0])  # the links back, as compute_statistics takes them
    >>> [(run.k, run.dt, len(run.positions)) for run in runs]
    [(0, 0.001, 12), (1, 0.002, 12)]
    >>> all(np.array_equal(a.displacements, b.displacements) for a, b in zip(runs, result.runs))
    True
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
    :func:`save_results`'s example reads its links back. A file that is not a results
    file is refused:

    >>> import pathlib, tempfile
    >>> import h5py
    >>> import ptv
    >>> tmp = tempfile.TemporaryDirectory()
    >>> other = pathlib.Path(tmp.name) / "other.h5"
    >>> h5py.File(other, "w").close()
    >>> ptv.load_runs(other)
    Traceback (most recent call last):
    ...
    ValueError: ...
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
