"""A rendered dataset in the layout OpenPTV (liboptv, its Python binding ``optv``,
pyptv) reads.

Layout of the export folder (OpenPTV's units: mm on both sides, pixels for the image
size; docs/export.md)::

    README.txt                      what each file is and which settings were guessed
    frames.csv                      dt,snapshot,frame,number: the OpenPTV frame number of
                                    each exposure of the dataset
    parameters/ptv.par              cameras, image size, pixel size, multimedia indices
                                    n1 (air), n2 (glass), n3 (water) and glass thickness
    parameters/criteria.par         observed volume and correspondence tolerances
    parameters/targ_rec.par         particle detection: grey thresholds and size bounds
    parameters/detect_plate.par     plate dot detection, same format
    parameters/sequence.par         the image sequence of Δt_0 (sequence_dt<k>.par: Δt_k)
    parameters/track.par            displacement bounds of Δt_0 (track_dt<k>.par: Δt_k)
    parameters/cal_ori.par          target file, calibration image and orientation file
                                    of each camera (the middle traverse position)
    cal/<camera>.tif.ori            initial exterior and interior orientation, glass vector
    cal/<camera>.tif.addpar         initial distortion and affine terms (zero)
    cal/<camera>/plane_<jj>.tif     8-bit plate image at traverse position j
    cal/target_plane_<jj>.txt       "id X Y Z" of every dot at traverse position j, mm
    img/dt<k>/<camera>.<number>     8-bit particle images, TIFF without extension
    img/seq<s>/<camera>.<number>    of a recording: frame n of recording s is number
                                    10001 + n − first (parameters/sequence_seq<s>.par,
                                    track.par for one frame interval)

OpenPTV's camera model is a pinhole with Brown distortion and an affine term behind
flat refractive slabs: each camera's slab has its own normal and distance (the glass
vector of its .ori file) but ptv.par holds one thickness and one set of indices for all
cameras. The rig's windows are flat, so the export sets each glass vector to the true
window normal and distance; rigs whose windows differ in thickness or media are refused.
"""

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from simulator.optics.camera import Camera
from validation.export.image_copies import grey_shift, noise_threshold, write_8bit
from validation.export.source import ExportSource, rotation_angles
from validation.run.experiment import object_pixel

#: OpenPTV's number of the first exposure of a sequence.
FIRST_NUMBER = 10001
#: Half-width of the epipolar band of the correspondences, px (criteria.par eps0).
EPIPOLAR_BAND_PX = 1.0
#: Margin added around the laser sheet for the observed volume, m.
VOLUME_MARGIN = 2e-3
#: Largest grey-level step inside one target before OpenPTV splits it (8-bit).
DISCONTINUITY = 100
#: The position noise a recording's track.par allows for, in object-side pixels: a tenth
#: of a pixel, what a fair calibration and centroid leave.
NOISE_GUESS_PX = 0.1
MM = 1e3


def frame_number(m: int, frame: str) -> int:
    """OpenPTV's frame number of frame ``frame`` (a or b) of snapshot m: the pairs one
    after the other, ``FIRST_NUMBER + 2m`` for a and one more for b."""
    return FIRST_NUMBER + 2 * m + (frame == "b")


@dataclass(frozen=True)
class Orientation:
    """One camera in OpenPTV's terms (mm; the camera looks along its −z axis, image y
    up, metric sensor coordinates from the sensor centre).

    Attributes
    ----------
    position : ndarray, shape (3,)
        Projection centre (x0, y0, z0), mm.
    angles : ndarray, shape (3,)
        (ω, φ, κ), rad: camera-to-world rotation R_x(ω) R_y(φ) R_z(κ).
    rotation : ndarray, shape (3, 3)
        That rotation matrix (``dm`` of the .ori file).
    primary_point : ndarray, shape (3,)
        (xh, yh, cc): principal point from the sensor centre and principal distance, mm.
    glass : ndarray, shape (3,)
        Glass vector: from the origin to the water side of the window, along its
        normal (toward the camera), mm.
    """

    position: np.ndarray
    angles: np.ndarray
    rotation: np.ndarray
    primary_point: np.ndarray
    glass: np.ndarray


def recorded_number(recording, n: int) -> int:
    """OpenPTV's frame number of frame n of a recording (a Dataset with ``sequence``):
    ``FIRST_NUMBER + n − first``."""
    return FIRST_NUMBER + n - recording.sequence.first


