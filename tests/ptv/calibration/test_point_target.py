"""One camera from one image of a 3-D target of listed points: the target file, the
seed camera, the association and the fit, on images of known cameras."""

import cv2
import numpy as np
import pytest

from ptv.calibration.io import load_calibrations, save_calibrations
from ptv.calibration.pinhole import PinholeCalibration, PinholeModel, project_parameters
from ptv.calibration.point_target import (
    PointTarget,
    associate,
    calibrate_point_target,
    read_target_points,
    seed_camera,
)
from ptv.calibration.refractive_pinhole import FlatWindow
from simulator.optics.forward import solve_chief_rays
from simulator.optics.interfaces import FlatInterfaces

SIZE = (800, 600)
#: Dot image: Gaussian σ (px), peak and background (DN), read noise σ (DN).
DOT_SIGMA, PEAK, BACKGROUND, NOISE = 1.3, 160.0, 20.0, 2.0


def stepped_target() -> np.ndarray:
    """A MyPTV-like stepped target, m: a 3 mm grid, 15 × 12 points, on three levels
    (0, −6 and −12 mm) in bands of X."""
    x, y = np.meshgrid(np.arange(15) * 3e-3, np.arange(12) * 3e-3)
    x, y = x.ravel(), y.ravel()
    z = np.where(x < 12e-3, 0.0, np.where(x < 30e-3, -6e-3, -12e-3))
    return np.column_stack([x, y, z])


def true_camera(k1: float = -0.15, centre=(0.02, 0.016, 0.5)) -> np.ndarray:
    """Full pinhole parameters of a camera 0.5 m in front of the target, aimed at it,
    f = 6000 px, principal point off centre, radial and tangential distortion."""
    centre = np.asarray(centre)
    aim = np.array([0.021, 0.0165, -0.006])
    z = (aim - centre) / np.linalg.norm(aim - centre)
    x = np.cross([0.0, 1.0, 0.0], z)
    x /= np.linalg.norm(x)
    rot = np.array([x, np.cross(z, x), z])
    params = np.zeros(17)
    params[:4] = 6000.0, 6010.0, 410.0, 290.0
    params[4:8] = k1, 0.3, 4e-4, -3e-4
    params[11:14] = cv2.Rodrigues(rot)[0].ravel()
    params[14:17] = -rot @ centre
    return params


