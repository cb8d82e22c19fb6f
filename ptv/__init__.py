"""The PTV stack: detection, calibration, triangulation, matching, tracking, statistics.

``ptv`` never imports ``simulator``: it sees only what a real experiment gives
(images, the nominal target description and the Δt values).

The names below are the public API, importable as ``ptv.<name>``; each is loaded on
first use, so ``import ptv`` stays cheap. Units are SI (m, s, m/s) except pixels (px,
x = column, y = row, (0, 0) the centre of the top-left pixel) and grey levels (DN).

Calibration (docs/calibration.md)
    PlateDescription      the nominal dot plate: pitch, dot sizes, marks, extent (m)
    read_csv_dots         one plate position's dots from an ``i,j,x,y`` CSV list
    read_openptv_dots     one plate position's dots from OpenPTV's ``.crd``/``.fix`` files
    PlaneObservation      dots of one traverse plane: Z, pixels (N, 2), plate (X, Y) (N, 2)
    CameraSheet           data-sheet values: image size, pixel pitch, lens focal length
    calibrate             one camera by method name: model-free, tsai, pinhole, soloff
    calibrate_model_free  the model-free pixel → line calibration (the paper's method)
    calibrate_tsai        the Tsai (1987) baseline: pinhole with one radial term
    calibrate_pinhole     the OpenCV pinhole baseline: f_x, f_y, principal point, k1 k2 p1 p2
    TsaiCalibration       a Tsai camera, fitted or built from known parameters
    save_calibrations     write a rig's calibrations to one HDF5 file
    load_calibrations     read them back: camera name → calibration
    CameraModel           the protocol every calibration offers: pixel_to_ray, project
    Rays                  N straight rays: origins (N, 3), m, and unit directions (N, 3)

Detection (docs/ptv.md §1)
    detect_particles      particles on one image, centres to sub-pixel accuracy
    Detections            what it returns: centres (N, 2) px, intensity, peak, size, flags
    DetectionFlag         the bits of Detections.flags: OVERLAP, ELONGATED, SATURATED, ...
    DetectorSettings      detection on a dataset's images: threshold, background, diameter

Triangulation (docs/ptv.md §2)
    triangulate_rays      least-squares points of C rays each (ptv.triangulate.closest_points)
    triangulate_pixels    points from corresponding pixels of calibrated cameras
                          (ptv.triangulate.triangulate)

Stereo matching (docs/ptv.md §3)
    match                 which detections of C cameras image the same particle

Tracking (docs/ptv.md §4, docs/lagrangian.md)
    search_radius         the Δt-scaled link radius k_v u′ Δt + k_b σ_b, m
    link                  particles of two frames linked one-to-one (double frame)
    track_frames          particles of consecutive frames linked into tracks
    fit_tracks            position, velocity, acceleration of track points, fixed window
    fit_recording         tracks fitted as ``synptv ptv --tracks`` fits them (noise,
                          outliers, window chosen from the data)
    TrackFitSettings      its options: fit window, fewest points

Statistics (docs/statistics.md)
    LogBins               log-spaced separation bins, m
    double_frame_sums     pair sums per snapshot, one run of frame pairs per Δt
    time_resolved_sums    pair sums per snapshot, the same particles at every Δt
    structure_function    S2(r) by the multi-Δt fit ⟨q⟩ = S2 Δt² + N, bootstrap errors
    fit_multi_dt          the line y = c1 Δt² + c2 in every bin
    RunParticles          the links of one Δt, X(t) and ΔX: what the statistics take
    StatisticsSettings    analysis volume, bins, plateau, C2, bootstrap
    compute_statistics    S2(r), ε(r), u′ and the rest from the runs of every Δt

Datasets and the pipeline (docs/experiment.md, docs/ptv.md §5–§7)
    read_experiment       a dataset folder's experiment.json, checked against its schema
    open_dataset          a dataset folder: cameras, Δt, frame pairs, image files
    read_image            a grey TIFF or PNG image, (H, W), DN
    ImageDetector         the detections of a dataset's images, frame by frame
    PipelineSettings      matching volume and tolerance, linking, median test, statistics
    run_pipeline          detections → matches → links → statistics for a whole dataset
    run_recording         the same for a time-resolved recording, with its tracks
    PtvSettings           every option of ``synptv ptv``: detection, pipeline, tracks
    load_settings         PtvSettings from a TOML file
    save_results          results.h5 and summary.json of a run
    load_runs             the links of every Δt back from a results.h5

A dataset folder from Python (what ``synptv ptv --positions-only`` computes)::

    import ptv

    dataset = ptv.open_dataset("my-dataset")
    calibrations = ptv.load_calibrations("my-dataset/calibrations/model-free.h5")
    detector = ptv.ImageDetector(dataset, ptv.DetectorSettings(threshold_sigmas=6))
    volume = ((-0.05, -0.05, -0.005), (0.05, 0.05, 0.005))  # matching box, m
    settings = ptv.PipelineSettings(volume=volume)
    result = ptv.run_pipeline(detector, calibrations, settings, statistics=False)
    for run in result.runs:  # one per Δt: X(t) and ΔX of every link, m
        print(run.dt, run.positions.shape, run.displacements.shape)

Left out, the matching volume is the paper's sheet (:class:`PipelineSettings`), not the
volume the calibration file records, which ``synptv ptv`` takes.

Every name's docstring has examples on small inputs; the modules hold the rest of the
stack (``ptv.reconstruct``: iterative particle reconstruction on dense images).
"""