def orientation(camera: Camera) -> Orientation:
    """The OpenPTV orientation of a rig camera's nominal pose, lens and window.

    The pupil centre is the projection centre, the image distance the principal
    distance, the principal point as on the sensor; the sensor tilt (Scheimpflug) and
    the lens distortion have no place in the guess (OpenPTV has no tilted sensor).

    Parameters
    ----------
    camera : simulator.optics.camera.Camera
        World → camera rotation R (rows: the camera's x right, y down, z forward).

    Returns
    -------
    Orientation
    """
    lens = camera.lens
    width, height = lens.sensor_size
    pitch = lens.pixel_pitch * MM
    # OpenPTV's camera axes: x right, y up, z backward; dm maps them to the world.
    dm = camera.rotation.T @ np.diag([1.0, -1.0, -1.0])
    cx, cy = lens.principal_point
    if camera.interfaces is None:
        glass = np.zeros(3)
    else:
        glass = camera.interfaces.normal * camera.interfaces.offsets[-1] * MM
    return Orientation(
        position=np.asarray(camera.center) * MM,
        angles=np.array(rotation_angles(dm)),
        rotation=dm,
        primary_point=np.array(
            [(cx - width / 2) * pitch, (height / 2 - cy) * pitch, lens.image_distance * MM]
        ),
        glass=glass,
    )


def ori_text(o: Orientation) -> str:
    """The .ori file of an orientation (OpenPTV's layout: position, angles, rotation
    matrix, principal point, principal distance, glass vector)."""
    rows = "\n".join("    " + " ".join(f"{v:13.10f}" for v in row) for row in o.rotation)
    xh, yh, cc = o.primary_point
    return (
        " ".join(f"{v:.10f}" for v in o.position)
        + "\n    "
        + " ".join(f"{v:.12f}" for v in o.angles)
        + f"\n\n{rows}\n\n    {xh:.8f} {yh:.8f}\n    {cc:.8f}\n\n    "
        + " ".join(f"{v:.10f}" for v in o.glass)
        + "\n"
    )


#: The .addpar of the guess: k1 k2 k3 p1 p2 (no distortion), scx = 1, she = 0.
ADDPAR_TEXT = "0 0 0 0 0 1 0\n"


def multimedia(source: ExportSource) -> tuple[float, float, float, float]:
    """(n1, n2, n3, d): air, glass and water indices and glass thickness (mm) shared by
    every camera's window.

    Raises
    ------
    ValueError
        A camera without a single glass window, or windows that differ in thickness
        or media: ptv.par holds one of each (the message names truth.h5).
    """
    found = {}
    for name, camera in zip(source.cameras, source.rig.cameras, strict=True):
        stack = camera.interfaces
        if stack is None or len(stack.offsets) != 2:
            raise ValueError(
                f"{source.folder / 'truth.h5'}: camera {name!r} does not look through one "
                "glass window (air | glass | water), which OpenPTV's ptv.par requires"
            )
        n1, n2, n3 = (float(n) for n in stack.indices)
        found[name] = (n1, n2, n3, round(float(np.diff(stack.offsets)[0]) * MM, 9))
    if len(set(found.values())) > 1:
        raise ValueError(
            f"{source.folder / 'truth.h5'}: the cameras' windows differ "
            f"({'; '.join(f'{k}: n = {v[:3]}, d = {v[3]} mm' for k, v in found.items())}), "
            "but OpenPTV's ptv.par holds one glass thickness and one set of indices"
        )
    return next(iter(found.values()))


def _common_sensor(source: ExportSource) -> tuple[int, int, float]:
    """(width, height, pixel pitch in mm) shared by every camera (ptv.par holds one)."""
    sensors = {
        (c.lens.sensor_size[0], c.lens.sensor_size[1], c.lens.pixel_pitch * MM)
        for c in source.rig.cameras
    }
    if len(sensors) > 1:
        raise ValueError(
            f"{source.folder / 'truth.h5'}: the cameras' sensors differ ({sorted(sensors)}), "
            "but OpenPTV's ptv.par holds one image size and one pixel size"
        )
    return next(iter(sensors))


