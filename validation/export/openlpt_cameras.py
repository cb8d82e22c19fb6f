"""OpenLPT 2.2.4's camera files of a rendered dataset, and how far each is from the truth.

OpenLPT (pip ``openlpt``, C++ core ``pyopenlpt``) reads a text camera file per camera
(docs/export.md §6): PINHOLE (OpenCV's pinhole and its k1, k2, p1, p2, k3 distortion),
PINPLATE (a pinhole behind flat refractive plates) or POLYNOMIAL (u and v each a
polynomial in X, Y, Z; mm in, px out). None has a tilted (Scheimpflug) sensor. Two sets
are written:

- **from the plates** (:func:`plate_calibrations`): what a careful experimentalist gets
  with OpenLPT's own plate calibration, which fits OpenCV's pinhole to plate dots
  (``cv2.calibrateCamera`` in its GUI; no refraction, no tilt). One pinhole per camera
  is fitted to the dots of every traverse position as one non-coplanar view
  (:func:`ptv.calibration.pinhole_fit.calibrate_pinhole`): the image centroid of each
  dot's light (truth.h5's plate group: what a dot detector measures, here without
  detection noise or failures) against the dot's nominal position (grid index × pitch,
  nominal traverse Z), as a user types it. f_x, f_y, the principal point and the pose
  are free, and no distortion term (OpenLPT's GUI offers 0 to 5): OpenLPT draws an
  epipolar line through the projection of the other camera's centre, far off the
  image, where a fitted distortion polynomial is unconstrained; with k1, k2, p1, p2
  OpenLPT matched no particle on a ``lpt-challenge-small`` dataset on which the
  distortion-free fit is as close to the truth (the tilt is absorbed by a principal
  point far off the sensor). Written as PINHOLE.
- **the true cameras** (:func:`true_camera_files`): each rig camera of truth.h5 (what
  the images were rendered with) as far as OpenLPT's models hold it: the POLYNOMIAL of
  smallest order from :data:`POLYNOMIAL_ORDERS` fitted by least squares to synptv's exact
  projection (tilt and refraction included) on a grid over the view volume whose
  largest error at random points of the volume is below :data:`POLYNOMIAL_TARGET_PX`.
  OpenLPT draws a polynomial camera's line of sight through the points where the
  polynomial's inverse meets two planes normal to the world axis nearest the camera's
  axis, on the view volume's faces; the line of sight in the water is straight, so the
  line through two accurate points is accurate between them.

Each file's error is measured by projecting the truth's particles (truth.h5) through the
file as OpenLPT evaluates it (:func:`project_file`) against their true image positions.
"""

import itertools
from dataclasses import dataclass

import cv2
import h5py
import numpy as np

from ptv.calibration.grid_errors import nominal_positions
from ptv.calibration.observations import PlaneObservation
from ptv.calibration.pinhole import PinholeCalibration, PinholeModel
from ptv.calibration.pinhole_fit import calibrate_pinhole
from ptv.io.experiment_file import read_experiment
from simulator.optics.camera import Camera
from validation.run.experiment import object_pixel
from validation.truth.truth_file import TruthFile

MM = 1e3
#: Polynomial orders tried for a true camera, smallest first.
POLYNOMIAL_ORDERS = (3, 4, 5)
#: Largest error (px, at random points of the view volume) at which an order is taken;
#: if none reaches it, the order of smallest largest error.
POLYNOMIAL_TARGET_PX = 0.01
#: Random points of the view volume on which a polynomial order is chosen, and their seed.
CHOICE_POINTS = 20_000
CHOICE_SEED = 0
#: The view volume is the rig's laser sheet (its lit volume) plus this many voxels each side.
VOLUME_MARGIN_VOXELS = 2.0
#: The plate pinhole's model: no distortion term (module docstring).
PLATE_MODEL = PinholeModel(distortion=())
#: Dots whose image centroid lies closer to the image's edge than this many dot diameters
#: (as imaged at the origin) are left out of the plate fit: a dot cut by the edge has
#: its centroid pulled inwards.
EDGE_MARGIN_DOTS = 0.75
#: Snapshots of Δt_0 whose true particles measure a file's error.
ERROR_SNAPSHOTS = 5
#: OpenLPT's world axes for a polynomial camera's reference planes.
_AXES = ("REF_X", "REF_Y", "REF_Z")


