"""PTV figures (Figs. 5a, 5b, 6a, 6b): on data too thin to measure a note in the panel,
never an exception; on a measurement, titles that say whose it is, values with their
errors at the error's precision, intercepts on top, a legend that does not shrink the
axes."""

import io
import re
from pathlib import Path
from types import SimpleNamespace

import matplotlib.pyplot as plt
import numpy as np
import pytest

from ptv.pipeline.double_frame import PtvResult
from ptv.settings import ANALYSIS_VOLUME, PipelineSettings, StatisticsSettings
from ptv.stats.links import RunParticles
from ptv.stats.run_statistics import compute_statistics
from validation.report.ptv_figures import (
    _loglog,
    epsilon_figure,
    q_versus_dt2_figure,
    raw_structure_figure,
    save_ptv_figures,
    structure_figure,
)
from validation.report.value_error import value_error
from validation.run.experiment import rung_label
from validation.run.scenario import load_scenario


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


def _runs(dt, *, sigma=10e-6, snapshots=8, particles=400, rng=0):
    """Runs of a smooth random velocity field, positions measured with white noise."""
    rng = np.random.default_rng(rng)
    k = rng.normal(size=(12, 3)) * 150.0
    amp = rng.normal(size=(12, 3)) * 0.06
    phase = rng.uniform(0, 2 * np.pi, 12)
    lower, upper = (np.array(v) for v in ANALYSIS_VOLUME)
    runs = []
    for kk, step in enumerate(dt):
        x = rng.uniform(lower, upper, size=(snapshots * particles, 3))
        v = np.sin(x @ k.T + phase) @ amp
        a, b = rng.normal(scale=sigma, size=(2, *x.shape))
        runs.append(
            RunParticles(
                k=kk,
                dt=float(step),
                positions=x + a,
                displacements=v * step + b - a,
                offsets=np.arange(snapshots + 1) * particles,
                snapshot_ids=np.arange(snapshots),
                detections=np.zeros((snapshots, 2, 2), dtype=np.int64),
                matches=np.zeros((snapshots, 2), dtype=np.int64),
                links=np.full(snapshots, particles),
                processed=np.arange(snapshots),
                in_analysis=np.ones(len(x), dtype=bool),
                outlier=np.zeros(len(x), dtype=bool),
            )
        )
    return runs


@pytest.fixture(scope="module")
def result():
    statistics = StatisticsSettings(n_boot=20, r_min=2e-3, n_bins=8, plateau=(3e-3, 20e-3))
    runs = _runs(np.array([1e-4, 2e-4, 3e-4, 4e-4, 5e-4]))
    source = SimpleNamespace(folder=Path("/data/tank-run-7"))
    settings = PipelineSettings(statistics=statistics)
    return PtvResult(source, ("cam1", "cam2"), settings, runs, compute_statistics(runs, statistics))


FIGURES = (raw_structure_figure, q_versus_dt2_figure, structure_figure, epsilon_figure)
LABEL = "scenario ci (seed 0), rung model-free: the PTV stack with the model-free calibration"


@pytest.mark.parametrize("draw", FIGURES, ids=lambda f: f.__name__)
def test_every_figure_says_whose_measurement_it_is(result, draw):
    figure = draw(result, label=LABEL)
    assert figure.get_suptitle() == LABEL
    plt.close(figure)
    # Without a label (synptv ptv): the folder of the data measured.
    figure = draw(result)
    assert "tank-run-7" in figure.get_suptitle()
    plt.close(figure)


def test_the_four_files_of_a_rung_carry_its_label(result, tmp_path):
    paths = save_ptv_figures(result, tmp_path, label=LABEL)
    assert sorted(paths) == ["fig5a", "fig5b", "fig6a", "fig6b"]
    assert all(p.is_file() and p.stat().st_mode & 0o777 == 0o644 for p in paths.values())


