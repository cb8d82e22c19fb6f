"""Hypothesis: the exact D_LL tends to 2u'² at large r and to εr²/(15ν) at small r."""

from math import factorial, fsum

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from simulator.spectra import KolmogorovBandSpectrum, PopeSpectrum
from simulator.truth import longitudinal_structure_function, structure_kernel
from simulator.turbulence import TurbulenceParameters

flows = st.builds(
    TurbulenceParameters,
    u_rms=st.floats(0.02, 1.0),
    epsilon=st.floats(1e-3, 3.0),
    nu=st.floats(3e-7, 3e-6),
).filter(lambda p: 30 <= p.R_lambda <= 3000)
spectra = st.sampled_from([PopeSpectrum, KolmogorovBandSpectrum])


@given(p=flows, kind=spectra)
def test_dll_limits(p, kind):
    s = kind(p)
    eps = s.dissipation()  # = ε within 0.5 % (tested in test_spectra)
    small = np.array([1e-4, 1e-3]) * p.eta
    assert np.allclose(
        longitudinal_structure_function(s, small), eps * small**2 / (15 * p.nu), rtol=1e-5
    )
    # The oscillating tail of G decays as 1/(k_min r)²: at r = 2000 / k_min it is < 1e-6.
    large = np.array([2e3, 1e4]) / s.support[0]
    assert np.allclose(longitudinal_structure_function(s, large), 2 * p.u_rms**2, rtol=2e-3)


@given(x=st.floats(1e-6, 2.0))
def test_structure_kernel_is_accurate_where_the_closed_form_cancels(x):
    # G(x) = 1/3 − (sin x − x cos x)/x³ = Σ_{n≥2} (−1)ⁿ 2n x^{2n−2}/(2n+1)!; for x ≤ 2
    # the terms shrink fast, so a compensated sum of 20 terms is exact to round-off.
    series = fsum((-1) ** n * 2 * n * x ** (2 * n - 2) / factorial(2 * n + 1) for n in range(2, 22))
    assert np.isclose(structure_kernel(np.array(x)), series, rtol=1e-13, atol=0)
