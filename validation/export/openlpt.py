"""A rendered dataset in the layout OpenLPT 2.2.4 (pip ``openlpt``; C++ core ``pyopenlpt``)
reads.

Layout of the export folder (OpenLPT's units: mm in the world, px on the images;
docs/export.md §6)::

    README.txt                          what each file is, the cameras' errors, what was
                                        chosen or guessed
    camFile/<camera>.txt                PINHOLE fitted to the plate dots, what OpenLPT's
                                        plate calibration gives (no refraction, no tilt)
    camFileTrue/<camera>.txt            the true camera as far as OpenLPT's models hold it
                                        (a POLYNOMIAL fitted to its exact projection)
    imgFile/dt<k>/<camera>/<mmmmmm>_<a|b>.tif   particle images of snapshot m at Δt_k,
                                        less the camera's background level (16-bit,
                                        uncompressed TIFF)
    imgFile/dt<k>/<camera>ImageNames.txt        image list of a camera and Δt_k: frame a
                                        of snapshot m on line 2m, frame b on 2m + 1
    config_dt<k>.txt                    OpenLPT's configuration of Δt_k with camFile/
                                        (config.txt is config_dt0.txt)
    config_true_dt<k>.txt               the same with camFileTrue/
    tracerConfig_dt<k>.txt              its tracer (STB, shake, IPR, 2-D peak) settings
    frames.csv                          dt,snapshot,frame,frame_index of every exposure
    run_ipr.py                          OpenLPT's IPR on every frame of a configuration
                                        (:mod:`validation.export.openlpt_driver`)

The cameras are :mod:`validation.export.openlpt_cameras`.
"""

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import tifffile

from ptv.io.images import read_image
from ptv.reconstruct import background_level
from validation.export.openlpt_cameras import (
    MM,
    POLYNOMIAL_TARGET_PX,
    VOLUME_MARGIN_VOXELS,
    CameraFile,
    ViewVolume,
    plate_calibrations,
    plate_camera_files,
    true_camera_files,
    true_images,
    view_volume,
)
from validation.export.openlpt_driver import DRIVER
from validation.export.source import ExportSource

#: OpenLPT estimates its OTF from the first five frames of each image list.
OTF_FRAMES = 5
#: The 2-D peak threshold, at least this many background noise σ above the
#: (subtracted) background, ...
PEAK_SIGMAS = 6.0
#: ... and at least this fraction of a typical particle image's peak: OpenLPT adds the
#: peaks of its residual images above the threshold as particles, and a residual keeps a
#: fair part of a particle's peak where its one-Gaussian OTF misfits the image.
PEAK_FRACTION = 0.3
#: The camera sets written: folder, configuration prefix, output folder prefix.
CAMERA_SETS = (
    ("camFile", "config", "Results/dt"),
    ("camFileTrue", "config_true", "Results/true_dt"),
)


# -- configuration files -----------------------------------------------------------------


@dataclass(frozen=True)
class TracerSettings:
    """The values of OpenLPT's tracer configuration (``tracerConfig.txt``), in its order.

    Lengths in voxels are multiplied by the main configuration's "voxel to mm".

    Attributes
    ----------
    search_radius : float
        Initial phase of STB: radius linking a track to an object, voxel.
    initial_frames : int
        Frames of the initial phase (≥ 4).
    neighbour_spacing : float
        Convergence phase: mean interparticle spacing to find neighbour tracks, voxel.
    shake_width : float
        Shake's first step, voxel.
    field_grid : (int, int, int)
        Grid of the predictive displacement field, points along X, Y, Z.
    field_radius : float
        Predictive field's search radius, voxel.
    ipr_loops : int
        IPR loops on all cameras.
    shake_loops : int
        Shake loops per IPR loop.
    ghost_threshold : float
        Objects fainter than this × the mean intensity are ghosts.
    tolerance_2d : float
        Half-width of the epipolar strips of the stereo matching, px.
    tolerance_3d : float
        Largest triangulation error of a match, voxel.
    reduced_cameras : int
        Cameras left out in the reduced IPR loops.
    reduced_loops : int
        IPR loops per reduced camera combination.
    peak_threshold : int
        Least grey level of a 2-D particle peak, image counts.
    particle_radius : float
        Particle image radius for the residual images and shaking, px.
    """

    search_radius: float = 10.0
    initial_frames: int = 4
    neighbour_spacing: float = 30.0
    shake_width: float = 0.25
    field_grid: tuple[int, int, int] = (21, 21, 21)
    field_radius: float = 25.0
    ipr_loops: int = 4
    shake_loops: int = 4
    ghost_threshold: float = 0.1
    tolerance_2d: float = 0.8
    tolerance_3d: float = 1.0
    reduced_cameras: int = 1
    reduced_loops: int = 2
    peak_threshold: int = 30
    particle_radius: float = 2.0

    def text(self) -> str:
        """The tracer configuration file."""
        nx, ny, nz = self.field_grid
        return f"""######### Initial Phase #########
{self.search_radius:.6g} # Search radius for connecting tracks to objects [voxel]
{self.initial_frames} # Number of frames for initial phase
######### Convergence Phase #########
{self.neighbour_spacing:.6g} # Avg interparticle spacing to identify neighbour tracks [voxel]
######### Shake #########
{self.shake_width:.6g} # shake width [voxel]
######### Predict Field #########
{nx} # xgrid
{ny} # ygrid
{nz} # zgrid
{self.field_radius:.6g} # searchRadius [voxel]
######### IPR #########
{self.ipr_loops} # No. of IPR loop
{self.shake_loops} # No. of Shake loop
{self.ghost_threshold:.6g} # ghost threshold
{self.tolerance_2d:.6g} # 2D tolerance [px]
{self.tolerance_3d:.6g} # 3D tolerance [voxel]
{self.reduced_cameras} # number of reduced camera
{self.reduced_loops} # no. of ipr loops for each reduced camera combination
######### Object Info #########
{self.peak_threshold} # 2D particle finder threshold [counts]
{self.particle_radius:.6g} # Particle radius [px], for residue image and shaking
"""