def _fmt(values) -> str:
    """Comma-separated values, each as the shortest text that reads back exactly."""
    return ",".join(repr(float(v)) for v in np.ravel(values))


def _tokens(text: str) -> list[str]:
    """An OpenLPT text file's values as its readers see them: '#' starts a comment,
    blank lines are skipped, one value a line."""
    lines = (line.split("#")[0].strip() for line in text.splitlines())
    return [line for line in lines if line]


def _numbers(token: str) -> np.ndarray:
    return np.array([float(v) for v in token.split(",")])


# -- the view volume ---------------------------------------------------------------------


@dataclass(frozen=True)
class ViewVolume:
    """The volume OpenLPT reconstructs in (its configuration's view volume).

    Attributes
    ----------
    lower, upper : ndarray, shape (3,)
        Corners, m: the rig's laser sheet plus :data:`VOLUME_MARGIN_VOXELS` voxels each side.
    voxel : float
        One object-side pixel at the origin, mean over the cameras, m (OpenLPT's
        "voxel to mm", in m).
    """

    lower: np.ndarray
    upper: np.ndarray
    voxel: float


def view_volume(rig) -> ViewVolume:
    """The :class:`ViewVolume` of a :class:`simulator.rigs.Rig`."""
    voxel = object_pixel(rig)
    centre, size = np.asarray(rig.sheet.centre, float), np.asarray(rig.sheet.size, float)
    margin = VOLUME_MARGIN_VOXELS * voxel
    return ViewVolume(centre - size / 2 - margin, centre + size / 2 + margin, voxel)


# -- POLYNOMIAL --------------------------------------------------------------------------


def monomial_powers(order: int) -> np.ndarray:
    """Powers (p, q, r) of every monomial X^p Y^q Z^r of total degree ≤ ``order``, by
    degree, (T, 3) int; T = (order + 1)(order + 2)(order + 3) / 6."""
    return np.array(
        [
            p
            for degree in range(order + 1)
            for p in itertools.product(range(degree + 1), repeat=3)
            if sum(p) == degree
        ],
        dtype=int,
    )


def _monomials(points_mm: np.ndarray, powers: np.ndarray) -> np.ndarray:
    """Every monomial of ``powers`` (T, 3) at points (N, 3), mm: (N, T)."""
    x = np.asarray(points_mm, float)
    return np.prod(x[:, None, :] ** powers[None, :, :], axis=2)


def polynomial_text(
    powers: np.ndarray, u: np.ndarray, v: np.ndarray, image_size, axis: int, planes
) -> str:
    """A POLYNOMIAL camera file (OpenLPT 2.2.4's layout).

    Parameters
    ----------
    powers : ndarray of int, shape (T, 3)
        (p, q, r) of each monomial.
    u, v : ndarray, shape (T,)
        Coefficients of the column and the row, px / mm^(p+q+r).
    image_size : (int, int)
        (width, height), px.
    axis : int
        World axis (0 X, 1 Y, 2 Z) normal to the two reference planes.
    planes : (float, float)
        The reference planes' coordinates along ``axis``, mm.
    """
    width, height = image_size
    rows_u = [f"{c!r},{p},{q},{r}" for c, (p, q, r) in zip(u.tolist(), powers, strict=True)]
    rows_v = [f"{c!r},{p},{q},{r}" for c, (p, q, r) in zip(v.tolist(), powers, strict=True)]
    lines = [
        "# Camera Model: (PINHOLE/PINPLATE/POLYNOMIAL)",
        "POLYNOMIAL",
        "# Calibration Error: (not read)",
        "None",
        "# Image Size: (n_row,n_col)",
        f"{int(height)},{int(width)}",
        "# Reference Plane: (REF_X/REF_Y/REF_Z,coordinate,coordinate) [mm]",
        f"{_AXES[axis]},{_fmt(planes)}",
        "# Number of Coefficients:",
        str(len(powers)),
        "# U_Coeff,X_Power,Y_Power,Z_Power",
        *rows_u,
        "# V_Coeff,X_Power,Y_Power,Z_Power",
        *rows_v,
    ]
    return "\n".join(lines) + "\n"


