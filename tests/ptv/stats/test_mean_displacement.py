"""The mean displacement's line, and its errors where successive snapshots correlate."""

import numpy as np
import pytest

from ptv.stats.mean_displacement import MeanDisplacement
from ptv.stats.multidt import LineFit


def _independent(chi2: float) -> MeanDisplacement:
    """Means of independent runs per Δt: intercept errors of 1 µm, χ²/dof ``chi2``."""
    three = np.ones(3)
    fit = LineFit(
        c1=0.01 * three,
        c2=2e-6 * three,
        se_c1=1e-3 * three,
        se_c2=1e-6 * three,
        cov_c1c2=-1e-10 * three,
        chi2_dof=chi2 * three,
        n_points=5,
        method="wls",
    )
    dt = np.linspace(1e-3, 5e-3, 5)
    return MeanDisplacement(
        dt=dt, mean=np.zeros((5, 3)), se=1e-6 * np.ones((5, 3)), count=np.full(5, 100), fit=fit
    )


@pytest.mark.parametrize("chi2", [0.5, 1.0])
def test_independent_runs_of_correlated_snapshots_have_their_errors_widened_by_root_tau(chi2):
    """Each Δt's mean over correlated snapshots: its variance is τ times the one of
    independent snapshots, so the intercept's error grows by √τ and the offset's
    statistic falls by τ (a scatter about the line no larger than the errors says
    nothing more)."""
    line = _independent(chi2)
    wider = line.with_correlated_snapshots(4.0)
    np.testing.assert_allclose(wider.se_offset_scaled, 2.0 * line.se_offset_scaled)
    np.testing.assert_allclose(wider.se, 2.0 * line.se)
    assert wider.offset_test()[0] == pytest.approx(line.offset_test()[0] / 4.0)
    assert wider.offset_test()[1] == line.offset_test()[1]


def test_a_scatter_that_already_shows_the_correlation_is_not_counted_twice():
    """χ²/dof = 9 about the line already widens the errors threefold (Birge); τ = 4
    adds nothing beyond it: the larger of the two, not their product."""
    line = _independent(9.0)
    wider = line.with_correlated_snapshots(4.0)
    np.testing.assert_allclose(wider.se_offset_scaled, line.se_offset_scaled)


def test_uncorrelated_snapshots_change_nothing():
    line = _independent(1.0)
    assert line.with_correlated_snapshots(1.0) is line
