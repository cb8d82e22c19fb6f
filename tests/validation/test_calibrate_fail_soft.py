"""A calibration method that cannot fit a camera: named with its reason; a baseline is
left out and the work goes on, a required method stops it."""

from dataclasses import replace

import numpy as np
import pytest

import ptv.calibration.plate_images as experiment
from ptv.calibration.plate_images import CameraCalibrationError
from ptv.rays import Rays
from simulator.presets import flow_preset
from simulator.rigs import load_rig
from validation.dataset.calibrate import calibrate_dataset
from validation.run.render_dataset import RenderSettings, write_dataset
from validation.run.run_report import _tsai_note
from validation.run.scenario import RigSection, load_scenario
from validation.run.verdict import failed_rung_checks, verdict, verdict_line

SETTINGS = RenderSettings(frames=1, planes=3, particles=50, n_modes=40, seed=2)


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    folder = tmp_path_factory.mktemp("fail-soft") / "ds"
    write_dataset(folder, load_rig("paper-stereo"), flow_preset("lem-10hz"), SETTINGS)
    return folder


@pytest.fixture
def tsai_fails_on_the_second_camera(monkeypatch):
    """Tsai diverges on the second camera of the rig, as it did on a rolled Scheimpflug
    camera of an unseen rig."""
    calibrate = experiment.calibrate
    calls = []

    def failing(method, observations, sheet):
        if method == "tsai":
            calls.append(sheet)
            if len(calls) == 2:
                raise ValueError("Tsai LM diverged (f = 0.000202 m): behind the camera")
        return calibrate(method, observations, sheet)

    monkeypatch.setattr(experiment, "calibrate", failing)


def test_a_baseline_that_fails_on_a_camera_is_named_and_left_out(
    folder, tmp_path, tsai_fails_on_the_second_camera
):
    result = calibrate_dataset(
        folder, methods=("model-free", "tsai"), out=tmp_path / "cal", required=("model-free",)
    )
    camera = load_rig("paper-stereo").camera_names[1]
    assert result.failed == {
        "tsai": {"camera": camera, "reason": "Tsai LM diverged (f = 0.000202 m): behind the camera"}
    }
    assert set(result.table1) == set(result.files) == {"model-free"}
    assert any(f"camera {camera}" in w and "without tsai" in w for w in result.warnings)
    # its rung's one check says which camera and why; the verdict is the method under test's
    checks, must_hold = verdict(
        [],
        {"model-free": [], "tsai": failed_rung_checks(result.failed["tsai"])},
        ["model-free", "tsai"],
        {},
    )
    assert checks["passed"] and must_hold == []
    assert "tsai fails 1 of 1" in verdict_line(checks) and "calibration.fitted" in verdict_line(
        checks
    )
    assert camera in checks["rungs"]["tsai"]["checks"][0]["tolerance"]


class _Nowhere:
    """A fitted model whose rays are defined nowhere, as the OpenCV pinhole's were on an
    oblique rig with strong distortion (its principal point fitted 2.7-2.9k px beyond the
    sensor's edge)."""

    def pixel_to_ray(self, xy):
        nan = np.full((len(xy), 3), np.nan)
        return Rays(nan, nan)

    def project(self, points):
        return np.full((len(points), 2), np.nan)


def test_a_baseline_fitted_with_no_ray_at_its_dots_is_named_and_left_out(
    folder, tmp_path, monkeypatch
):
    calibrate, calls = experiment.calibrate, []

    def diverging(method, observations, sheet):
        model = calibrate(method, observations, sheet)
        calls.append(method)
        return _Nowhere() if calls.count("tsai") == 2 and method == "tsai" else model

    monkeypatch.setattr(experiment, "calibrate", diverging)
    result = calibrate_dataset(
        folder, methods=("model-free", "tsai"), out=tmp_path / "cal", required=("model-free",)
    )
    camera = load_rig("paper-stereo").camera_names[1]
    assert list(result.failed) == ["tsai"] and result.failed["tsai"]["camera"] == camera
    assert "no ray at any of the" in result.failed["tsai"]["reason"]
    assert set(result.table1) == {"model-free"}


def test_a_required_method_that_fails_stops_with_the_camera_named(
    folder, tmp_path, tsai_fails_on_the_second_camera
):
    camera = load_rig("paper-stereo").camera_names[1]
    with pytest.raises(CameraCalibrationError, match=f"tsai cannot calibrate camera {camera}"):
        calibrate_dataset(folder, methods=("model-free", "tsai"), out=tmp_path / "cal")
    assert not (tmp_path / "cal").exists()


def test_a_calibration_baseline_without_a_rung_is_printed_with_its_camera():
    from validation.run.verdict import rung_checks, summary_lines

    from .test_run_verdict import comparison, matching

    checks, must_hold = verdict(
        [], {"model-free": rung_checks(comparison(), matching())}, ["model-free"], {}
    )
    failed = {"tsai": {"camera": "cam2", "reason": "Tsai LM diverged"}}
    printed = summary_lines(
        {"checks": checks, "must_hold": must_hold, "calibration": {"failed": failed}}
    )
    assert printed[-2] == (
        "tsai (baseline: reported, not required): could not calibrate camera cam2: Tsai LM diverged"
    )
    assert printed[-1] == "verdict: every required check passes"


def test_the_report_says_when_scheimpflug_cameras_are_outside_tsais_model():
    results = {"calibration": {"tsai_reprojection_rms_px": {"cam1": 3.61, "cam2": 3.62}}}
    note = " ".join(_tsai_note(results, load_scenario("default")))  # paper-stereo: Scheimpflug
    assert "sensor square to the optical axis" in note and "cam1 3.61 px, cam2 3.62 px" in note
    untilted = replace(load_scenario("default"), rig=RigSection("conventional"))
    assert _tsai_note(results, untilted) == []  # no tilted sensor: nothing to say
    assert _tsai_note({"calibration": {}}, load_scenario("default")) == []  # Tsai not fitted