from importlib import import_module

#: Public name → (module, name there). Kept out of the namespace until first use: the
#: stack imports numba, OpenCV, h5py and SciPy, over a second together.
_EXPORTS = {
    # calibration
    "PlateDescription": ("ptv.calibration.plate", "PlateDescription"),
    "read_csv_dots": ("ptv.calibration.dot_lists", "read_csv_dots"),
    "read_openptv_dots": ("ptv.calibration.dot_lists", "read_openptv_dots"),
    "PlaneObservation": ("ptv.calibration.observations", "PlaneObservation"),
    "CameraSheet": ("ptv.calibration.methods", "CameraSheet"),
    "calibrate": ("ptv.calibration.methods", "calibrate"),
    "calibrate_model_free": ("ptv.calibration.model_free", "calibrate_model_free"),
    "calibrate_tsai": ("ptv.calibration.tsai", "calibrate_tsai"),
    "calibrate_pinhole": ("ptv.calibration.pinhole_fit", "calibrate_pinhole"),
    "TsaiCalibration": ("ptv.calibration.tsai", "TsaiCalibration"),
    "save_calibrations": ("ptv.calibration.io", "save_calibrations"),
    "load_calibrations": ("ptv.calibration.io", "load_calibrations"),
    "CameraModel": ("ptv.camera_model", "CameraModel"),
    "Rays": ("ptv.rays", "Rays"),
    # detection
    "detect_particles": ("ptv.detect.locate", "detect_particles"),
    "Detections": ("ptv.detect.detections", "Detections"),
    "DetectionFlag": ("ptv.detect.detections", "DetectionFlag"),
    "DetectorSettings": ("ptv.settings", "DetectorSettings"),
    # triangulation: ``ptv.triangulate`` is the module, so the functions take other names
    "triangulate_rays": ("ptv.triangulate", "closest_points"),
    "triangulate_pixels": ("ptv.triangulate", "triangulate"),
    # stereo matching
    "match": ("ptv.matching.stereo", "match"),
    # tracking
    "search_radius": ("ptv.tracking.linking", "search_radius"),
    "link": ("ptv.tracking.linking", "link"),
    "track_frames": ("ptv.tracking.linking", "track_frames"),
    "fit_tracks": ("ptv.tracking.fitting", "fit_tracks"),
    "fit_recording": ("ptv.pipeline.track_fit", "fit_recording"),
    "TrackFitSettings": ("ptv.settings", "TrackFitSettings"),
    # statistics
    "LogBins": ("ptv.bins", "LogBins"),
    "double_frame_sums": ("ptv.stats.structure", "double_frame_sums"),
    "time_resolved_sums": ("ptv.stats.structure", "time_resolved_sums"),
    "structure_function": ("ptv.stats.structure", "structure_function"),
    "fit_multi_dt": ("ptv.stats.multidt", "fit_multi_dt"),
    "RunParticles": ("ptv.stats.links", "RunParticles"),
    "StatisticsSettings": ("ptv.settings", "StatisticsSettings"),
    "compute_statistics": ("ptv.stats.run_statistics", "compute_statistics"),
    # datasets and the pipeline
    "read_experiment": ("ptv.io.experiment_file", "read_experiment"),
    "open_dataset": ("ptv.io.dataset", "open_dataset"),
    "read_image": ("ptv.io.images", "read_image"),
    "ImageDetector": ("ptv.detect.frames", "ImageDetector"),
    "PipelineSettings": ("ptv.settings", "PipelineSettings"),
    "run_pipeline": ("ptv.pipeline.double_frame", "run_pipeline"),
    "run_recording": ("ptv.pipeline.time_resolved", "run_recording"),
    "PtvSettings": ("ptv.settings", "PtvSettings"),
    "load_settings": ("ptv.pipeline.settings_file", "load_settings"),
    "save_results": ("ptv.pipeline.results", "save_results"),
    "load_runs": ("ptv.pipeline.results", "load_runs"),
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
