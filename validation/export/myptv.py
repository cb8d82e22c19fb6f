"""A rendered dataset in the layout of MyPTV's workflow (``workflow.py params_file.yml``).

Layout of the export folder (lab coordinates in mm, image coordinates in pixels;
docs/export.md)::

    README.txt                              what each file is, what was guessed
    params_file.yml                         the workflow's parameters, one section per
                                            step (calibration, segmentation, matching,
                                            tracking), set for camera 1 and Δt_0
    frames.csv                              dt,snapshot,frame,frame: MyPTV's frame
                                            number of each exposure
    <camera>                                initial camera file (MyPTV's Tsai model)
    Calibration/<camera>/plane_<jj>.tif     plate image at traverse position j
    Calibration/target_file_plane_<jj>      "x y z" (tab-separated, mm) of every dot
    Images/dt<k>/<camera>/<mmmmmm>_<a|b>.tif   particle images of snapshot m at Δt_k

MyPTV reads the 16-bit images as they are: they are hard links to (or copies of) the
dataset's files. Its camera models have no refraction term: the polynomial correction
of its calibration absorbs the windows.
"""

from pathlib import Path

import numpy as np

from simulator.optics.camera import Camera
from validation.export.image_copies import link_or_copy, noise_threshold
from validation.export.source import ExportSource, rotation_angles

MM = 1e3
#: Margin added around the laser sheet for the matching region, m.
VOLUME_MARGIN = 2e-3


def frame_index(m: int, frame: str) -> int:
    """MyPTV's frame number of frame ``frame`` of snapshot m: its place in the sorted
    image folder of one Δt (2m for a, 2m + 1 for b)."""
    return 2 * m + (frame == "b")


def camera_file(name: str, camera: Camera) -> str:
    """An initial MyPTV camera file (Tsai model) from a rig camera's nominal pose and lens.

    MyPTV projects a point X to η = f v₁/v₃ + W/2 + x_h, ζ = f v₂/v₃ + H/2 + y_h with
    v = R (X − O), R = R_x(θ₁) R_y(θ₂) R_z(θ₃): O is the pupil centre (mm), R the
    world → camera rotation, f the principal distance in pixels and (x_h, y_h) the
    principal point from the sensor centre, px. The correction matrix E starts at zero.
    Each line ends in a space: MyPTV's reader drops the last two characters of a line.

    Parameters
    ----------
    name : str
        Camera name (the file's name).
    camera : simulator.optics.camera.Camera
        The rig camera.

    Returns
    -------
    str
        The file's text.
    """
    lens = camera.lens
    width, height = lens.sensor_size
    cx, cy = lens.principal_point

    def line(values) -> str:
        return " ".join(f"{v:.12g}" for v in values) + " \n"

    return (
        "Tsai model camera\n"
        f"{name}\n"
        + line([width, height])
        + line(np.asarray(camera.center) * MM)
        + line(rotation_angles(camera.rotation))
        + line([lens.fx])
        + line([cx - width / 2, cy - height / 2])
        + "".join(line(np.zeros(5)) for _ in range(3))
    )


def _target_file(dots: np.ndarray) -> str:
    """A MyPTV target file: one "x y z" line per dot, tab-separated, mm."""
    return "".join("\t".join(f"{v:.6f}" for v in dot) + "\n" for dot in np.asarray(dots) * MM)


def params_file(source: ExportSource, threshold: int) -> str:
    """params_file.yml: the workflow's steps set for camera 1, Δt_0 and the middle plane."""
    first = source.cameras[0]
    width, height = source.rig.cameras[0].lens.sensor_size
    middle = len(source.dots) // 2
    sheet = source.rig.sheet
    lo = (np.asarray(sheet.centre) - np.asarray(sheet.size) / 2 - VOLUME_MARGIN) * MM
    hi = (np.asarray(sheet.centre) + np.asarray(sheet.size) / 2 + VOLUME_MARGIN) * MM
    step = source.max_speed * source.dataset.dt[0] * MM
    names = ", ".join(source.cameras)
    blobs = ", ".join(f"blobs_{c}_dt0" for c in source.cameras)
    roi = ", ".join(f"{v:g}" for pair in zip(lo, hi, strict=True) for v in pair)
    return f"""- calibration:
    camera_name: {first}
    resolution: {width}, {height}
    calibration_image: ./Calibration/{first}/plane_{middle:02d}.tif
    target_file: ./Calibration/target_file_plane_{middle:02d}
    segmented_points_file: ./Calibration/blobs_{first}_plane_{middle:02d}
    calibration_points_file: ./Calibration/cal_points_{first}

- segmentation:
    Number_of_images: None
    image_start: 0
    images_folder: Images/dt0/{first}
    single_image_name: 000000_a.tif
    image_extension: '.tif'
    mask: 1.0
    ROI: 0, {width}, 0, {height}
    plot_result: False
    threshold: {threshold}
    median: None
    blur_sigma: None
    local_filter: None
    min_xsize: 1.0
    min_ysize: 1.0
    min_mass: None
    max_xsize: 15.0
    max_ysize: 15.0
    max_mass: None
    method: labeling
    particle_size: 3
    save_name: blobs_{first}_dt0

- matching:
    blob_files: {blobs}
    frame_start: 0
    N_frames: None
    camera_names: {names}
    cam_resolution: {width}, {height}
    ROI: {roi}
    voxel_size: 2.0
    max_blob_distance: 1.0
    max_err: 0.1
    save_name: particles_dt0

- tracking:
    particles_file_name: particles_dt0
    frame_start: 0
    N_frames: None
    d_max: {step:.6g}
    dv_max: {step:.6g}
    save_name: trajectories_dt0
"""


