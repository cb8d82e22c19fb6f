"""Least-squares fit of one pixel-integrated elliptical Gaussian per window (private).

Model on a (2w + 1)² window: m = A · spot(x₀, y₀, σ_x, σ_y, ρ) + B (spot of unit
integral, :func:`ptv.reconstruct._spots.spot_block`), parameters
p = (A, x₀, y₀, σ_x, σ_y, ρ, B). Levenberg–Marquardt with a forward-difference Jacobian,
unweighted (the noise of isolated spots is close enough to uniform for a width).
"""

import numpy as np
from numba import njit

from ptv.reconstruct._spots import spot_block

N_PARAMS = 7
_SIGMA_MIN, _SIGMA_MAX, _RHO_MAX = 0.2, 6.0, 0.95


@njit(cache=True, nogil=True)
def _model(p, i0, j0, n, fx, fy, block, out):  # pragma: no cover (compiled)
    spot_block(p[1], p[2], p[3], p[4], p[5], i0, j0, n, n, fx, fy, block)
    for j in range(n):
        for i in range(n):
            out[j * n + i] = p[0] * block[j, i] + p[6]


@njit(cache=True, nogil=True)
def _clamp(p, fit_rho):  # pragma: no cover (compiled)
    p[3] = min(max(p[3], _SIGMA_MIN), _SIGMA_MAX)
    p[4] = min(max(p[4], _SIGMA_MIN), _SIGMA_MAX)
    p[5] = min(max(p[5], -_RHO_MAX), _RHO_MAX) if fit_rho else 0.0


@njit(cache=True, nogil=True)
def fit_spots(image, centres, w, sigma0, fit_rho, max_iter):  # pragma: no cover (compiled)
    """Fit every window of half-width ``w`` centred on the pixel nearest to ``centres``.

    Returns (params (N, 7), rms residual (N,), ok (N,)); a window not wholly inside the
    image, or a fit that does not converge, is not ok.
    """
    rows, cols = image.shape
    n_spots = centres.shape[0]
    n = 2 * w + 1
    npx = n * n
    params = np.full((n_spots, N_PARAMS), np.nan)
    rms = np.full(n_spots, np.nan)
    ok = np.zeros(n_spots, dtype=np.bool_)
    fx = np.empty(n + 2)
    fy = np.empty(n + 2)
    block = np.empty((n, n))
    data = np.empty(npx)
    model = np.empty(npx)
    trial = np.empty(npx)
    jac = np.empty((npx, N_PARAMS))
    p = np.empty(N_PARAMS)
    q = np.empty(N_PARAMS)
    for s in range(n_spots):
        ic = int(np.floor(centres[s, 0] + 0.5))
        jc = int(np.floor(centres[s, 1] + 0.5))
        i0 = ic - w
        j0 = jc - w
        if i0 < 0 or j0 < 0 or ic + w >= cols or jc + w >= rows:
            continue
        edge_sum = 0.0
        edge_n = 0
        total = 0.0
        for j in range(n):
            for i in range(n):
                v = image[j0 + j, i0 + i]
                data[j * n + i] = v
                total += v
                if i == 0 or j == 0 or i == n - 1 or j == n - 1:
                    edge_sum += v
                    edge_n += 1
        b0 = edge_sum / edge_n
        p[0] = max(total - b0 * npx, 1e-6)
        p[1] = centres[s, 0]
        p[2] = centres[s, 1]
        p[3] = sigma0
        p[4] = sigma0
        p[5] = 0.0
        p[6] = b0
        _model(p, i0, j0, n, fx, fy, block, model)
        cost = 0.0
        for k in range(npx):
            cost += (data[k] - model[k]) ** 2
        lam = 1e-3
        converged = False
        for _ in range(max_iter):
            # forward-difference Jacobian
            for a in range(N_PARAMS):
                if a == 5 and not fit_rho:
                    for k in range(npx):
                        jac[k, a] = 0.0
                    continue
                h = 1e-6 * max(abs(p[0]), 1.0) if a == 0 else (1e-5 if a != 6 else 1e-4)
                for b in range(N_PARAMS):
                    q[b] = p[b]
                q[a] += h
                _model(q, i0, j0, n, fx, fy, block, trial)
                for k in range(npx):
                    jac[k, a] = (trial[k] - model[k]) / h
            jtj = jac.T @ jac
            grad = np.zeros(N_PARAMS)
            for k in range(npx):
                r = data[k] - model[k]
                for a in range(N_PARAMS):
                    grad[a] += jac[k, a] * r
            if not fit_rho:
                jtj[5, 5] = 1.0
            improved = False
            for _try in range(10):
                lhs = jtj.copy()
                for a in range(N_PARAMS):
                    lhs[a, a] += lam * max(jtj[a, a], 1e-12)
                step = np.linalg.solve(lhs, grad)
                for a in range(N_PARAMS):
                    q[a] = p[a] + step[a]
                _clamp(q, fit_rho)
                _model(q, i0, j0, n, fx, fy, block, trial)
                new_cost = 0.0
                for k in range(npx):
                    new_cost += (data[k] - trial[k]) ** 2
                if new_cost < cost:
                    rel = (cost - new_cost) / max(cost, 1e-300)
                    for a in range(N_PARAMS):
                        p[a] = q[a]
                    for k in range(npx):
                        model[k] = trial[k]
                    cost = new_cost
                    lam = max(lam * 0.3, 1e-9)
                    improved = True
                    if rel < 1e-9:
                        converged = True
                    break
                lam *= 10.0
            if not improved:
                converged = True  # no step lowers the cost: at the minimum
            if converged:
                break
        if converged and p[0] > 0:
            for a in range(N_PARAMS):
                params[s, a] = p[a]
            rms[s] = np.sqrt(cost / npx)
            ok[s] = True
    return params, rms, ok
