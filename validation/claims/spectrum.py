"""The spectrum claim: the simulated flow has Pope's model spectrum of the preset's u′, ε, ν.

The statistics claims take their references (the exact D_LL, the ε deficit) from the
flow's own spectrum, so a wrong constant in it would move the flow and its references
alike; this claim pins the spectrum to Pope's formula with his constants written apart
from the simulator (:mod:`validation.truth.pope`).
"""

import numpy as np

from simulator.spectra import PopeSpectrum
from validation.claims.base import Claim, ClaimResult, result
from validation.claims.context import ClaimContext
from validation.truth.pope import POPE_BETA, POPE_C, POPE_P0, energy_and_dissipation, pope_energy

#: Largest relative difference from the formula (rounding only).
FORMULA_TOLERANCE = 1e-9
#: Largest relative error of the energy and dissipation: the simulator solves c_L, c_η to
#: 1e-8 of its own trapezoid rule in ln k (20001 nodes), which agrees with the
#: Gauss–Legendre quadrature here to ≈ 1e-10.
INTEGRAL_TOLERANCE = 1e-6


def _pope(claim: Claim, ctx: ClaimContext) -> ClaimResult:
    p = ctx.preset.parameters
    spectrum = PopeSpectrum(p)
    k = np.geomspace(spectrum.k_min, spectrum.k_max, 2000)  # where modes are laid
    formula = pope_energy(
        k, u_rms=p.u_rms, epsilon=p.epsilon, nu=p.nu, c_l=spectrum.c_L, c_eta=spectrum.c_eta
    )
    shape = float(np.max(np.abs(spectrum.energy(k) / formula - 1)))
    energy, dissipation = energy_and_dissipation(spectrum.energy, *spectrum.support, p.nu)
    integrals = max(abs(energy / (1.5 * p.u_rms**2) - 1), abs(dissipation / p.epsilon - 1))
    value = max(shape / FORMULA_TOLERANCE, integrals / INTEGRAL_TOLERANCE)
    return result(
        claim,
        value,
        f"E(k) = Pope's formula (C = {POPE_C:g}, p₀ = {POPE_P0:g}, β = {POPE_BETA:g}, "
        f"c_L = {spectrum.c_L:.3f}, c_η = {spectrum.c_eta:.3f}) within {FORMULA_TOLERANCE:g} "
        f"(worst {shape:.1e}); ∫E = (3/2)u′², 2ν∫k²E = ε within {INTEGRAL_TOLERANCE:g} "
        f"(worst {integrals:.1e}; Gauss–Legendre in ln k); worst / tolerance ≤ 1",
        value <= 1,
    )


SPECTRUM_CLAIMS: tuple[Claim, ...] = (
    Claim(
        "flow.pope_spectrum",
        "§3 (flow set-up; docs/flow.md §2)",
        "the simulated flow has Pope's model spectrum of the preset's u′, ε and ν",
        _pope,
    ),
)