def config_text(
    *,
    frames: tuple[int, int],
    frame_rate: int,
    cameras: list[tuple[str, int]],
    image_lists: list[str],
    volume: ViewVolume,
    output: str,
    tracer: str,
    threads: int = 0,
) -> str:
    """OpenLPT's main configuration file (``config.txt``), its fields in order.

    Parameters
    ----------
    frames : (int, int)
        First and last frame processed (lines of the image lists, from 0, inclusive).
    frame_rate : int
        Frames per second, Hz (OpenLPT reads an integer).
    cameras : list of (str, int)
        Each camera's file path and the largest grey level of its images.
    image_lists : list of str
        Each camera's image list path.
    volume : ViewVolume
        The view volume and the voxel.
    output : str
        Output folder.
    tracer : str
        Tracer configuration path.
    threads : int
        OpenMP threads (0: as many as cores).

    Returns
    -------
    str
    """
    lo, hi = volume.lower * MM, volume.upper * MM
    box = ",".join(f"{v:.6f}" for pair in zip(lo, hi, strict=True) for v in pair)
    return (
        "\n".join(
            [
                "# Frame Range: [startID,endID] (lines of the image lists, from 0)",
                f"{frames[0]},{frames[1]}",
                "# Frame Rate: [Hz]",
                str(int(frame_rate)),
                "# Number of Threads: (0: use as many as possible)",
                str(threads),
                "# Number of Cameras:",
                str(len(cameras)),
                "# Camera File Path, Max Intensity",
                *(f"{path},{int(top)}" for path, top in cameras),
                "# Image File Path",
                *image_lists,
                "# View Volume: (xmin,xmax,ymin,ymax,zmin,zmax) [mm]",
                box,
                "# Voxel to MM: [mm per voxel]",
                f"{volume.voxel * MM:.9g}",
                "# Output Folder Path:",
                output,
                "# Object Types:",
                "Tracer",
                "# STB Config Files:",
                tracer,
                "# Flag to load previous track files, previous frameID",
                "0,-1",
            ]
        )
        + "\n"
    )


def image_list(paths: list[str], least: int = OTF_FRAMES) -> str:
    """An image list: one path a line, the list repeated until it holds ``least`` lines
    (OpenLPT reads five frames to estimate its OTF, even for fewer)."""
    lines = list(paths)
    while len(lines) < least:
        lines.append(paths[len(lines) % len(paths)])
    return "\n".join(lines) + "\n"


# -- the export --------------------------------------------------------------------------


def frame_index(m: int, frame: str) -> int:
    """The line of a Δt's image list holding frame ``frame`` of snapshot m: 2m (a),
    2m + 1 (b)."""
    return 2 * m + (frame == "b")


def max_intensity(source: ExportSource) -> int:
    """The largest grey level of the images: 2^bit_depth − 1 where experiment.json
    declares it, else the full range of the first image's type."""
    if source.bit_depth is not None:
        return 2**source.bit_depth - 1
    first = read_image(source.frame_path(0, source.cameras[0], 0, "a"))
    return int(np.iinfo(first.dtype).max) if first.dtype.kind in "ui" else 65535