def test_fig5b_without_a_fitted_separation_draws_no_legend_and_warns_nothing(result):
    # Warnings are errors in the tests: matplotlib's "No artists with labels" would fail.
    nothing = np.zeros(result.statistics.structure.r.size, dtype=bool)
    figure = q_versus_dt2_figure(result, separations=nothing)
    assert figure.axes[0].get_legend() is None
    plt.close(figure)


def test_fig5b_prints_c2_at_the_precision_of_its_error_and_draws_the_intercepts_on_top(result):
    figure = q_versus_dt2_figure(result)
    ax, zoom = figure.axes
    sf = result.statistics.structure
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert labels
    for text in labels:
        c2 = re.search(r"c2 = (.*)$", text).group(1)
        value, error = c2.removesuffix(" µm²").split(" ± ")
        # The error has two significant digits, the value as many decimals.
        assert len(error.replace(".", "").lstrip("0")) == 2
        assert len(value.partition(".")[2]) == len(error.partition(".")[2])
    # The first label is that of a fitted bin, printed by the shared helper.
    b = int(np.flatnonzero(sf.fitted)[0])
    assert labels[0].endswith(value_error(sf.noise[b] * 1e12, sf.se_noise[b] * 1e12, "µm²"))
    # The ◆ intercepts lie above every line of the zoom and its spines.
    diamonds = [line for line in zoom.lines if line.get_marker() == "D"]
    others = [line for line in zoom.lines if line.get_marker() != "D"]
    assert diamonds and others
    top = max(a.get_zorder() for a in [*others, *zoom.spines.values()])
    assert min(d.get_zorder() for d in diamonds) > top
    assert all(d.get_markeredgecolor() == "black" for d in diamonds)
    # Every intercept lies within the zoom's y range: none is hidden off the panel.
    low, high = zoom.get_ylim()
    c2 = sf.noise[sf.fitted] * 1e12
    assert np.all((c2 >= low) & (c2 <= high))
    plt.close(figure)


def test_fig6b_legend_names_only_what_is_drawn_and_leaves_the_axes_their_size(result):
    figure = epsilon_figure(result)
    ax, legend_panel = figure.axes
    legend = legend_panel.get_legend()
    labels = [t.get_text() for t in legend.get_texts()]
    plateau = result.statistics.plateau
    expected = value_error(plateau.epsilon, plateau.se_epsilon, "m²/s³")
    assert any(text.endswith(expected) for text in labels)
    # The legend holds the panel's entries, and none for the ±1 s.e. band, often
    # thinner than its line (the label gives the error instead).
    assert sorted(ax.get_legend_handles_labels()[1]) == sorted(labels)
    assert labels[0].startswith("(S2/C2)^(3/2)/r")  # the measurement first
    assert all(c.get_label().startswith("_") for c in ax.collections)
    # The axes are those of Fig. 6a: the legend lies below, not beside them.
    other = structure_figure(result)
    for fig in (figure, other):
        fig.canvas.draw()
    size = ax.get_window_extent().size / figure.dpi
    reference = other.axes[0].get_window_extent().size / other.dpi
    assert size == pytest.approx(reference, rel=0.1)
    plt.close(figure)
    plt.close(other)


def test_a_rung_is_titled_with_its_run_and_what_it_measures():
    scenario = load_scenario("ci")
    run = Path("/out/calibrations")
    for variant in ("exact", "detection", "true-cameras", "model-free", "tsai"):
        label = rung_label(scenario, variant, run)
        assert label.startswith(f"scenario ci (seed {scenario.seed}), rung {variant}: ")
    assert rung_label(scenario, "tsai", run).endswith("the PTV stack with the tsai calibration")
    assert "true cameras" in rung_label(scenario, "true-cameras", run)
    assert "true trajectories" in rung_label(scenario, "exact", run)
    # A study's calibration from fewer planes is named by its folder.
    fewer = rung_label(scenario, "model-free", Path("/out/calibrations-planes-03"))
    assert fewer.endswith("model-free calibration (calibrations-planes-03)")