def dot_size_bounds(source: ExportSource) -> tuple[tuple[int, int], tuple[int, int]]:
    """Pixel-count and width bounds of a plate dot's image for detect_plate.par.

    A dot of diameter D (the plate's small dots) to M (its marks) images to about
    D f / L pixels across, f the principal distance in px and L the camera's distance
    to the origin (the largest over the cameras for the smallest image, the smallest for
    the largest). The bounds take half the smallest area and four times the largest.

    Returns
    -------
    ((int, int), (int, int))
        (least, most) pixels of a dot, (least, most) width in px.
    """
    scales = [
        c.lens.fx / float(np.linalg.norm(c.center)) for c in source.rig.cameras
    ]  # px per m at the origin, refraction aside
    small = source.dot_diameters[0] * min(scales)
    large = source.dot_diameters[1] * max(scales)
    area = np.pi / 4
    return (
        (max(3, int(0.5 * area * small**2)), int(np.ceil(4 * area * large**2)) + 10),
        (max(1, int(0.5 * small)), int(np.ceil(2 * large)) + 2),
    )


def _lines(*values) -> str:
    return "".join(f"{v}\n" for v in values)


@dataclass(frozen=True)
class Guesses:
    """The settings an export guesses from the images (README.txt reports them).

    Attributes
    ----------
    plate_shift, particle_shift : int
        Right shifts to 8 bits of the plate and particle images.
    particle_threshold, plate_threshold : list of int
        Grey threshold per camera, 8-bit.
    """

    plate_shift: int
    particle_shift: int
    particle_threshold: list
    plate_threshold: list


def _particle_images(source: ExportSource) -> list[tuple[Path, str, Path]]:
    """(source image, camera, path in the export) of every particle image."""
    if source.recordings:
        return [
            (r.recorded_path(c, n), c, Path(f"img/seq{s}/{c}.{recorded_number(r, n)}"))
            for s, r in enumerate(source.recordings)
            for n in r.sequence.frame_numbers()
            for c in source.cameras
        ]
    return [
        (source.frame_path(k, c, m, f), c, Path(f"img/dt{k}/{c}.{frame_number(m, f)}"))
        for k in range(source.dataset.n_dt)
        for m in range(source.dataset.frames[k])
        for f in "ab"
        for c in source.cameras
    ]


def _guesses(source: ExportSource) -> Guesses:
    """8-bit shifts and thresholds, from the dataset's images."""
    plates = [p for row in source.plate_images for p in row]
    particles = _particle_images(source)
    plate_shift = grey_shift(plates)
    particle_shift = grey_shift([path for path, _, _ in particles])
    first = {camera: path for path, camera, _ in reversed(particles)}
    return Guesses(
        plate_shift=plate_shift,
        particle_shift=particle_shift,
        particle_threshold=[noise_threshold(first[c], particle_shift) for c in source.cameras],
        plate_threshold=[
            max(noise_threshold(row[0], plate_shift), (255 >> 2)) for row in source.plate_images
        ],
    )


def _target_par(thresholds: list, pixels: tuple[int, int], size: tuple[int, int], sumg: int):
    """targ_rec.par / detect_plate.par: 4 thresholds, discontinuity, pixel-count, x-size
    and y-size bounds, least grey sum, cross size."""
    padded = [*thresholds, *[thresholds[-1]] * (4 - len(thresholds))]
    return _lines(*padded[:4], DISCONTINUITY, *pixels, *size, *size, sumg, 2)


def _par_files(source: ExportSource, guesses: Guesses) -> dict[str, str]:
    """Every parameters/*.par file, by name."""
    width, height, pitch = _common_sensor(source)
    n1, n2, n3, d = multimedia(source)
    names = source.cameras
    middle = len(source.dots) // 2
    first_images = "img/seq0" if source.recordings else "img/dt0"
    ptv = _lines(
        len(names),
        *[
            line
            for c in names
            for line in (f"{first_images}/{c}.{FIRST_NUMBER}", f"cal/{c}/plane_{middle:02d}.tif")
        ],
        0,  # no highpass filter: the rendered background is uniform
        0,  # allCam_flag: accept pairs and triplets, not only points seen by all cameras
        1,  # TIFF images
        width,
        height,
        pitch,
        pitch,
        0,  # chfield: full frames, not interlaced fields
        n1,
        n2,
        n3,
        d,
    )
    sheet = source.rig.sheet
    lo = (np.asarray(sheet.centre) - np.asarray(sheet.size) / 2 - VOLUME_MARGIN) * MM
    hi = (np.asarray(sheet.centre) + np.asarray(sheet.size) / 2 + VOLUME_MARGIN) * MM
    criteria = _lines(
        lo[0],
        lo[2],
        hi[2],
        hi[0],
        lo[2],
        hi[2],
        0.02,
        0.02,
        0.02,
        0.02,
        33,
        EPIPOLAR_BAND_PX * pitch,
    )
    files = {
        "ptv.par": ptv,
        "criteria.par": criteria,
        "targ_rec.par": _target_par(guesses.particle_threshold, (2, 400), (1, 30), 10),
        "detect_plate.par": _target_par(guesses.plate_threshold, *dot_size_bounds(source), 100),
        "cal_ori.par": _lines(
            f"cal/target_plane_{middle:02d}.txt",
            *[
                line
                for c in names
                for line in (f"cal/{c}/plane_{middle:02d}.tif", f"cal/{c}.tif.ori")
            ],
            1,
            0,
            0,
        ),
    }
    return files | (_recording_files(source) if source.recordings else _pair_files(source))


