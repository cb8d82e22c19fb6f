"""Real plate images (examples/openptv-multiplane): every dot found and indexed from
the seed dots, where OpenPTV's own sorted dot lists put it."""

from pathlib import Path

import numpy as np
import pytest

from ptv.calibration.plate_images import find_traverse_dots, plate_setup

EXAMPLE = Path(__file__).parents[3] / "examples" / "openptv-multiplane"


@pytest.fixture(scope="module")
def dots():
    return find_traverse_dots(plate_setup(EXAMPLE))


@pytest.mark.parametrize("camera", [1, 2, 3, 4])
def test_every_dot_is_indexed_where_openptv_sorted_it(dots, camera):
    for plane in range(4):
        found = dots[f"cam{camera}"][plane]
        stem = EXAMPLE / "openptv" / "cal" / f"plane{plane + 1}_cam{camera}.tif"
        pixels = np.loadtxt(f"{stem}.crd")[:, 1:3]
        indices = np.round(np.loadtxt(f"{stem}.fix")[:, 1:3] / 5.0).astype(int)  # mm / pitch
        row = {tuple(ij): k for k, ij in enumerate(indices.tolist())}
        assert len(found.indices) == len(indices) == 405
        theirs = pixels[[row[tuple(ij)] for ij in found.indices.tolist()]]
        # OpenPTV puts (0, 0) at the top-left pixel's corner, synptv at its centre; the
        # binary dots are symmetric about whole pixels, so the centres agree exactly.
        np.testing.assert_allclose(found.pixels, theirs - 0.5, atol=1e-6)
