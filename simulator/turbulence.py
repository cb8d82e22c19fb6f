"""Turbulence parameters (u', ε, ν) and the scales derived from them (docs/flow.md §4)."""

from dataclasses import dataclass
from math import isfinite, sqrt

#: Kinematic viscosity of water at 20 °C used by the paper, m²/s.
NU_WATER = 1.0e-6


@dataclass(frozen=True)
class TurbulenceParameters:
    """Prescribed single-point statistics of a homogeneous isotropic flow.

    Parameters
    ----------
    u_rms : float
        u', the rms of **one** velocity component, m/s.
    epsilon : float
        Mean dissipation rate ε, m²/s³.
    nu : float
        Kinematic viscosity ν, m²/s.

    Examples
    --------
    The paper's 10 Hz condition (docs/flow.md §4): η ≈ 49 µm, τ_η ≈ 2.4 ms, R_λ ≈ 339.

    >>> import simulator
    >>> flow = simulator.TurbulenceParameters(u_rms=0.19, epsilon=0.17)  # m/s, m²/s³
    >>> round(flow.eta * 1e6, 1), round(flow.tau_eta * 1e3, 3)  # µm, ms
    (49.2, 2.425)
    >>> round(flow.R_lambda, 1), round(flow.L_int * 1e2, 2)  # –, cm
    (339.1, 4.03)
    """

    u_rms: float
    epsilon: float
    nu: float = NU_WATER

    def __post_init__(self) -> None:
        for name in ("u_rms", "epsilon", "nu"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a finite number > 0, got {value!r}")

    @property
    def k_t(self) -> float:
        """Turbulent kinetic energy (3/2)u'², m²/s²."""
        return 1.5 * self.u_rms**2

    @property
    def eta(self) -> float:
        """Kolmogorov length η = (ν³/ε)^{1/4}, m."""
        return (self.nu**3 / self.epsilon) ** 0.25

    @property
    def tau_eta(self) -> float:
        """Kolmogorov time τ_η = (ν/ε)^{1/2}, s."""
        return sqrt(self.nu / self.epsilon)

    @property
    def u_eta(self) -> float:
        """Kolmogorov velocity (εν)^{1/4}, m/s."""
        return (self.epsilon * self.nu) ** 0.25

    @property
    def taylor_microscale(self) -> float:
        """λ_g = (15 ν u'²/ε)^{1/2}, m."""
        return sqrt(15.0 * self.nu * self.u_rms**2 / self.epsilon)

    @property
    def R_lambda(self) -> float:
        """Taylor-scale Reynolds number (15 u'⁴/(εν))^{1/2}."""
        return sqrt(15.0 * self.u_rms**4 / (self.epsilon * self.nu))

    @property
    def L_int(self) -> float:
        """The paper's integral scale u'³/ε, m."""
        return self.u_rms**3 / self.epsilon

    def as_dict(self) -> dict[str, float]:
        """Prescribed and derived scales in SI units, for reports and JSON."""
        return {
            "u_rms": self.u_rms,
            "epsilon": self.epsilon,
            "nu": self.nu,
            "eta": self.eta,
            "tau_eta": self.tau_eta,
            "R_lambda": self.R_lambda,
            "L_int": self.L_int,
            "taylor_microscale": self.taylor_microscale,
        }
