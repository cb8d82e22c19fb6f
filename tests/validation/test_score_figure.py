"""score.png says what it leaves out: the position errors beyond its histograms' axis,
and the c1/S2 points beyond its axis (triangles on the edge, named in the legend)."""

import matplotlib.pyplot as plt
import numpy as np
import pytest

from validation.report.score_report import score_figure


def _result(ratio):
    r = np.geomspace(1e-3, 3e-2, len(ratio))
    return {
        "settings": {
            "positions": "/runs/a/ptv/model-free/results.h5",
            "dataset": "/runs/a/dataset",
        },
        "per_dt": [{"dt_s": 1e-4, "yield": 0.97, "ghost_fraction": 0.02}],
        "yield": 0.97,
        "ghost_fraction": 0.02,
        "position_rms_um": {"x": 8.0, "y": 8.0, "z": 20.0},
        "statistics": {
            "computed": True,
            "sample_truth": {"r": r.tolist()},
            "c1_over_truth": list(ratio),
            "c1": {"r_range_m": [2e-3, 2e-2]},
        },
    }


def test_the_figure_counts_the_errors_beyond_its_axis_and_explains_the_triangles():
    rng = np.random.default_rng(0)
    errors = rng.normal(scale=8e-6, size=(4000, 3))
    errors[:5, 2] = 500e-6  # five far outliers in z
    figure = score_figure(_result([1.0, 1.02, 1.5, 0.99]), errors)
    ax_error, ax_c1 = figure.axes[1], figure.axes[2]
    labels = [t.get_text() for t in ax_error.get_legend().get_texts()]
    # The axis stops at the 99.5th percentile of |error|, and says how many lie beyond.
    reach = np.percentile(np.abs(errors), 99.5) * 1e6
    assert ax_error.get_xlim() == pytest.approx((-reach, reach))
    for k, label in enumerate(labels):
        beyond = np.count_nonzero(np.abs(errors[:, k]) * 1e6 > reach)
        assert label.endswith(f"; {beyond} beyond ±{reach:.3g} µm not shown")
    assert int(labels[2].split("; ")[1].split()[0]) >= 5  # the outliers are counted
    c1_labels = [t.get_text() for t in ax_c1.get_legend().get_texts()]
    assert any(text.startswith("off the axis") for text in c1_labels)
    assert "results.h5" in figure.get_suptitle() and "dataset" in figure.get_suptitle()
    plt.close(figure)


def test_no_triangle_entry_when_every_point_is_on_the_axis():
    errors = np.random.default_rng(1).normal(scale=8e-6, size=(100, 3))
    figure = score_figure(_result([1.0, 1.02, 0.99]), errors)
    c1_labels = [t.get_text() for t in figure.axes[2].get_legend().get_texts()]
    assert not any("off the axis" in text for text in c1_labels)
    plt.close(figure)