@dataclass(frozen=True)
class ImageLevels:
    """What the export reads off a camera's first image (DN).

    Attributes
    ----------
    background : float
        Background level: the mode of the grey levels
        (:func:`ptv.reconstruct.background_level`, valid in dense images too).
    noise : float
        Background noise σ, from the pixels below the level.
    peak : float
        Typical particle image peak above the background: the median of the local
        maxima (3 × 3) more than :data:`PEAK_SIGMAS` σ above it.
    """

    background: float
    noise: float
    peak: float


def image_levels(image: np.ndarray) -> ImageLevels:
    """The :class:`ImageLevels` of one particle image, shape (H, W)."""
    from scipy.ndimage import maximum_filter

    bg = background_level(image)
    values = np.asarray(image, float)
    above = values - bg.level
    peaks = above[(values == maximum_filter(values, size=3)) & (above > PEAK_SIGMAS * bg.noise)]
    peak = float(np.median(peaks)) if peaks.size else PEAK_SIGMAS * bg.noise
    return ImageLevels(float(bg.level), float(bg.noise), peak)


def tracer_settings(
    source: ExportSource, k: int, volume: ViewVolume, levels: list[ImageLevels]
) -> TracerSettings:
    """The tracer settings of Δt_k: OpenLPT's usual values, with the link radius from the
    flow (max speed × Δt_k in voxels, at least 2) and the 2-D peak threshold
    :func:`peak_threshold` of the cameras' images."""
    step = source.max_speed * source.dataset.dt[k] / volume.voxel
    return TracerSettings(
        search_radius=max(2.0, math.ceil(step)), peak_threshold=peak_threshold(levels)
    )


def peak_threshold(levels: list[ImageLevels]) -> int:
    """OpenLPT's 2-D peak threshold above the subtracted background, DN: the larger of
    :data:`PEAK_FRACTION` × the faintest camera's typical particle peak and
    :data:`PEAK_SIGMAS` × the noisiest camera's background σ."""
    fraction = PEAK_FRACTION * min(v.peak for v in levels)
    return max(1, math.ceil(max(fraction, PEAK_SIGMAS * max(v.noise for v in levels))))


def _image_target(k: int, camera: str, m: int, frame: str) -> str:
    return f"imgFile/dt{k}/{camera}/{m:06d}_{frame}.tif"


def write_openlpt(source: ExportSource, out: Path) -> list[Path]:
    """Write ``source`` in OpenLPT's layout (module docstring) into the folder ``out``.

    Parameters
    ----------
    source : ExportSource
        The checked dataset (frame pairs).
    out : Path
        A folder that does not exist yet.

    Returns
    -------
    list of Path
        The files written.

    Raises
    ------
    ValueError
        A recorded dataset, a camera the plate fit cannot
        calibrate or that images too little of the view volume; raised before anything
        is written.
    """
    if source.recordings:
        raise ValueError(
            f"--dataset {source.folder}: a time-resolved recording; --format openlpt "
            "exports frame pairs only"
        )
    volume = view_volume(source.rig)
    truth = true_images(source.folder, source.cameras)
    sets = [
        plate_camera_files(plate_calibrations(source), truth),
        true_camera_files(source.rig, volume, truth),
    ]
    levels = [image_levels(read_image(source.frame_path(0, c, 0, "a"))) for c in source.cameras]
    offsets = [round(v.background) for v in levels]
    top = max_intensity(source)
    settings = [tracer_settings(source, k, volume, levels) for k in range(source.dataset.n_dt)]
    written = []

    def text(relative: str, content: str) -> None:
        path = out / relative
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(content)
        written.append(path)

    for files, (folder, _, _) in zip(sets, CAMERA_SETS, strict=True):
        for name, cam in zip(source.cameras, files, strict=True):
            text(f"{folder}/{name}.txt", cam.text)
    rows = ["dt,snapshot,frame,frame_index"]
    for k in range(source.dataset.n_dt):
        pairs = [(m, f) for m in range(source.dataset.frames[k]) for f in "ab"]
        rows += [f"{k},{m},{f},{frame_index(m, f)}" for m, f in pairs]
        for name, offset in zip(source.cameras, offsets, strict=True):
            targets = [_image_target(k, name, m, f) for m, f in pairs]
            for (m, f), target in zip(pairs, targets, strict=True):
                _image(source.frame_path(k, name, m, f), out / target, offset)
                written.append(out / target)
            text(f"imgFile/dt{k}/{name}ImageNames.txt", image_list(targets))
        text(f"tracerConfig_dt{k}.txt", settings[k].text())
        for folder, config, results in CAMERA_SETS:
            content = config_text(
                frames=(0, len(pairs) - 1),
                frame_rate=max(1, round(1.0 / source.dataset.dt[k])),
                cameras=[(f"{folder}/{name}.txt", top) for name in source.cameras],
                image_lists=[f"imgFile/dt{k}/{name}ImageNames.txt" for name in source.cameras],
                volume=volume,
                output=f"{results}{k}/",
                tracer=f"tracerConfig_dt{k}.txt",
            )
            text(f"{config}_dt{k}.txt", content)
            if k == 0 and config == "config":
                text("config.txt", content)
    text("frames.csv", "\n".join(rows) + "\n")
    text("run_ipr.py", DRIVER)
    text("README.txt", readme(source, sets, volume, settings, top, levels))
    return written