def render(params: np.ndarray, points: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """An 8-bit image of the target's dots (pixel-sampled Gaussians) with read noise and
    a few specks."""
    return dot_image(project_parameters(params, points)[0], rng)


def dot_image(xy: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """An 8-bit image of dots at pixels ``xy`` (N, 2), with read noise and specks."""
    rows, cols = np.mgrid[0 : SIZE[1], 0 : SIZE[0]]
    image = np.full((SIZE[1], SIZE[0]), BACKGROUND)
    for x, y in xy:
        r0, c0 = round(y), round(x)
        sl = np.s_[max(r0 - 6, 0) : r0 + 7, max(c0 - 6, 0) : c0 + 7]
        d2 = (cols[sl] - x) ** 2 + (rows[sl] - y) ** 2
        image[sl] += PEAK * np.exp(-d2 / (2 * DOT_SIGMA**2))
    for x, y in rng.uniform([20, 20], [SIZE[0] - 20, SIZE[1] - 20], size=(15, 2)):
        image[int(y), int(x)] += 120.0  # a one-pixel speck: below min_dot_area
    image += rng.normal(0.0, NOISE, image.shape)
    return np.clip(np.round(image), 0, 255).astype(np.uint8)


def seeds_of(params, points, rows, rng, error_px=1.5) -> dict:
    xy, _ = project_parameters(params, points[rows])
    return {
        int(r): tuple(p + rng.uniform(-error_px, error_px, 2))
        for r, p in zip(rows, xy, strict=True)
    }


SEED_ROWS = [0, 14, 165, 179, 7, 90]


def test_a_known_camera_is_recovered_from_its_image_and_six_rough_seeds():
    rng = np.random.default_rng(3)
    points = stepped_target()
    truth = true_camera()
    target = PointTarget(points, np.arange(len(points)))
    fit = calibrate_point_target(
        render(truth, points, rng), target, seeds_of(truth, points, SEED_ROWS, rng)
    )
    assert len(fit.rows) == len(points)  # every dot found and no speck taken
    expected, _ = project_parameters(truth, points[fit.rows])
    assert np.median(np.linalg.norm(fit.pixels - expected, axis=1)) < 0.1
    # Reprojection at the level of the dot centres' noise (a few hundredths of a px).
    assert fit.rms < 0.08
    assert_projects_like(fit.calibration, truth, 0.15)


def assert_projects_like(calibration, truth, tolerance_px):
    """The camera, not only the fitted points: a volume 10 mm deeper and shallower than
    the target projects where the true camera puts it."""
    grid = np.stack(
        np.meshgrid(
            np.linspace(0, 42e-3, 6), np.linspace(0, 33e-3, 5), np.linspace(-22e-3, 10e-3, 5)
        ),
        axis=-1,
    ).reshape(-1, 3)
    true_xy, _ = project_parameters(truth, grid)
    assert np.max(np.linalg.norm(calibration.project(grid) - true_xy, axis=1)) < tolerance_px


def test_the_principal_point_stays_at_the_centre_when_the_target_asks():
    rng = np.random.default_rng(4)
    points = stepped_target()
    truth = true_camera()
    truth[2:4] = (SIZE[0] - 1) / 2, (SIZE[1] - 1) / 2
    target = PointTarget(
        points, np.arange(len(points)), model=PinholeModel(("k1",), fixed_principal_point=True)
    )
    truth[5:8] = 0.0  # k1 only
    fit = calibrate_point_target(
        render(truth, points, rng), target, seeds_of(truth, points, SEED_ROWS, rng)
    )
    assert fit.calibration.params[2:4] == pytest.approx(truth[2:4])
    assert fit.rms < 0.08 and len(fit.rows) == len(points)
    assert_projects_like(fit.calibration, truth, 0.15)


def test_a_fixed_principal_point_survives_the_calibration_file(tmp_path):
    points = stepped_target()
    truth = true_camera()
    model = PinholeModel(("k1", "k2"), fixed_principal_point=True)
    camera = PinholeCalibration(SIZE, model, truth, 0.1, "test", n_points=len(points))
    save_calibrations(tmp_path / "pinhole.h5", {"cam1": camera, "cam2": camera})
    back = load_calibrations(tmp_path / "pinhole.h5")["cam2"]
    assert back.model == model and back.model.name == "k1,k2+fixed pp"
    np.testing.assert_array_equal(back.project(points), camera.project(points))


def test_a_seed_on_the_wrong_point_is_named():
    rng = np.random.default_rng(5)
    points = stepped_target()
    truth = true_camera()
    seeds = seeds_of(truth, points, SEED_ROWS, rng)
    seeds[165], seeds[179] = seeds[179], seeds[165]  # two seeds swapped
    target = PointTarget(points, np.arange(len(points)) + 1)
    with pytest.raises(ValueError, match=r"cal\.tif: the seed points do not fit one camera"):
        calibrate_point_target(render(truth, points, rng), target, seeds, source="cal.tif")


def test_the_seed_camera_fits_exact_seeds_of_an_undistorted_camera():
    points = stepped_target()
    truth = true_camera(k1=0.0)
    truth[2:4] = (SIZE[0] - 1) / 2, (SIZE[1] - 1) / 2
    truth[1] = truth[0]
    truth[4:9] = 0.0
    rows = SEED_ROWS[:4]
    xy, _ = project_parameters(truth, points[rows])
    params, residuals = seed_camera(points[rows], xy, SIZE)
    assert residuals.max() < 1e-6
    assert params[0] == pytest.approx(truth[0], rel=1e-6)


def test_association_pairs_mutual_nearest_neighbours_only():
    predicted = np.array([[10.0, 10.0], [12.0, 10.0], [50.0, 50.0], [np.nan, np.nan]])
    blobs = np.array([[10.5, 10.0], [80.0, 80.0], [49.0, 50.0]])
    rows, blob_rows = associate(predicted, blobs, tolerance=3.0)
    # Point 1 is within reach of blob 0 but point 0 is nearer it; blob 1 is too far.
    assert rows.tolist() == [0, 2] and blob_rows.tolist() == [0, 2]


# -- the target file -------------------------------------------------------------------


def test_target_files_with_or_without_ids_in_mm_or_m(tmp_path):
    path = tmp_path / "target_file"
    path.write_text("# X Y Z\n0\t0\t0\n\n3.0 0 -6\n")
    ids, points = read_target_points(path, "mm")
    assert ids.tolist() == [0, 1] and points.tolist() == [[0, 0, 0], [3e-3, 0, -6e-3]]
    path.write_text("7 1 2 3\n9 4 5 6\n")
    ids, points = read_target_points(path, "m")
    assert ids.tolist() == [7, 9] and points.tolist() == [[1, 2, 3], [4, 5, 6]]


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("0 0 0\n1 2\n", r"line 2: expected 3, got '1 2'"),
        ("0 0\n", r"line 1: expected 3 numbers \(X Y Z\) or 4 \(id X Y Z\)"),
        ("0 0 0\n1 x 2\n", "line 2: expected 3, got '1 x 2'"),
        ("1 0 0 0\n1 1 0 0\n", "line 1: id 1 appears again later"),
        ("1.5 0 0 0\n", r"line 1: the id '1.5' is not an integer"),
        ("0 0 0\n1 1 1\n0 0 0\n", "line 1: the same point appears again later"),
        ("# nothing\n", "no target points"),
    ],
)
def test_a_bad_target_file_is_named_with_its_line(tmp_path, text, message):
    path = tmp_path / "target_file"
    path.write_text(text)
    with pytest.raises(ValueError, match=f"{path}: {message}"):
        read_target_points(path, "mm")