def write_myptv(source: ExportSource, out: Path) -> list[Path]:
    """Write ``source`` in MyPTV's layout (module docstring) into the folder ``out``.

    Parameters
    ----------
    source : ExportSource
        The checked dataset.
    out : Path
        An empty folder.

    Returns
    -------
    list of Path
        The files written.
    """
    written = []

    def text(relative: str, content: str) -> None:
        path = out / relative
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(content)
        written.append(path)

    def image(source_path: Path, relative: str) -> None:
        link_or_copy(source_path, out / relative)
        written.append(out / relative)

    threshold = noise_threshold(source.frame_path(0, source.cameras[0], 0, "a"), 0)
    for name, camera in zip(source.cameras, source.rig.cameras, strict=True):
        text(name, camera_file(name, camera))
    for j, dots in enumerate(source.dots):
        text(f"Calibration/target_file_plane_{j:02d}", _target_file(dots))
    for name, row in zip(source.cameras, source.plate_images, strict=True):
        for j, path in enumerate(row):
            image(path, f"Calibration/{name}/plane_{j:02d}.tif")
    rows = ["dt,snapshot,frame,frame_index"]
    for k in range(source.dataset.n_dt):
        for m in range(source.dataset.frames[k]):
            for frame in "ab":
                rows.append(f"{k},{m},{frame},{frame_index(m, frame)}")
                for name in source.cameras:
                    image(
                        source.frame_path(k, name, m, frame),
                        f"Images/dt{k}/{name}/{m:06d}_{frame}.tif",
                    )
    text("frames.csv", "\n".join(rows) + "\n")
    text("params_file.yml", params_file(source, threshold))
    text("README.txt", readme(source, threshold))
    return written


def readme(source: ExportSource, threshold: int) -> str:
    """README.txt of a MyPTV export: each file, and every setting that was guessed."""
    dt = ", ".join(f"dt{k} = {v * 1e3:.6g} ms" for k, v in enumerate(source.dataset.dt))
    z = ", ".join(f"{v * MM:g}" for v in source.dots[:, 0, 2])
    return f"""MyPTV export of the synptv dataset {source.folder}
(written by `synptv export --format myptv`; docs/export.md of synptv)

Units: lab coordinates in mm, in the dataset's world frame (divide MyPTV's positions by
1000 to score them with `synptv score`, which reads metres); image coordinates in
pixels, x = column, y = row, (0, 0) = the centre of the top-left pixel.

Cameras: {", ".join(source.cameras)}. Time separations: {dt}.
Double-frame acquisition: snapshot m of every dt is a pair of exposures, frame a at t
and frame b at t + dt, independent of the other pairs. The images of one dt and one
camera are in Images/dt<k>/<camera>/, named <mmmmmm>_<a|b>.tif, so that MyPTV's sorted
order numbers them 2m (frame a) and 2m + 1 (frame b); frames.csv lists every exposure
(dt, snapshot, frame, frame_index).

FILES
  params_file.yml                        MyPTV's workflow parameters, set for the first
                                         camera, dt0 and the middle traverse position
                                         (edit camera_name, images_folder and the file
                                         names for the others)
  <camera>                               initial camera file, MyPTV's Tsai model
  Calibration/<camera>/plane_<jj>.tif    plate image at traverse position j (16-bit)
  Calibration/target_file_plane_<jj>     "x y z" (mm, tab-separated) of every dot at
                                         traverse position j: the plate's nominal grid at
                                         the nominal traverse Z_j = {z} mm
  Images/dt<k>/<camera>/<mmmmmm>_<a|b>.tif   particle images (16-bit, 12 bits used)
  frames.csv                             dt,snapshot,frame,frame_index of each exposure

WHAT WAS CHOSEN OR GUESSED, AND WHY
  * The images are the rendered 16-bit files (hard links or copies): MyPTV reads them.
  * Calibration. MyPTV calibrates each camera from one image of a target with known
    points; this dataset has one image per traverse position of a flat plate. Segment
    the dots of each plane (segmentation on the plate image), match them to that
    plane's target file (match_target_file) and join the calibration point files of
    the planes into one: only several planes fix the depth.
  * Initial camera files: the rig's nominal camera placement, as a user would measure
    it on the bench: O = the lens's entrance pupil (mm), theta from its pointing,
    f = the lens-to-sensor distance in pixels, principal point at the sensor's centre,
    no correction terms. MyPTV's models have no refraction and no tilted (Scheimpflug)
    sensor: its correction terms must absorb both, starting from this guess.
  * Segmentation threshold {threshold}: the background median plus six robust noise sigmas of
    the first image of the first camera (in the 16-bit grey levels).
  * Matching region: the laser sheet plus {VOLUME_MARGIN * MM:g} mm; voxel size, blob distance and
    triangulation error limits are MyPTV's example values, not tuned.
  * Tracking bounds: {source.max_speed:.3g} m/s x dt0 (the true velocities' mean speed
    plus five rms of a component). The pairs are double-frame exposures: only the
    a -> b link of each pair is meaningful.
  * This layout follows MyPTV's documentation; it has not been run through MyPTV here.
"""
