"""The Lagrangian acceleration of tracers from their positions alone: a reference for the
DNS's acceleration code that shares none of it (docs/dns.md §13).

The DNS writes, for every tracer of a shared-first-frame dataset, its exact position X
at t and at t + τ_k for the scenario's Δt set (τ_1 … τ_K), all from one start, and its
velocity v = u(X, t) (``truth.h5``, :mod:`validation.truth.truth_file`). The positions
come from the RK4 integration of dX/dt = u(X, t) on the solver's stage fields
(:mod:`simulator.dns.tracers`): they never pass through the code that forms
a = ∂u/∂t + (u·∇)u (``FlowFields.acceleration``, ``truth_at``). Their Taylor series,

    y_k = X(t + τ_k) − X(t) − v τ_k = Σ_{n=2}^{p+1} X⁽ⁿ⁾ τ_kⁿ/n! + X⁽ᵖ⁺²⁾ τ_kᵖ⁺²/(p+2)! + …,

is fitted by least squares for the p derivatives X⁽²⁾ = a, X⁽³⁾ = ȧ, …, X⁽ᵖ⁺¹⁾ = a⁽ᵖ⁻¹⁾
(:func:`fit_derivatives`; p = ``terms`` ≤ K). The positions carry no noise (float64,
RK4 errors of order h⁴ far below the τ² signal), so the estimate's only error is the
truncation of the series: to leading order

    â − a = g_p a⁽ᵖ⁾,    g_p = [B⁺]₀ · (τ_kᵖ⁺²/(p+2)!)_k   (units sᵖ),

B⁺ the fit's pseudo-inverse (:func:`truncation_gain`), and its rms over tracers is
|g_p|·rms(a⁽ᵖ⁾). The fit with p + 1 terms measures a⁽ᵖ⁾ itself (its last coefficient),
so the bound is computed from the same data (:func:`truncation_bound`). On ``dns-ci``'s
Δt set (τ_K = 0.21 τ_η) with p = 3 it is about 10⁻³ a_rms (docs/dns.md §13).
"""

from dataclasses import dataclass
from math import factorial

import numpy as np

#: Derivatives fitted by default (a, ȧ, ä): the truncation is then of order τ_K³ a⁽³⁾.
DEFAULT_TERMS = 3


def _checked_times(times: np.ndarray) -> np.ndarray:
    times = np.asarray(times, dtype=float)
    if times.ndim != 1 or len(times) < 2 or times[0] != 0 or np.any(np.diff(times) <= 0):
        raise ValueError(f"times must start at 0 and increase strictly, got {times}")
    return times


def _scaled_design(times: np.ndarray, terms: int) -> tuple[np.ndarray, float]:
    """B̃[k, n] = s_kⁿ⁺²/(n+2)! with s = τ/τ_K (K × terms), and τ_K."""
    tau = times[1:]
    if not 1 <= terms <= len(tau):
        raise ValueError(f"terms must be in 1 … {len(tau)} (the Δt values), got {terms!r}")
    scale = float(tau[-1])
    s = tau / scale
    powers = np.arange(2, terms + 2)
    design = s[:, None] ** powers / np.array([factorial(n) for n in powers], dtype=float)
    return design, scale


def fit_derivatives(
    times: np.ndarray,
    positions: np.ndarray,
    velocity: np.ndarray,
    *,
    terms: int = DEFAULT_TERMS,
) -> np.ndarray:
    """The time derivatives a, ȧ, … of tracers from positions on a common start.

    Parameters
    ----------
    times : ndarray, shape (T,)
        0, τ_1, …, τ_K: times after the start, s, strictly increasing.
    positions : ndarray, shape (..., T, P, 3)
        X of P tracers at those times, m.
    velocity : ndarray, shape (..., P, 3)
        Their exact velocity at the start, m/s.
    terms : int
        Derivatives fitted, 1 ≤ terms ≤ K.

    Returns
    -------
    ndarray, shape (terms, ..., P, 3)
        X⁽ⁿ⁺²⁾ for n = 0 … terms − 1: the acceleration (m/s²), its time derivative
        (m/s³), and so on.
    """
    times = _checked_times(times)
    positions = np.asarray(positions, dtype=float)
    velocity = np.asarray(velocity, dtype=float)
    if positions.ndim < 3 or positions.shape[-3] != len(times) or positions.shape[-1] != 3:
        raise ValueError(
            f"positions must have shape (..., {len(times)}, P, 3), got {positions.shape}"
        )
    if velocity.shape != positions.shape[:-3] + positions.shape[-2:]:
        raise ValueError(
            f"velocity must have shape {positions.shape[:-3] + positions.shape[-2:]}, "
            f"got {velocity.shape}"
        )
    design, scale = _scaled_design(times, terms)
    inverse = np.linalg.pinv(design)  # (terms, K)
    tau = times[1:, None, None]
    start = positions[..., :1, :, :]
    y = positions[..., 1:, :, :] - start - tau * velocity[..., None, :, :]
    scaled = np.einsum("nk,...kpc->n...pc", inverse, y)
    powers = np.arange(2, terms + 2).reshape((terms,) + (1,) * (scaled.ndim - 1))
    return scaled / scale**powers


