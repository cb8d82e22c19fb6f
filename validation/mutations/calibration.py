"""Mutations of the calibration and triangulation (``ptv.calibration``, ``ptv.triangulate``)
and of the synthetic dots they are fitted on, caught by the ``calib`` claims."""

from dataclasses import replace

import numpy as np

from ptv import triangulate
from ptv.calibration import model_free, tsai
from ptv.calibration.observations import PlaneObservation
from simulator.rigs import load_rig
from simulator.target import Imperfections, PlateDesign, build_plate, traverse_positions
from validation.mutations.base import Mutation
from validation.mutations.patching import Patch, edited
from validation.mutations.probes import POINTS, PinholeProbe, stereo_pair
from validation.truth import calibration_errors


def _model_free_calibration():
    """A model-free calibration of a probe camera whose dots are bent by a cubic term."""
    camera = PinholeProbe([0.0, 0.0, -0.5], focal_px=2000.0)
    u = np.linspace(-0.05, 0.05, 9)
    xy = np.stack(np.meshgrid(u, u), axis=-1).reshape(-1, 2)
    observations = []
    for z in (-0.005, 0.005):
        pixels = camera.project(np.column_stack([xy, np.full(len(xy), z)])) + 256.0
        pixels += 2.0 * ((pixels - 256.0) / 200.0) ** 3
        observations.append(PlaneObservation(z, pixels, xy))
    return model_free.calibrate_model_free(observations, (512, 512))


def _model_free_planes():
    """Plane-map degree and largest T_j⁻¹ residual of the probe's model-free calibration."""
    plane = _model_free_calibration().planes[0]
    return np.array([plane.to_world.degree, plane.residual_px.max()])


def _model_free_rays():
    """Rays of a few pixels of the probe's model-free calibration."""
    calibration = _model_free_calibration()
    rays = calibration.pixel_to_ray(np.array([[200.0, 220.0], [300.0, 260.0]]))
    return np.concatenate([rays.origins, rays.directions])


def _triangulated():
    cameras = stereo_pair()
    return triangulate.triangulate(cameras, [c.project(POINTS) for c in cameras]).points


def _tsai_rays():
    camera = tsai.TsaiCalibration(
        rotation=np.eye(3),
        translation=np.array([0.0, 0.0, 0.5]),
        focal_length=0.05,
        kappa1=200.0,
        sx=1.0,
        principal_point=(256.0, 256.0),
        pixel_size=(5.5e-6, 5.5e-6),
    )
    return camera.pixel_to_ray(np.array([[0.0, 0.0], [400.0, 100.0]])).directions


def _dots():
    plate = build_plate(PlateDesign(), traverse_positions(), imperfections=Imperfections(), rng=0)
    cameras = load_rig("conventional").cameras
    return calibration_errors.synthetic_plane_dots(cameras, plate, noise_px=0.05, rng=1)[0][
        0
    ].pixels


def _table1():
    delta = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 1.0]])
    return np.array(
        [calibration_errors.PositionErrors(np.zeros((2, 3)), delta, np.zeros(2, dtype=int)).d]
    )


def _shifted(offset: tuple[float, float, float]):
    """A ``triangulate`` whose points are moved by ``offset``, m."""

    def make(original):
        def triangulate(cameras, pixels):
            result = original(cameras, pixels)
            return replace(result, points=result.points + np.asarray(offset))

        return triangulate

    return make


def _noisier(factor: float):
    """A ``synthetic_plane_dots`` whose centre noise is ``factor`` times the one asked for."""

    def make(original):
        def synthetic_plane_dots(cameras, plate, *, noise_px, **options):
            return original(cameras, plate, noise_px=factor * noise_px, **options)

        return synthetic_plane_dots

    return make


def _plane_degree(degree: int) -> Patch:
    return Patch(
        "ptv.calibration.model_free:calibrate_model_free",
        edited("degree: int = 3,", f"degree: int = {degree},"),
    )


CALIBRATION_MUTATIONS: tuple[Mutation, ...] = (
    Mutation(
        "plane-maps-quadratic",
        "the model-free calibration fits quadratic plane maps T_j (6 terms) instead of cubic",
        (_plane_degree(2),),
        ("calib.plane_fit_residual", "calib.noise_limited", "calib.model_error"),
        ("calib",),
        _model_free_planes,
    ),
    Mutation(
        "plane-maps-linear",
        "the model-free calibration fits linear plane maps T_j (3 terms) instead of cubic",
        (_plane_degree(1),),
        ("calib.plane_fit_residual", "calib.noise_limited", "calib.model_error"),
        ("calib",),
        _model_free_planes,
    ),
    Mutation(
        "rays-from-first-plane",
        "the model-free rays start on the first calibration plane instead of at Z̄, where "
        "their coefficients were fitted",
        (
            Patch(
                "ptv.calibration.model_free:calibrate_model_free",
                edited("z_ref=z_ref,", "z_ref=float(z.min()),"),
            ),
        ),
        ("calib.noise_limited", "calib.model_error", "calib.sub_pixel"),
        ("calib",),
        _model_free_rays,
    ),
    Mutation(
        "table1-root-sum-square",
        "Table 1's d as √(d_X² + d_Y² + d_Z²) instead of the mean 3-D distance (docs/errata.md E6)",
        (
            Patch(
                "validation.truth.calibration_errors:PositionErrors.d",
                edited(
                    "np.nanmean(np.linalg.norm(self.delta, axis=1))",
                    "np.linalg.norm(np.nanmean(np.abs(self.delta), axis=0))",
                ),
            ),
        ),
        ("calib.table1_mean_distance", "calib.noise_limited"),
        ("calib",),
        _table1,
    ),
    Mutation(
        "triangulation-z-10um",
        "every triangulated point 10 µm too far along Z",
        (Patch("ptv.triangulate:triangulate", _shifted((0.0, 0.0, 10e-6))),),
        ("calib.noise_limited", "calib.model_error"),
        ("calib",),
        _triangulated,
    ),
    Mutation(
        "triangulation-x-10um",
        "every triangulated point 10 µm too far along X",
        (Patch("ptv.triangulate:triangulate", _shifted((10e-6, 0.0, 0.0))),),
        ("calib.noise_limited", "calib.model_error"),
        ("calib",),
        _triangulated,
    ),
    Mutation(
        "tsai-distortion-sign",
        "Tsai's pixel → ray applies the radial term with the wrong sign (X_u = X_d(1 − κ₁ρ_d²)) "
        "while its fit and projection use the right one",
        (
            Patch(
                "ptv.calibration.tsai:TsaiCalibration.pixel_to_ray",
                edited("factor = 1.0 + self.kappa1", "factor = 1.0 - self.kappa1"),
            ),
        ),
        ("calib.similar_conventional",),
        ("calib",),
        _tsai_rays,
    ),
    Mutation(
        "dot-noise-doubled",
        "the synthetic calibration dots carry twice the centre noise the claims are told of",
        (Patch("validation.truth.calibration_errors:synthetic_plane_dots", _noisier(2.0)),),
        ("calib.noise_limited", "calib.plane_fit_residual"),
        ("calib",),
        _dots,
    ),
)
