"""PTV figures on data too thin to measure: a note in the panel, never an exception."""

import io

import matplotlib.pyplot as plt
import pytest

from validation.report.ptv_figures import _loglog


@pytest.mark.parametrize(
    ("x", "y"),
    [([], []), ([1.0, 2.0], [0.0, -1.0]), ([-1.0], [3.0])],
    ids=["empty", "y<=0", "x<=0"],
)
def test_a_log_panel_without_positive_data_says_so_and_saves(x, y):
    figure, ax = plt.subplots()
    ax.plot(x, y, "o")
    _loglog(ax)
    figure.savefig(io.BytesIO(), format="png")
    assert ax.get_xscale() == "linear"
    assert any("nothing to plot" in text.get_text() for text in ax.texts)
    plt.close(figure)


def test_a_log_panel_with_positive_data_is_log_log():
    figure, ax = plt.subplots()
    ax.plot([1e-3, 1e-2], [0.0, 5.0], "o")  # a zero among positive values is masked
    _loglog(ax)
    figure.savefig(io.BytesIO(), format="png")
    assert ax.get_xscale() == ax.get_yscale() == "log"
    assert not ax.texts
    plt.close(figure)
