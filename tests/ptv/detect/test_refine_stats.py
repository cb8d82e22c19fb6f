"""The fit statistics the noise model is measured from, against a NumPy reference
(model from scipy's erf, Jacobian by central differences, hat matrix by np.linalg)."""

import numpy as np
import pytest
from scipy.special import erf

from ptv.detect import _refine

SIDE = 2 * _refine.HALF + 1


def _model(params, rows, cols, fixed):
    """B + fixed + A·Ex·Ey on the window's pixels (pixel-integrated Gaussian)."""
    a, x0, y0, s, b = params

    def mass(edges, centre):
        return 0.5 * (
            erf((edges + 0.5 - centre) / (np.sqrt(2) * s))
            - erf((edges - 0.5 - centre) / (np.sqrt(2) * s))
        )

    return b + fixed + a * mass(cols, x0) * mass(rows, y0)


def _reference(img, params, rows, cols, fixed):
    model = _model(params, rows, cols, fixed)
    resid = img[rows, cols] - model
    steps = 1e-6 * np.maximum(np.abs(params), 1.0)
    jac = np.empty((rows.size, params.size))
    for k, h in enumerate(steps):
        up, down = params.copy(), params.copy()
        up[k] += h
        down[k] -= h
        jac[:, k] = (_model(up, rows, cols, fixed) - _model(down, rows, cols, fixed)) / (2 * h)
    hat = np.einsum("pu,uv,pv->p", jac, np.linalg.inv(jac.T @ jac), jac)
    light = model - params[4]
    grid = resid.reshape(SIDE, SIDE)
    adjacent = np.sum(grid[:, :-1] * grid[:, 1:]) + np.sum(grid[:-1, :] * grid[1:, :])
    return np.sum(resid**2), np.sum((1 - hat) * light), adjacent


@pytest.mark.parametrize("seed", range(5))
def test_lone_spot_statistics_against_numpy(seed):
    rng = np.random.default_rng(seed)
    img = rng.normal(100.0, 5.0, (30, 30))
    work = _refine.workspace(1)
    for _ in range(20):
        x, y = rng.uniform(8, 22, 2)
        params = np.array(
            [rng.uniform(300, 3e4), x, y, rng.uniform(0.5, 1.5), rng.uniform(90, 110)]
        )
        r0, c0 = int(y + 0.5), int(x + 0.5)
        rows, cols = np.mgrid[r0 - 2 : r0 + 3, c0 - 2 : c0 + 3]
        rows, cols = rows.ravel().astype(np.int64), cols.ravel().astype(np.int64)
        fixed = rng.uniform(0.0, 50.0, SIDE * SIDE)  # light of neighbours held fixed
        out = np.zeros(5)
        _refine._lone_spot_stats(img, rows, cols, params, work, fixed, out)
        square, residual_light, adjacent = _reference(img, params, rows, cols, fixed)
        assert out[0] == pytest.approx(square, rel=1e-9)
        assert out[1] == pytest.approx(residual_light, rel=1e-5)
        assert out[4] == pytest.approx(adjacent, rel=1e-9, abs=1e-6 * square)