def test_a_missing_target_file_and_unknown_units(tmp_path):
    with pytest.raises(FileNotFoundError, match=r"target points file .* is missing"):
        read_target_points(tmp_path / "none", "mm")
    (tmp_path / "t").write_text("0 0 0\n")
    with pytest.raises(ValueError, match="units must be one of m, mm, got 'cm'"):
        read_target_points(tmp_path / "t", "cm")


def test_a_flat_target_cannot_calibrate_from_one_image():
    points = stepped_target()
    points[:, 2] = 0.0
    with pytest.raises(ValueError, match="all target points lie in one plane"):
        PointTarget(points, np.arange(len(points)))
    with pytest.raises(ValueError, match="at least 12 points"):
        PointTarget(stepped_target()[:5], np.arange(5))


def test_a_camera_behind_a_window_is_recovered_from_its_image():
    """Rendered through air, glass and water by the simulator's ray optics: the
    straight-ray pinhole misplaces the camera by tens of mm, the pinhole fitted through
    the window finds it, and projects a volume 18 mm deeper than the target as the
    truth does."""
    rng = np.random.default_rng(8)
    points = stepped_target()
    truth_params = true_camera()
    window = FlatWindow([0.0, 0.0, 1.0], 0.02, 0.008, 1.49, 1.33)
    stack = FlatInterfaces([0.0, 0.0, -1.0], [-0.028, -0.02], window.indices)
    centre = -cv2.Rodrigues(truth_params[11:14])[0].T @ truth_params[14:17]

    def through_window(world: np.ndarray) -> np.ndarray:
        directions = solve_chief_rays(centre, world, stack).directions
        return project_parameters(truth_params, centre + directions)[0]

    image = dot_image(through_window(points), rng)
    seeds = {int(r): tuple(through_window(points[[r]])[0] + rng.uniform(-1.5, 1.5, 2))
             for r in SEED_ROWS}  # fmt: skip
    target = PointTarget(points, np.arange(len(points)))
    straight = calibrate_point_target(image, target, seeds)
    fit = calibrate_point_target(image, target, seeds, window=window)
    assert len(fit.rows) == len(points)
    assert fit.rms < 0.08  # the dot centres' noise
    assert np.linalg.norm(fit.calibration.centre - centre) < 1e-3
    assert np.linalg.norm(straight.calibration.centre - centre) > 0.01
    volume = np.stack(
        np.meshgrid(np.linspace(0, 42e-3, 6), np.linspace(0, 33e-3, 5),
                    np.linspace(-30e-3, 10e-3, 5)),
        axis=-1,
    ).reshape(-1, 3)  # fmt: skip
    error = np.linalg.norm(fit.calibration.project(volume) - through_window(volume), axis=1)
    assert error.max() < 0.15
