"""Constant-power forcing of the lowest wavenumbers (docs/dns.md §2).

f̂(k) = ε/(2E_f) û(k) on the band 0 < |k| ≤ k_f and 0 elsewhere, where E_f is the kinetic
energy of that band. The power it injects, ⟨u·f⟩ = (ε/(2E_f))·2E_f = ε, is the
prescribed ε at every instant, whatever the state: the mean dissipation of the
stationary flow is known in advance. f is parallel to û, so it is divergence-free, and
the band lies inside the modes the 2/3 rule keeps.
"""

from dataclasses import dataclass
from math import isfinite

import numpy as np

from simulator.dns.grid import Grid

#: Default upper edge of the forced band, in units of the box wavenumber 2π/L.
DEFAULT_BAND = 2.0


@dataclass(frozen=True)
class ConstantPowerForcing:
    """Forcing that injects a prescribed power.

    Parameters
    ----------
    epsilon : float
        Injection rate ε, m²/s³.
    band : float
        k_f/(2π/L): modes with 0 < |k| ≤ k_f are forced (default 2: 32 modes).

    Examples
    --------
    Whatever the state, the forcing puts in ε (docs/dns.md §2):

    >>> import simulator
    >>> setup = simulator.dns_setup(1e-6, 0.1, 32)
    >>> forcing = simulator.ConstantPowerForcing(0.1)  # ε, m²/s³
    >>> solver = simulator.NavierStokesSolver(setup.grid, nu=1e-6, forcing=forcing)
    >>> state = simulator.initial_state(solver, rng=3)
    >>> round(solver.injection(state), 12)  # ⟨u·f⟩, m²/s³
    0.1
    """

    epsilon: float
    band: float = DEFAULT_BAND

    def __post_init__(self) -> None:
        for name in ("epsilon", "band"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
            if not (isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
        if self.band < 1.0:
            raise ValueError(f"band must be at least 1 (no mode below), got {self.band}")


class ForcedBand:
    """The forced modes of one grid and the forcing they receive.

    Parameters
    ----------
    grid : Grid
        The grid; the band must lie inside its 2/3-rule cut-off.
    forcing : ConstantPowerForcing
        Rate and band.
    """

    def __init__(self, grid: Grid, forcing: ConstantPowerForcing) -> None:
        if forcing.band * grid.k0 >= grid.kmax:
            raise ValueError(
                f"band = {forcing.band} reaches the cut-off k_max/(2π/L) = {grid.n / 3:.3g}"
            )
        kx, ky, kz = grid.wavenumbers()
        k2 = kx[:, None, None] ** 2 + ky[None, :, None] ** 2 + kz[None, None, :] ** 2
        kf2 = (forcing.band * grid.k0) ** 2 * (1.0 + 1e-12)  # shells exactly at k_f included
        self.forcing = forcing
        self.index = np.nonzero((k2 > 0.0) & (k2 <= kf2))
        self.weights = grid.mode_weights()[self.index[2]]
        self._norm = float(grid.n) ** 6

    @property
    def modes(self) -> int:
        """Modes of the full spectrum that are forced (each conjugate pair counts twice)."""
        return int(self.weights.sum())

    def energy(self, uh: np.ndarray) -> float:
        """Kinetic energy E_f of the band, m²/s², from coefficients of shape (3, N, N, M)."""
        band = uh[(slice(None), *self.index)]
        return 0.5 * float(np.sum(self.weights * np.sum(np.abs(band) ** 2, axis=0))) / self._norm

    def coefficient(self, uh: np.ndarray) -> float:
        """ε/(2E_f), 1/s.

        Raises
        ------
        ValueError
            The band holds no energy (a state that the forcing cannot drive).
        """
        e_f = self.energy(uh)
        if not e_f > 0.0:
            raise ValueError("the forced band holds no energy: the forcing cannot inject ε")
        return self.forcing.epsilon / (2.0 * e_f)

    def add_to(self, out: np.ndarray, uh: np.ndarray) -> None:
        """out += f̂(û) on the band (both of shape (3, N, N, M), complex)."""
        where = (slice(None), *self.index)
        out[where] += self.coefficient(uh) * uh[where]

    def injection(self, uh: np.ndarray) -> float:
        """Power ⟨u·f⟩ the forcing puts into state û, m²/s³ (ε by construction)."""
        where = (slice(None), *self.index)
        f = self.coefficient(uh) * uh[where]
        product = np.sum((np.conj(uh[where]) * f).real, axis=0)
        return float(np.sum(self.weights * product)) / self._norm