def _image(source_path: Path, target: Path, level: int) -> None:
    """Write the image as OpenLPT reads it: the grey levels less the camera's background
    level (clipped at 0), in an uncompressed 16-bit TIFF file (OpenLPT's libtiff has no
    Deflate codec, with which synptv writes its TIFFs)."""
    image = read_image(source_path).astype(np.int64) - level
    target.parent.mkdir(parents=True, exist_ok=True)
    tifffile.imwrite(target, np.clip(image, 0, 65535).astype(np.uint16), compression=None)


def _camera_lines(names, files: list[CameraFile]) -> str:
    return "\n".join(
        f"  {name:<8} {f.model:<10} error rms {f.rms_px:.3g} px, max {f.max_px:.3g} px "
        f"over {f.points} particle images; {f.detail}"
        for name, f in zip(names, files, strict=True)
    )


def readme(
    source: ExportSource,
    sets: list[list[CameraFile]],
    volume: ViewVolume,
    settings: list[TracerSettings],
    top: int,
    levels: list[ImageLevels],
) -> str:
    """README.txt of an OpenLPT export: each file, the camera models and their error,
    and every setting that was chosen or guessed."""
    dt = ", ".join(f"dt{k} = {v * 1e3:.6g} ms" for k, v in enumerate(source.dataset.dt))
    lo, hi = volume.lower * MM, volume.upper * MM
    box = ", ".join(f"{a:.3f} .. {b:.3f}" for a, b in zip(lo, hi, strict=True))
    radii = ", ".join(f"dt{k}: {s.search_radius:g}" for k, s in enumerate(settings))
    s0 = settings[0]
    bg = ", ".join(
        f"{c} {round(v.background)}" for c, v in zip(source.cameras, levels, strict=True)
    )
    noise = max(v.noise for v in levels)
    peak = min(v.peak for v in levels)
    return f"""OpenLPT export of the synptv dataset {source.folder}
(written by `synptv export --format openlpt`; docs/export.md §6 of synptv). For OpenLPT
2.2.4 (pip install openlpt opencv-python, in its own environment). Run from this folder:
OpenLPT reads a configuration's paths relative to the working folder.

Units: mm in every OpenLPT file (positions, view volume, voxel size); image coordinates
in px, x = column, y = row, (0, 0) the centre of the top-left pixel (OpenLPT's
convention too). OpenLPT's 3-D results are in mm in the dataset's world frame: divide
by 1000 to score them with `synptv score` (metres); run_ipr.py --positions does it.

Cameras: {", ".join(source.cameras)}. Time separations: {dt}.
Snapshot m of every dt is a pair of exposures, frame a at t and frame b at t + dt; the
pairs are independent of each other. Each dt has its own image lists, in which frame a
of snapshot m is line 2m and frame b line 2m + 1 (OpenLPT's frame numbers, from 0);
frames.csv lists them all.

FILES
  camFile/<camera>.txt          PINHOLE camera fitted to the plate dots (below)
  camFileTrue/<camera>.txt      the true camera as a POLYNOMIAL (below)
  imgFile/dt<k>/<camera>/<mmmmmm>_<a|b>.tif   particle images: the rendered grey
                                levels less the camera's background level,
                                uncompressed 16-bit TIFF
  imgFile/dt<k>/<camera>ImageNames.txt        image list of one camera at dt<k>
  config_dt<k>.txt              OpenLPT's configuration for dt<k> with camFile/:
                                frames 0 .. 2M - 1 of its lists, the cameras, the
                                lists, view volume, voxel, output Results/dt<k>/
  config.txt                    = config_dt0.txt
  config_true_dt<k>.txt         the same with camFileTrue/, output Results/true_dt<k>/
  tracerConfig_dt<k>.txt        tracer settings for dt<k> (STB, shake, IPR, 2-D peaks)
  frames.csv                    dt,snapshot,frame,frame_index of every exposure
  run_ipr.py                    OpenLPT's IPR on every frame of a configuration

CAMERAS (error = distance between the file's projection of the truth's particles,
both frames of the first snapshots of dt0, and their true image positions)
 camFile/: what OpenLPT's plate calibration gives, done carefully. OpenLPT's calibration
 fits OpenCV's pinhole (cv2.calibrateCamera: no refraction, no tilted sensor) to plate
 dots; here one pinhole per camera (f_x, f_y, principal point, k1, k2, p1, p2 free) is
 fitted to the dots of every traverse position as one non-coplanar view, the dots' image
 centroids (truth.h5's plate group, what a dot detector measures; dots within
 0.75 dot diameters of the image edge left out) against their nominal positions (grid
 index x pitch, nominal traverse Z), as a user types them. Scheimpflug tilt and
 refraction are absorbed where the pinhole and its distortion can absorb them.
{_camera_lines(source.cameras, sets[0])}
 camFileTrue/: the true cameras (truth.h5's rig, what the images were rendered with) as
 far as OpenLPT's models hold them: OpenLPT's POLYNOMIAL (u and v each a polynomial in
 X, Y, Z in mm) fitted by least squares to synptv's exact projection (tilt and
 refraction included) on a grid over the view volume, the smallest order from 3 to 5
 whose largest error there is below {POLYNOMIAL_TARGET_PX:g} px. Its lines of sight go through
 the points where its inverse meets two planes on the view volume's faces normal to the
 world axis nearest the camera's axis. Do not use it outside the view volume.
{_camera_lines(source.cameras, sets[1])}

WHAT WAS CHOSEN OR GUESSED, AND WHY
  * View volume: the lit volume (the rig's laser sheet) plus {VOLUME_MARGIN_VOXELS:g} voxels each
    side: {box} mm. OpenLPT drops objects outside it.
  * Voxel to mm: {volume.voxel * MM:.6g}, the object-side size of one pixel at the
    origin, mean over the cameras. Every [voxel] value of the tracer settings is
    multiplied by it.
  * Background subtracted: OpenLPT expects a zero background (its OTF estimate fits log
    I around each peak, its residual images subtract the projected particles only;
    `openlpt preprocess` subtracts a mean background image from real images). Each
    camera's images are written less its background level, the mode of the grey
    levels of its first image, clipped at 0: {bg} DN. Uncompressed TIFF: OpenLPT's
    libtiff cannot read the Deflate compression synptv renders with.
  * Max intensity {top}: the images' largest grey level (2^bit_depth - 1).
  * Image lists hold at least {OTF_FRAMES} lines: OpenLPT estimates its OTF on the first five
    frames of the lists even when fewer are processed; a shorter list repeats its
    frames.
  * Frame rate: 1/dt rounded to an integer Hz (OpenLPT reads an integer); it matters
    only to STB, which these independent pairs are not for.
  * Tracer settings: OpenLPT's GUI defaults (4 IPR loops, 4 shake loops, ghost
    threshold 0.1, 2-D tolerance 0.8 px, 3-D tolerance 1 voxel, 1 camera dropped in 2
    reduced loops, shake width 0.25 voxel, particle radius {s0.particle_radius:g} px); link search
    radius = the largest particle displacement over dt ({source.max_speed:.3g} m/s, the true
    velocities' mean speed plus five rms of a component, times dt) in voxels ({radii});
    2-D peak threshold {s0.peak_threshold} counts above the subtracted background: the larger of
    {PEAK_FRACTION:g} x the typical particle image peak ({peak:.4g} DN, the median of the local
    maxima of the first image, the faintest camera) and {PEAK_SIGMAS:g} x the background noise
    ({noise:.3g} DN, the noisiest camera). OpenLPT adds every peak of its residual images
    above the threshold as a candidate; at the noise level most of them are ghosts.
  * No plate images are exported: OpenLPT's plate calibration is an interactive GUI
    step; camFile/ holds its result.

HOW TO RUN
  IPR on every frame of dt0, positions for synptv score (metres):
    python run_ipr.py config_dt0.txt --positions Results/dt0/positions.csv --dt 0
    synptv score --dataset {source.folder} --positions Results/dt0/positions.csv
  (config_true_dt0.txt for the true cameras.) run_ipr.py uses OpenLPT's Python API
  (openlpt.IPR.runIPR) and also writes <output folder>/ipr.csv (frame,x_mm,y_mm,z_mm);
  --summary FILE adds its times and memory. OpenLPT's own command line (openlpt
  config_dt0.txt) runs Shake-the-Box over the frame range, which needs a time-resolved
  sequence: the pairs here are independent.
"""
