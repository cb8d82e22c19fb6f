"""The report's IPR section from reconstruction scores built here."""

import json

import matplotlib.pyplot as plt

from validation.report.ipr_report import ipr_html, judged_rungs, reconstruction_figure


def _score(found: float) -> dict:
    """A reconstruction.json as the IPR stage writes it (nan as None)."""
    return {
        "found": found,
        "ghosts": 0.001,
        "rms_um": 3.3,
        "rms_px": 0.024,
        "ppp": 0.035,
        "displacement_rms_um": None,
        "seconds_per_exposure": 6.3,
        "outer_iterations_median": 9.0,
        "by_depth": [
            {
                "z_mm": [-15.0, -9.0],
                "particles": 10,
                "found": found,
                "rms_um": 3.0,
                "rms_px": 0.03,
                "points": 10,
                "ghosts": None,
            },
            {
                "z_mm": [-9.0, -3.0],
                "particles": 10,
                "found": 1.0,
                "rms_um": 2.0,
                "rms_px": 0.02,
                "points": 10,
                "ghosts": 0.0,
            },
        ],
        "by_neighbour": [
            {
                "distance_px": [0.0, 1.0],
                "particles": 5,
                "found": 0.8,
                "rms_um": 4.0,
                "rms_px": 0.04,
            },
            {
                "distance_px": [5.0, None],
                "particles": 0,
                "found": None,
                "rms_um": None,
                "rms_px": None,
            },
        ],
    }


def test_every_rung_is_a_row_and_a_curve_and_missing_values_are_dashes():
    scores = json.loads(
        json.dumps({"ipr-true-cameras": _score(0.99), "ipr-model-free": _score(0.98)})
    )
    html = ipr_html(scores)
    text = "".join(html)
    assert text.count("<tr>") == 3  # the header and one row per rung
    assert "ipr-model-free" in text and "98 %" in text and "–" in text
    figure = reconstruction_figure(scores, label="test")
    found, error, overlap = figure.axes
    assert len(found.get_lines()) == 4  # found and 1 − ghosts per rung
    assert len(error.get_lines()) == 3  # per rung, and the 0.1 px line
    assert len(overlap.get_lines()) == 2
    assert [t.get_text() for t in overlap.get_xticklabels()] == ["0–1"]  # empty class left out
    plt.close(figure)
    assert judged_rungs({"reconstruction": scores}) == ["ipr-model-free"]
    assert ipr_html({}) == [] and judged_rungs({}) == []
