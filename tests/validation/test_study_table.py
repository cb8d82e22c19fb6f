"""The study figure: its error bars are the bootstrap errors with one seed, the seeds'
scatter with several, and a note says which."""

import matplotlib.pyplot as plt
import numpy as np
import pytest

from validation.studies.table import study_figure


def _row(planes, seed, c1, c1_se, eps, eps_se):
    return {
        "seed": seed,
        "planes": planes,
        "method": "model-free",
        "table1_d_um": 7.0,
        "model_error_um": 8.0,
        "yield": 0.97,
        "ghosts": 0.02,
        "c1_rel_err": {"10": c1, "40": c1, "100": c1},
        "c1_rel_se": {"10": c1_se, "40": c1_se, "100": c1_se},
        "epsilon_rel_err": eps,
        "epsilon_rel_se": eps_se,
    }


def _half_heights(ax):
    """Half the length of each error bar of the panel's first series, in its units."""
    container = ax.containers[0]
    segments = container.lines[2][0].get_segments()
    return np.array([abs(s[1][1] - s[0][1]) / 2 for s in segments])


def _note(figure):
    return " ".join(t.get_text() for t in figure.texts)


def test_one_seed_shows_the_bootstrap_errors():
    rows = [_row(3, 0, -0.02, 0.03, -0.003, 0.014), _row(7, 0, -0.01, 0.025, -0.002, 0.012)]
    figure = study_figure("planes", rows)
    c1_panel, eps_panel = figure.axes[2], figure.axes[3]
    assert _half_heights(c1_panel) == pytest.approx([3.0, 2.5])  # %
    assert _half_heights(eps_panel) == pytest.approx([1.4, 1.2])
    assert "bootstrap" in _note(figure)
    plt.close(figure)


def test_several_seeds_show_the_standard_error_of_their_mean():
    rows = [
        _row(3, 0, -0.02, 0.03, -0.003, 0.014),
        _row(3, 1, 0.02, 0.03, 0.001, 0.014),
    ]
    figure = study_figure("planes", rows)
    eps_panel = figure.axes[3]
    # Two seeds, −0.3 % and +0.1 %: standard deviation 0.283 %, over √2.
    assert _half_heights(eps_panel) == pytest.approx([0.4 / np.sqrt(2) / np.sqrt(2)])
    assert "2 seeds" in _note(figure)
    plt.close(figure)