def acceleration_from_positions(
    times: np.ndarray, positions: np.ndarray, velocity: np.ndarray, *, terms: int = DEFAULT_TERMS
) -> np.ndarray:
    """The Lagrangian acceleration of :func:`fit_derivatives`, shape (..., P, 3), m/s²."""
    return fit_derivatives(times, positions, velocity, terms=terms)[0]


def truncation_gain(times: np.ndarray, terms: int = DEFAULT_TERMS) -> float:
    """g_p: the leading error of the fitted acceleration per unit a⁽ᵖ⁾, â − a = g_p a⁽ᵖ⁾.

    Parameters
    ----------
    times : ndarray, shape (T,)
        0, τ_1, …, τ_K, s.
    terms : int
        p, the derivatives fitted.

    Returns
    -------
    float
        g_p, sᵖ (the fit's row for a applied to τᵖ⁺²/(p+2)!).
    """
    times = _checked_times(times)
    design, scale = _scaled_design(times, terms)
    s = times[1:] / scale
    column = s ** (terms + 2) / factorial(terms + 2)
    return float(np.linalg.pinv(design)[0] @ column) * scale**terms


@dataclass(frozen=True)
class TruncationBound:
    """How far the fitted acceleration can lie from the exact one (module docstring).

    Attributes
    ----------
    terms : int
        p, the derivatives of the fit.
    gain : float
        g_p, sᵖ.
    derivative_rms : float
        rms of one component of a⁽ᵖ⁾ over the tracers, from the fit with p + 1 terms,
        m/s^(p+2).
    acceleration_rms : float
        rms of one component of the fitted a, m/s².
    next_order_rms : float
        rms of one component of the difference between the fits with p and p + 1 terms
        (what the next term changes: the truncation, measured), m/s².
    """

    terms: int
    gain: float
    derivative_rms: float
    acceleration_rms: float
    next_order_rms: float

    @property
    def error_rms(self) -> float:
        """|g_p|·rms(a⁽ᵖ⁾): the leading truncation error, rms per component, m/s²."""
        return abs(self.gain) * self.derivative_rms

    @property
    def relative(self) -> float:
        """:attr:`error_rms` over the acceleration's rms."""
        return self.error_rms / self.acceleration_rms

    def as_dict(self) -> dict:
        """JSON-able form (SI)."""
        return {
            "terms": self.terms,
            "gain": self.gain,
            "derivative_rms": self.derivative_rms,
            "acceleration_rms": self.acceleration_rms,
            "error_rms": self.error_rms,
            "relative": self.relative,
            "next_order_rms_relative": self.next_order_rms / self.acceleration_rms,
        }


def truncation_bound(
    times: np.ndarray, positions: np.ndarray, velocity: np.ndarray, *, terms: int = DEFAULT_TERMS
) -> TruncationBound:
    """The leading truncation error of :func:`acceleration_from_positions`, measured on
    the same tracers: g_p times the rms of a⁽ᵖ⁾ from the fit with p + 1 terms.

    Parameters
    ----------
    times, positions, velocity
        As :func:`fit_derivatives`.
    terms : int
        p; p + 1 ≤ K (the Δt values) is needed.

    Returns
    -------
    TruncationBound
    """
    times = _checked_times(times)
    if terms + 1 > len(times) - 1:
        raise ValueError(
            f"the bound fits {terms + 1} derivatives: it needs that many Δt values, "
            f"got {len(times) - 1}"
        )
    lower = fit_derivatives(times, positions, velocity, terms=terms)
    upper = fit_derivatives(times, positions, velocity, terms=terms + 1)
    return TruncationBound(
        terms=terms,
        gain=truncation_gain(times, terms),
        derivative_rms=float(np.sqrt(np.mean(upper[-1] ** 2))),
        acceleration_rms=float(np.sqrt(np.mean(lower[0] ** 2))),
        next_order_rms=float(np.sqrt(np.mean((lower[0] - upper[0]) ** 2))),
    )