def _pair_files(source: ExportSource) -> dict[str, str]:
    """sequence and track .par files of each Δt's frame pairs."""
    files = {}
    for k, dt in enumerate(source.dataset.dt):
        last = frame_number(source.dataset.frames[k] - 1, "b")
        sequence = _lines(*[f"img/dt{k}/{c}." for c in source.cameras], FIRST_NUMBER, last)
        step = source.max_speed * dt * MM
        track = _lines(-step, step, -step, step, -step, step, 120, 0.4 * step, 0)
        files[f"sequence_dt{k}.par"] = sequence
        files[f"track_dt{k}.par"] = track
        if k == 0:
            files["sequence.par"], files["track.par"] = sequence, track
    return files


def recording_bounds(source: ExportSource) -> tuple[float, float]:
    """track.par's bounds for a recording, mm: the most a particle moves in one frame
    interval τ per component, max_speed·τ, and the most it leaves its constant-velocity
    prediction, max_acceleration·τ² + 5√6σ, σ = :data:`NOISE_GUESS_PX` object-side
    pixels (the noise of the three positions the prediction and its point carry)."""
    tau = 1.0 / source.recordings[0].sequence.frame_rate
    noise = 5 * np.sqrt(6) * NOISE_GUESS_PX * object_pixel(source.rig)
    return source.max_speed * tau * MM, (source.max_acceleration * tau**2 + noise) * MM


def _recording_files(source: ExportSource) -> dict[str, str]:
    """sequence .par files of each recording, and track.par for one frame interval."""
    step, acceleration = recording_bounds(source)
    files = {"track.par": _lines(-step, step, -step, step, -step, step, 120, acceleration, 0)}
    for s, recording in enumerate(source.recordings):
        numbers = recording.sequence.frame_numbers()
        files[f"sequence_seq{s}.par"] = _lines(
            *[f"img/seq{s}/{c}." for c in source.cameras],
            recorded_number(recording, numbers[0]),
            recorded_number(recording, numbers[-1]),
        )
    files["sequence.par"] = files["sequence_seq0.par"]
    return files


def _target_file(dots: np.ndarray) -> str:
    """A target file: one line "id X Y Z" per dot (ids from 1, mm)."""
    return "".join(
        f"{i + 1} {x:.6f} {y:.6f} {z:.6f}\n" for i, (x, y, z) in enumerate(np.asarray(dots) * MM)
    )


def write_openptv(source: ExportSource, out: Path) -> list[Path]:
    """Write ``source`` in the OpenPTV layout (module docstring) into the folder ``out``.

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

    Raises
    ------
    ValueError
        A rig OpenPTV's parameter files cannot describe (windows or sensors that differ
        between cameras), raised before anything is written.
    """
    _common_sensor(source)
    multimedia(source)
    guesses = _guesses(source)
    written = []

    def text(relative: str, content: str) -> None:
        path = out / relative
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(content)
        written.append(path)

    for name, content in _par_files(source, guesses).items():
        text(f"parameters/{name}", content)
    for name, camera in zip(source.cameras, source.rig.cameras, strict=True):
        text(f"cal/{name}.tif.ori", ori_text(orientation(camera)))
        text(f"cal/{name}.tif.addpar", ADDPAR_TEXT)
    for j, dots in enumerate(source.dots):
        text(f"cal/target_plane_{j:02d}.txt", _target_file(dots))
    for name, row in zip(source.cameras, source.plate_images, strict=True):
        for j, path in enumerate(row):
            target = out / "cal" / name / f"plane_{j:02d}.tif"
            write_8bit(path, target, guesses.plate_shift)
            written.append(target)
    for path, _, relative in _particle_images(source):
        write_8bit(path, out / relative, guesses.particle_shift)
        written.append(out / relative)
    text("frames.csv", _frames_csv(source))
    text("README.txt", readme(source, guesses))
    return written