def fit_polynomial(camera: Camera, volume: ViewVolume, order: int) -> str:
    """The POLYNOMIAL file of ``order`` fitted to a camera's exact projection.

    Parameters
    ----------
    camera : simulator.optics.camera.Camera
        The rig camera (refraction, tilt and distortion in its ``project``).
    volume : ViewVolume
        Where the fit holds: a grid of (2 order + 5)³ points over it, those the camera
        does not image left out.
    order : int
        Largest total degree, ≥ 1.

    Returns
    -------
    str
        The camera file.

    Raises
    ------
    ValueError
        The camera images fewer grid points than twice the coefficients.
    """
    n = 2 * order + 5
    axes = [np.linspace(lo, hi, n) for lo, hi in zip(volume.lower, volume.upper, strict=True)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    xy = camera.project(grid)
    seen = np.isfinite(xy).all(axis=1)
    powers = monomial_powers(order)
    if seen.sum() < 2 * len(powers):
        raise ValueError(
            f"the camera images {int(seen.sum())} of {len(grid)} points of the view volume: "
            f"too few for a polynomial of order {order}"
        )
    design = _monomials(grid[seen] * MM, powers)
    scale = np.abs(design).max(axis=0)
    coef = np.linalg.lstsq(design / scale, xy[seen], rcond=None)[0] / scale[:, None]
    axis = int(np.argmax(np.abs(camera.axis)))
    planes = (volume.lower[axis] * MM, volume.upper[axis] * MM)
    return polynomial_text(powers, coef[:, 0], coef[:, 1], camera.lens.sensor_size, axis, planes)


# -- PINHOLE -----------------------------------------------------------------------------


def pinhole_text(calibration: PinholeCalibration) -> str:
    """The PINHOLE file of an OpenCV pinhole without distortion fitted by synptv
    (OpenLPT 2.2.4's layout).

    OpenLPT's pinhole: X_c = R X + t (mm), u = f_x X_c/Z_c + c_x, v = f_y Y_c/Z_c + c_y
    (its distortion terms, all zero here, are left off). The file also holds Rᵀ and −Rᵀt
    (the camera centre), which OpenLPT reads for its lines of sight.

    Raises
    ------
    ValueError
        A calibration with a tilted sensor or a distortion term.
    """
    if calibration.model.tilted or calibration.model.distortion:
        raise ValueError("the export writes OpenLPT pinholes without tilt or distortion")
    width, height = calibration.image_size
    rotation = calibration.rotation
    t = calibration.tvec * MM
    lines = [
        "# Camera Model: (PINHOLE/PINPLATE/POLYNOMIAL)",
        "PINHOLE",
        "# Camera Calibration Error: (not read)",
        "None",
        "# Pose Calibration Error: (not read)",
        "None",
        "# Image Size: (n_row,n_col)",
        f"{int(height)},{int(width)}",
        "# Camera Matrix:",
        *(_fmt(row) for row in calibration.camera_matrix),
        "# Distortion Coefficients: (k1,k2,p1,p2,k3)",
        "0,0,0,0,0",
        "# Rotation Vector: (not read)",
        _fmt(cv2.Rodrigues(rotation)[0]),
        "# Rotation Matrix: (world -> camera)",
        *(_fmt(row) for row in rotation),
        "# Inverse of Rotation Matrix:",
        *(_fmt(row) for row in rotation.T),
        "# Translation Vector: [mm]",
        _fmt(t),
        "# Inverse of Translation Vector: (camera centre) [mm]",
        _fmt(-rotation.T @ t),
    ]
    return "\n".join(lines) + "\n"


def project_file(text: str, points_mm: np.ndarray) -> np.ndarray:
    """Pixels (N, 2) of points (N, 3), mm, through a POLYNOMIAL camera file or a PINHOLE
    one without distortion, as OpenLPT 2.2.4 evaluates it.

    Raises
    ------
    ValueError
        Another model, or a PINHOLE file with a distortion coefficient OpenLPT applies
        (one above 1e-8).
    """
    v = _tokens(text)
    x = np.asarray(points_mm, float)
    if v[0] == "POLYNOMIAL":
        n = int(v[4])
        u_rows = np.array([_numbers(row) for row in v[5 : 5 + n]])
        v_rows = np.array([_numbers(row) for row in v[5 + n : 5 + 2 * n]])
        a = _monomials(x, u_rows[:, 1:].astype(int))
        return np.column_stack([a @ u_rows[:, 0], a @ v_rows[:, 0]])
    if v[0] != "PINHOLE" or (_numbers(v[7]) > 1e-8).any():
        raise ValueError("project_file reads POLYNOMIAL files and undistorted PINHOLE ones")
    k = np.array([_numbers(v[i]) for i in (4, 5, 6)])
    rotation = np.array([_numbers(v[i]) for i in (9, 10, 11)])
    xc = x @ rotation.T + _numbers(v[15])
    return np.column_stack(
        [k[0, 0] * xc[:, 0] / xc[:, 2] + k[0, 2], k[1, 1] * xc[:, 1] / xc[:, 2] + k[1, 2]]
    )


# -- the two sets ------------------------------------------------------------------------


@dataclass(frozen=True)
class CameraFile:
    """One camera as written for OpenLPT, and its error against the truth.

    Attributes
    ----------
    model : str
        ``"PINHOLE"`` or ``"POLYNOMIAL"``.
    text : str
        The camera file.
    rms_px, max_px : float
        RMS and largest distance between the file's projection of the truth's particles
        and their true image positions, px (:func:`file_errors`).
    points : int
        Particle images measured.
    detail : str
        How the file was made: the polynomial's order and terms, or the plate fit's
        residual on its dots.
    """

    model: str
    text: str
    rms_px: float
    max_px: float
    points: int
    detail: str


@dataclass(frozen=True)
class TrueImages:
    """The truth's particles and where each camera images them.

    Attributes
    ----------
    positions : ndarray, shape (N, 3)
        Particle positions at both frames of the first snapshots of Δt_0, m.
    xy : list of ndarray, shape (N, 2)
        Their true image positions per camera, px (NaN where not imaged).
    """

    positions: np.ndarray
    xy: list


def true_images(folder, cameras) -> TrueImages:
    """:class:`TrueImages` of the first :data:`ERROR_SNAPSHOTS` snapshots of Δt_0 of the
    dataset ``folder``'s truth.h5, for the cameras named ``cameras``."""
    run = TruthFile(folder).runs(0, ERROR_SNAPSHOTS)[0]
    positions = run.positions.reshape(-1, 3)
    xy = []
    for name in cameras:
        pixels = run.xy[name].reshape(-1, 2).astype(float)
        pixels[~run.visible[name].reshape(-1)] = np.nan
        xy.append(pixels)
    return TrueImages(positions, xy)


def file_errors(text: str, positions: np.ndarray, xy: np.ndarray) -> tuple[float, float, int]:
    """RMS and largest distance (px) between a camera file's projection of ``positions``
    (N, 3) m and the true image positions ``xy`` (N, 2) px, over the finite rows of
    ``xy``; and their count."""
    seen = np.isfinite(xy).all(axis=1) & np.isfinite(positions).all(axis=1)
    d = np.linalg.norm(project_file(text, positions[seen] * MM) - xy[seen], axis=1)
    if not len(d):
        return float("nan"), float("nan"), 0
    return float(np.sqrt(np.mean(d**2))), float(d.max()), int(seen.sum())


def plate_calibrations(source) -> dict[str, PinholeCalibration]:
    """One OpenCV pinhole per camera fitted to the plate dots (module docstring).

    Parameters
    ----------
    source : validation.export.source.ExportSource
        The dataset: its truth.h5's plate group gives, per camera and traverse position,
        the centroid of each dot's light on the image (what a dot detector measures);
        the dots' nominal positions (grid index × pitch, nominal traverse Z) are what
        the fit is given for them, as a user types them.

    Returns
    -------
    dict of str to PinholeCalibration
        In the dataset's camera order.

    Raises
    ------
    ValueError
        A camera the fit cannot calibrate (the message names it and the file).
    """
    with h5py.File(source.folder / "truth.h5", "r") as f:
        plate = f["plate"]
        z = plate["z_nominal"][:]
        pitch = read_experiment(source.folder)["target"]["pitch"]
        nominal = nominal_positions(plate["dot_indices"][:], pitch, z)
        seen = {c: plate[f"{c}/dots_on_sensor"][:] for c in source.cameras}
        centroids = {c: plate[f"{c}/dots_centroid"][:] for c in source.cameras}
    out = {}
    for name, camera in zip(source.cameras, source.rig.cameras, strict=True):
        lens = camera.lens
        width, height = lens.sensor_size
        margin = EDGE_MARGIN_DOTS * source.dot_diameters[0] / object_pixel(source.rig)
        planes = []
        for j in range(len(z)):
            xy = centroids[name][j]
            inside = seen[name][j] & np.isfinite(xy).all(axis=1)
            inside &= (xy >= margin).all(axis=1)
            inside &= (xy[:, 0] <= width - 1 - margin) & (xy[:, 1] <= height - 1 - margin)
            planes.append(PlaneObservation(z[j], xy[inside], nominal[j, inside, :2]))
        try:
            out[name] = calibrate_pinhole(
                planes,
                (width, height),
                model=PLATE_MODEL,
                focal_px=lens.focal_length / lens.pixel_pitch,
            )
        except ValueError as err:
            raise ValueError(
                f"{source.folder / 'truth.h5'}: plate dots of camera {name!r}: {err}"
            ) from None
    return out


def plate_camera_files(calibrations: dict, truth: TrueImages) -> list[CameraFile]:
    """PINHOLE files of the plate calibrations, each with its error on the truth."""
    files = []
    for fit, xy in zip(calibrations.values(), truth.xy, strict=True):
        text = pinhole_text(fit)
        rms, worst, n = file_errors(text, truth.positions, xy)
        detail = f"pinhole from {fit.n_points} plate dots, residual {fit.rms:.3g} px rms"
        files.append(CameraFile("PINHOLE", text, rms, worst, n, detail))
    return files


def true_camera_files(rig, volume: ViewVolume, truth: TrueImages) -> list[CameraFile]:
    """POLYNOMIAL files of the rig's true cameras (module docstring), each with its
    error on the truth.

    Raises
    ------
    ValueError
        A camera that images too little of the view volume (the message names it).
    """
    points = np.random.default_rng(CHOICE_SEED).uniform(
        volume.lower, volume.upper, (CHOICE_POINTS, 3)
    )
    files = []
    for name, camera, xy in zip(rig.camera_names, rig.cameras, truth.xy, strict=True):
        exact = camera.project(points)
        best = None
        for order in POLYNOMIAL_ORDERS:
            try:
                text = fit_polynomial(camera, volume, order)
            except ValueError as err:
                raise ValueError(f"camera {name!r}: {err}") from None
            _, worst, _ = file_errors(text, points, exact)
            if best is None or worst < best[1]:
                best = (text, worst, order)
            if worst <= POLYNOMIAL_TARGET_PX:
                break
        text, worst, order = best
        rms, largest, n = file_errors(text, truth.positions, xy)
        detail = (
            f"polynomial of order {order} ({len(monomial_powers(order))} terms) fitted to "
            f"the true projection, largest error {worst:.2g} px over the view volume"
        )
        files.append(CameraFile("POLYNOMIAL", text, rms, largest, n, detail))
    return files
