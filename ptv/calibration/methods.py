"""One entry point for every calibration method, selected by name.

Each method takes the plane observations of one camera and the nominal data-sheet
values a user knows (image size, pixel pitch, lens focal length) and returns an
object offering the camera protocol (``pixel_to_ray``, ``project``).
"""

from collections.abc import Callable, Sequence
from dataclasses import dataclass

from ptv.calibration.model_free import calibrate_model_free
from ptv.calibration.observations import PlaneObservation
from ptv.calibration.pinhole_fit import calibrate_pinhole
from ptv.calibration.soloff import calibrate_soloff
from ptv.calibration.tsai import calibrate_tsai
from ptv.camera_model import CameraModel


@dataclass(frozen=True)
class CameraSheet:
    """Nominal camera data a user knows from the data sheets.

    Attributes
    ----------
    image_size : tuple of int
        (width, height), px.
    pixel_pitch : float
        Pixel size, m.
    focal_length : float
        Nominal lens focal length, m.

    Examples
    --------
    >>> import ptv
    >>> sheet = ptv.CameraSheet(image_size=(640, 480), pixel_pitch=1e-5, focal_length=0.05)
    >>> sheet.focal_length / sheet.pixel_pitch  # the pinhole's starting f, px
    5000.0
    """

    image_size: tuple[int, int]
    pixel_pitch: float
    focal_length: float


def _model_free(observations: Sequence[PlaneObservation], sheet: CameraSheet) -> CameraModel:
    return calibrate_model_free(list(observations), sheet.image_size)


def _tsai(observations: Sequence[PlaneObservation], sheet: CameraSheet) -> CameraModel:
    return calibrate_tsai(observations, pixel_pitch=sheet.pixel_pitch, sensor_size=sheet.image_size)


def _pinhole(observations: Sequence[PlaneObservation], sheet: CameraSheet) -> CameraModel:
    return calibrate_pinhole(
        list(observations), sheet.image_size, focal_px=sheet.focal_length / sheet.pixel_pitch
    )


def _soloff(observations: Sequence[PlaneObservation], sheet: CameraSheet) -> CameraModel:
    return calibrate_soloff(list(observations), sheet.image_size)


#: Calibration methods by name: the paper's model-free method and the baselines.
CALIBRATION_METHODS: dict[str, Callable[[Sequence[PlaneObservation], CameraSheet], CameraModel]] = {
    "model-free": _model_free,
    "tsai": _tsai,
    "pinhole": _pinhole,
    "soloff": _soloff,
}

#: Fewest plate positions with distinct Z each method can be fitted on: Soloff's
#: polynomial is quadratic in Z, the others need two planes to fix the depth.
MIN_PLANES = {"model-free": 2, "tsai": 2, "pinhole": 2, "soloff": 3}


def check_planes(methods: Sequence[str], planes: int) -> None:
    """Refuse, before any dot is searched, methods that cannot be fitted on ``planes``
    plate positions with distinct Z.

    Raises
    ------
    ValueError
        Naming the methods that need more planes and those that can run on these.
    """
    short = [m for m in methods if planes < MIN_PLANES[m]]
    if short:
        possible = [m for m in CALIBRATION_METHODS if planes >= MIN_PLANES[m]]
        needs = ", ".join(f"{m} needs {MIN_PLANES[m]}" for m in short)
        raise ValueError(
            f"the traverse gives {planes} plate position(s) with distinct Z: {needs}; "
            f"methods that can run on {planes}: {', '.join(possible) or 'none'}"
        )


def calibrate(
    method: str, observations: Sequence[PlaneObservation], sheet: CameraSheet
) -> CameraModel:
    """Calibrate one camera with the method called ``method``.

    Parameters
    ----------
    method : {"model-free", "tsai", "pinhole", "soloff"}
        The method (:data:`CALIBRATION_METHODS`).
    observations : sequence of PlaneObservation
        The camera's dots on each traverse plane (at least :data:`MIN_PLANES` of them
        with distinct Z).
    sheet : CameraSheet
        The camera's data-sheet values.

    Returns
    -------
    CameraModel
        The fitted calibration (``pixel_to_ray``, ``project``).

    Raises
    ------
    ValueError
        Unknown method (the message lists the known ones) or bad observations.

    Examples
    --------
    Every method on the dots of a known camera (a Tsai camera turned 20° about Y):

    >>> import numpy as np
    >>> import ptv
    >>> from scipy.spatial.transform import Rotation
    >>> turn = Rotation.from_euler("y", 20, degrees=True).as_matrix()
    >>> truth = ptv.TsaiCalibration(turn, [0, 0, 0.5], focal_length=0.05, kappa1=0.0,
    ...                             sx=1.0, principal_point=(319.5, 239.5),
    ...                             pixel_size=(1e-5, 1e-5))
    >>> ij = np.stack(np.meshgrid(np.arange(-4, 5), np.arange(-4, 5)), axis=-1).reshape(-1, 2)
    >>> xy = 4e-3 * ij  # a 9 × 9 dot plate, 4 mm pitch
    >>> planes = [
    ...     ptv.PlaneObservation(z, truth.project(np.column_stack([xy, np.full(81, z)])), xy)
    ...     for z in (-2e-3, 0.0, 2e-3)
    ... ]
    >>> sheet = ptv.CameraSheet(image_size=(640, 480), pixel_pitch=1e-5, focal_length=0.05)
    >>> point = np.array([[3e-3, -2e-3, 1e-3]])  # m
    >>> for method in ("model-free", "tsai", "pinhole", "soloff"):
    ...     fit = ptv.calibrate(method, planes, sheet)
    ...     error = np.abs(fit.project(point) - truth.project(point)).max()
    ...     print(f"{method:10s} {type(fit).__name__:21s} {error < 1e-4}")
    model-free ModelFreeCalibration  True
    tsai       TsaiCalibration       True
    pinhole    PinholeCalibration    True
    soloff     SoloffCalibration     True
    """
    try:
        fit = CALIBRATION_METHODS[method]
    except KeyError:
        raise ValueError(
            f"unknown calibration method {method!r}; known: {', '.join(CALIBRATION_METHODS)}"
        ) from None
    return fit(observations, sheet)
