"""Fig. 3 (the calibration error maps) stands alone: it says why two methods' columns
look alike when they do."""

import matplotlib.pyplot as plt
import numpy as np

from ptv.calibration.grid_errors import PositionErrors
from validation.report.calibration_figures import agreement_note, error_maps


def _errors(scale, rng):
    grid = np.stack(np.meshgrid(np.arange(5), np.arange(5), [0.0]), axis=-1).reshape(-1, 3)
    truth = grid * 5e-3
    delta = rng.normal(scale=scale, size=truth.shape)
    return PositionErrors(truth, delta, np.zeros(len(truth), dtype=int))


def test_model_free_and_soloff_that_agree_are_explained():
    rng = np.random.default_rng(0)
    alike = _errors(5e-6, rng)
    soloff = PositionErrors(alike.truth, alike.delta * 1.0003, alike.plane)
    maps = {"model-free": alike, "tsai": _errors(40e-6, rng), "soloff": soloff}
    note = agreement_note(maps)
    assert "Model-free and Soloff agree" in note and "same detected dots" in note
    # Both values, to enough digits to tell them apart.
    assert f"{alike.d * 1e6:.4g}" in note and f"{soloff.d * 1e6:.4g}" in note
    figure = error_maps(maps, title="Fig. 3")
    assert any(note.split(":")[0] in " ".join(t.get_text().split()) for t in figure.texts)
    plt.close(figure)


def test_no_agreement_is_claimed_where_there_is_none():
    rng = np.random.default_rng(1)
    maps = {"model-free": _errors(5e-6, rng), "soloff": _errors(10e-6, rng)}
    assert agreement_note(maps) == ""
    assert agreement_note({"model-free": maps["model-free"]}) == ""
    figure = error_maps(maps)
    assert not any("agree" in t.get_text() for t in figure.texts)
    assert any("colour scale of its own" in t.get_text() for t in figure.texts)
    plt.close(figure)
