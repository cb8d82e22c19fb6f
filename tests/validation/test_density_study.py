"""The density study's points: tracers from the density of the volume's image."""

import numpy as np
import pytest
from matplotlib.path import Path as Polygon
from scipy.spatial import ConvexHull

from simulator.rigs import load_rig
from validation.run.scenario import load_scenario
from validation.studies.density import DENSITIES_PPP, volume_image_area
from validation.studies.rendered import study_points


def _hull_area(camera, box) -> float:
    """Pixels of the sensor inside the convex hull of the volume's 8 projected corners
    (perspective keeps a box convex; a flat window bends its edges by far less than a
    pixel here), counted on the pixel centres: apart from the study's random points."""
    lower, upper = box
    corners = np.array([[x, y, z] for x in (lower[0], upper[0]) for y in (lower[1], upper[1])
                        for z in (lower[2], upper[2])])  # fmt: skip
    xy = camera.project(corners)
    hull = Polygon(xy[ConvexHull(xy).vertices])
    width, height = camera.lens.sensor_size
    grid = np.stack(np.meshgrid(np.arange(width) + 0.5, np.arange(height) + 0.5), -1)
    return float(hull.contains_points(grid.reshape(-1, 2)).sum())


def test_the_volume_image_area_is_the_projected_volume_on_the_sensor():
    rig = load_rig("lpt-challenge-small")
    centre, size = np.asarray(rig.sheet.centre), np.asarray(rig.sheet.size)
    box = (centre - size / 2, centre + size / 2)
    exact = np.mean([_hull_area(camera, box) for camera in rig.cameras])
    # 8 px cells overstate the area by about half a cell along the outline (~2 %)
    assert volume_image_area(rig) == pytest.approx(exact, rel=0.03)
    assert volume_image_area(rig) >= exact


def test_density_points_sweep_the_challenge_densities_from_the_scenario():
    scenario = load_scenario("dense-ci")
    points = study_points("density", scenario, 2)
    assert [p.params["ppp"] for p in points] == [*DENSITIES_PPP, *DENSITIES_PPP]
    area = volume_image_area(load_rig("lpt-challenge-small"))
    for point in points:
        assert point.scenario.particles.count == round(point.params["ppp"] * area)
        assert point.scenario.particles.count == point.params["tracers"]
        assert point.scenario.ipr == scenario.ipr
    # dense-ci itself is the 0.05 point, to the rounding of its count
    at_005 = next(p for p in points if p.params["ppp"] == 0.05)
    assert at_005.scenario.particles.count == pytest.approx(9300, rel=0.01)
    assert {p.scenario.seed for p in points} == {0, 1}
    assert len({p.work for p in points}) == len(points)  # each renders anew