def _frames_csv(source: ExportSource) -> str:
    """frames.csv: the OpenPTV number of every exposure (frame pairs) or recorded frame."""
    if source.recordings:
        rows = ["sequence,frame,number"] + [
            f"{s},{n},{recorded_number(r, n)}"
            for s, r in enumerate(source.recordings)
            for n in r.sequence.frame_numbers()
        ]
    else:
        rows = ["dt,snapshot,frame,number"] + [
            f"{k},{m},{frame},{frame_number(m, frame)}"
            for k in range(source.dataset.n_dt)
            for m in range(source.dataset.frames[k])
            for frame in "ab"
        ]
    return "\n".join(rows) + "\n"


def readme(source: ExportSource, guesses: Guesses) -> str:
    """README.txt of an OpenPTV export: each file, and every setting that was guessed."""
    n1, n2, n3, d = multimedia(source)
    width, height, pitch = _common_sensor(source)
    kind = _acquisition(source)
    z = ", ".join(f"{v * MM:g}" for v in source.dots[:, 0, 2])
    particle = ", ".join(str(v) for v in guesses.particle_threshold)
    plate = ", ".join(str(v) for v in guesses.plate_threshold)
    dots = dot_size_bounds(source)
    return f"""OpenPTV export of the synptv dataset {source.folder}
(written by `synptv export --format openptv`; docs/export.md of synptv)

Units: mm in every OpenPTV file (positions, glass vector, pixel size, thickness);
image coordinates in pixels, x = column, y = row, (0, 0) = the centre of the top-left
pixel. OpenPTV's 3-D results are in mm in the dataset's world frame: divide by 1000 to
score them with `synptv score` (metres).

Cameras: {", ".join(source.cameras)}; {width} x {height} px of {pitch * 1e3:g} um.
{kind.acquisition}

FILES
  parameters/ptv.par           cameras, first image and calibration image of each,
                               image and pixel size, multimedia n1 = {n1:g} (air),
                               n2 = {n2:g} (glass), n3 = {n3:g} (water), glass thickness {d:g} mm
  parameters/criteria.par      observed volume (the laser sheet plus {VOLUME_MARGIN * MM:g} mm) and
                               correspondence tolerances
  parameters/targ_rec.par      particle detection: thresholds, size bounds
  parameters/detect_plate.par  plate dot detection: thresholds, size bounds
{kind.sequence_files}
  parameters/cal_ori.par       target file, calibration image and orientation file
                               of each camera, at the middle traverse position
  cal/<camera>.tif.ori         initial orientation (position, angles, rotation matrix,
                               principal point, principal distance, glass vector)
  cal/<camera>.tif.addpar      initial distortion k1 k2 k3 p1 p2 and affine scx she
  cal/<camera>/plane_<jj>.tif  plate image at traverse position j (8-bit)
  cal/target_plane_<jj>.txt    "id X Y Z" (mm) of every dot at traverse position j:
                               the plate's nominal grid at the nominal traverse
                               Z_j = {z} mm (the true dots differ by the
                               plate's manufacturing and traverse errors)
{kind.image_files}

WHAT WAS CHOSEN OR GUESSED, AND WHY
  * No highpass filter (ptv.par hp_flag 0): the rendered background is uniform, and
    OpenPTV's background subtraction lost particles in a trial.
  * 8-bit images. OpenPTV processes 8-bit images; the rendered ones hold 12-bit grey
    levels. Plate images are shifted right by {guesses.plate_shift} bits and particle images by
    {guesses.particle_shift} bits: the smallest shifts that keep the brightest pixel of all plates
    (of all particle images) at or below 255, so nothing clips. The lost low bits
    cost OpenPTV some centroid precision; that is OpenPTV's format, not the data's.
  * Initial orientations (.ori). The rig's nominal camera placement, as a user would
    measure it on the bench: projection centre = the lens's entrance pupil, rotation
    from its pointing, principal distance = the lens-to-sensor distance, principal
    point at the sensor's centre. They are a starting point for OpenPTV's own
    calibration, not a calibration. Distortion and affine terms (.addpar) start at
    zero. The sensors are tilted (Scheimpflug mounts), which OpenPTV's model has no
    term for: its calibration must absorb the tilt in its angles, principal point,
    distortion and affine terms.
  * Multimedia model. OpenPTV refracts each camera's rays through one flat slab
    (air | glass | water) with the indices and thickness of ptv.par and the normal and
    distance of the camera's glass vector (last line of its .ori). The rig's windows
    are flat slabs too, each at its own angle to its camera's axis (oblique windows),
    so this export writes each glass vector exactly: the window's true normal, scaled
    by the distance from the origin to its water-side face. What OpenPTV cannot hold
    is a different thickness or glass per camera (refused by this export) and a slab
    it does not fit: its calibration keeps the glass vector fixed, so an error in the
    window's position is absorbed elsewhere.
  * Thresholds. Particle grey thresholds (targ_rec.par) per camera: {particle}, the
    background median plus six robust noise sigmas of the first frame; plate
    thresholds (detect_plate.par): {plate} (at least a quarter of the 8-bit range).
    Size bounds: 2-400 px per particle (loose); per dot, from half the area of a
    small dot to four times that of a mark as imaged at the camera's distance
    ({dots[0][0]}-{dots[0][1]} px, {dots[1][0]}-{dots[1][1]} px across).
  * Correspondences (criteria.par). Epipolar band eps0 = {EPIPOLAR_BAND_PX:g} px on the sensor
    ({EPIPOLAR_BAND_PX * pitch:g} mm): a few times a good calibration's residual, and narrow,
    since with two cameras each other particle inside the band makes a pair ambiguous
    (set it to about twice your calibration's RMS residual); OpenPTV's usual
    similarity limits (0.02) and corrmin 33.
{kind.tracking}
"""


