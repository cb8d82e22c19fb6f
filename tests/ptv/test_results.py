"""Why a run is too thin to measure: the warnings of the run summary."""

from ptv.pipeline.summary import thin_data_warnings


def _counts(det_a, det_b, matches, links_used=500):
    return {
        "dt": 1e-3,
        "detections": {
            "left": {"a": det_a[0], "b": det_b[0]},
            "right": {"a": det_a[1], "b": det_b[1]},
        },
        "matches": {"a": matches[0], "b": matches[1]},
        "links_used": links_used,
    }


def test_a_healthy_run_has_no_warning():
    assert thin_data_warnings([_counts((1000, 980), (1010, 990), (870, 860))]) == []


def test_a_blank_frame_names_the_frame_and_the_camera():
    (line,) = thin_data_warnings([_counts((1000, 980), (1010, 0), (870, 0))])
    assert line.startswith("Δt = 1 ms, frame b: 0 matches from left 1010, right 0 detections")
    assert "camera right sees fewest" in line


def test_another_rigs_calibration_leaves_few_matches_in_both_frames_in_one_line():
    (line,) = thin_data_warnings([_counts((870, 880), (860, 875), (81, 77), links_used=3)])
    assert line.startswith("Δt = 1 ms, frame b: 77 matches")  # the worst of the two
    assert "(and 1 more of the 2 frames)" in line
    assert "that the matching volume holds the particles" in line


def test_a_dt_without_links_is_reported_when_the_statistics_are_asked_for():
    counts = [_counts((1000, 980), (1010, 990), (870, 860), links_used=0)]
    (line,) = thin_data_warnings(counts)
    assert "no link used" in line
    assert thin_data_warnings(counts, statistics=False) == []