@dataclass(frozen=True)
class _Acquisition:
    """The parts of README.txt that differ between frame pairs and recordings."""

    acquisition: str
    sequence_files: str
    image_files: str
    tracking: str


def _acquisition(source: ExportSource) -> _Acquisition:
    """README.txt's description of the particle images and their tracking bounds."""
    if not source.recordings:
        dt = ", ".join(f"dt{k} = {v * 1e3:.6g} ms" for k, v in enumerate(source.dataset.dt))
        return _Acquisition(
            acquisition=f"""\
Time separations: {dt}.
Double-frame acquisition: snapshot m of every dt is a pair of exposures, frame a at t
and frame b at t + dt; the pairs are independent of each other (do not track from one
pair to the next). Each dt is one image sequence, img/dt<k>/<camera>.<number>, with
number = {FIRST_NUMBER} + 2m for frame a and {FIRST_NUMBER + 1} + 2m for frame b; frames.csv
lists them all (dt, snapshot, frame, number).""",
            sequence_files="""\
  parameters/sequence.par      the sequence of dt0; sequence_dt<k>.par for dt<k>
                               (copy one over sequence.par to process that dt)
  parameters/track.par         tracking bounds for dt0; track_dt<k>.par for dt<k>""",
            image_files="""\
  img/dt<k>/<camera>.<number>  particle images (8-bit TIFF, no extension)
  frames.csv                   dt,snapshot,frame,number of every exposure""",
            tracking=f"""\
  * Tracking (track.par). Displacement bounds of +-{source.max_speed:.3g} m/s x dt per
    component (the true velocities' mean speed plus five rms of a component); the
    pairs are double-frame exposures, so only the a -> b link of each pair is meaningful.""",
        )
    rate = source.recordings[0].sequence.frame_rate
    step, acceleration = recording_bounds(source)
    return _Acquisition(
        acquisition=f"""\
Time-resolved acquisition: {len(source.recordings)} recording(s) at {rate:.6g} frames per
second. Recording s is one image sequence, img/seq<s>/<camera>.<number>, its frame n
numbered {FIRST_NUMBER} + n - first; frames.csv lists them all (sequence, frame, number).
Track them with OpenPTV's tracker, frame after frame.""",
        sequence_files="""\
  parameters/sequence.par      the images of recording 0; sequence_seq<s>.par of
                               recording s (copy one over sequence.par to track it)
  parameters/track.par         tracking bounds for one frame interval""",
        image_files="""\
  img/seq<s>/<camera>.<number> particle images (8-bit TIFF, no extension)
  frames.csv                   sequence,frame,number of every recorded frame""",
        tracking=f"""\
  * Tracking (track.par). Displacement bounds of +-{step:.4g} mm per frame and
    component: {source.max_speed:.3g} m/s (the true velocities' mean speed plus five rms of a
    component) over one frame interval. Acceleration bound dacc = {acceleration:.4g} mm: the
    most a particle leaves its constant-velocity prediction, {source.max_acceleration:.3g} m/s2 (the
    true accelerations' mean plus five rms of a component) times the interval squared,
    plus five times the noise of the three positions behind the prediction and its
    point, sqrt(6) x {NOISE_GUESS_PX:g} object-side pixel. Angle bound 120 gon; no
    particles added.""",
    )
