"""The settings file of ``synptv ptv``: printed defaults read back, any settings survive
write ∘ read, and every refusal names the file, the section and the field."""

import math
import tomllib

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ptv.pipeline.settings_file import (
    SettingsError,
    load_settings,
    settings_from_dict,
    settings_toml,
)
from ptv.settings import DetectorSettings, PipelineSettings, PtvSettings, StatisticsSettings


def test_the_printed_defaults_are_the_defaults():
    assert settings_from_dict(tomllib.loads(settings_toml())) == PtvSettings()


def test_an_empty_file_keeps_every_default(tmp_path):
    path = tmp_path / "empty.toml"
    path.write_text("")
    assert load_settings(path) == PtvSettings()


lengths = st.floats(1e-4, 0.2)


@st.composite
def ptv_settings(draw):
    half = [draw(lengths) for _ in range(3)]
    r_min = draw(st.floats(1e-4, 1e-3))
    r_max = draw(st.floats(2e-2, 5e-2))
    statistics = StatisticsSettings(
        analysis_volume=(tuple(-h for h in half), tuple(half)),
        r_min=r_min,
        r_max=r_max,
        n_bins=draw(st.integers(2, 60)),
        plateau=(2 * r_min, r_max / 2),
        kolmogorov_c2=draw(st.floats(1.0, 3.0)),
        n_boot=draw(st.integers(2, 500)),
        plateau_method=draw(st.sampled_from(["mean", "max"])),
        trajectory_threshold=draw(st.none() | st.floats(1.5, 20.0)),
        seed=draw(st.integers(0, 2**31)),
    )
    pipeline = PipelineSettings(
        volume=(tuple(-2 * h for h in half), tuple(2 * h for h in half)),
        tolerance=draw(st.floats(1e-6, 1e-3)),
        min_cameras=draw(st.integers(2, 6)),
        max_speed=draw(st.floats(0.01, 20.0)),
        max_acceleration=draw(st.floats(0.1, 1e4)),
        outlier_threshold=draw(st.none() | st.floats(1.0, 10.0)),
        snapshots=draw(st.none() | st.integers(1, 10_000)),
        statistics=statistics,
    )
    detection = DetectorSettings(
        threshold_sigmas=draw(st.floats(1.0, 20.0)),
        saturation=draw(st.none() | st.floats(100.0, 65535.0)),
        diameter=draw(st.none() | st.floats(0.5, 60.0) | st.integers(1, 60)),
    )
    return PtvSettings(detection=detection, pipeline=pipeline)


@settings(max_examples=60, deadline=None)
@given(ptv_settings())
def test_any_settings_survive_writing_and_reading_back(chosen):
    assert settings_from_dict(tomllib.loads(settings_toml(chosen))) == chosen


@pytest.mark.parametrize(
    ("body", "message"),
    [
        ("[detect]\n", "unknown section [detect]"),
        ("[linking]\nmax_sped = 1.0\n", "[linking] unknown field 'max_sped'"),
        ("[matching]\nmin_cameras = 1\n", "[matching] min_cameras must be an integer >= 2"),
        ("[linking]\nmax_speed = -1.0\n", "[linking] max_speed must be a finite number > 0"),
        ("[linking]\nmax_acceleration = 0\n", "[linking] max_acceleration must be a finite"),
        ("[detection]\nsaturation = 'x'\n", "[detection] saturation must be a finite number"),
        ("[detection]\ndiameter = -15\n", "[detection] diameter must be a finite number > 0"),
        (
            "[detection]\nbackground = 'tophat'\ndiameter = 15.0\n",
            "[detection] diameter 15.0 px is wider than the top-hat's disc (tophat_radius 4",
        ),
        ("[statistics]\nplateau = [0.02, 0.002]\n", "[statistics] plateau must be"),
        ("[statistics]\nanalysis_volume = [1, 2]\n", "[statistics] analysis_volume"),
        ("[run]\nsnapshots = 0\n", "[run] snapshots must be an integer >= 1"),
        ("matching = 3\n", "[matching] must be a table"),
    ],
)
def test_bad_settings_are_one_line_errors_naming_file_section_and_field(tmp_path, body, message):
    path = tmp_path / "bad.toml"
    path.write_text(body)
    with pytest.raises(SettingsError) as error:
        load_settings(path)
    assert str(error.value).startswith(f"{path}: ") and message in str(error.value)
    assert "\n" not in str(error.value)


def test_a_missing_or_broken_file_is_named(tmp_path):
    with pytest.raises(SettingsError, match="does not exist"):
        load_settings(tmp_path / "none.toml")
    broken = tmp_path / "broken.toml"
    broken.write_text("[linking\n")
    with pytest.raises(SettingsError, match=r"broken\.toml: not a readable TOML file"):
        load_settings(broken)


def test_min_cameras_tolerance_and_max_speed_left_out_follow_the_cameras_and_the_data():
    from ptv.settings import default_min_cameras

    assert [default_min_cameras(n) for n in (2, 3, 4, 5, 6)] == [2, 2, 3, 4, 5]
    defaults = PipelineSettings()
    assert defaults.min_cameras is None and defaults.max_speed is None
    assert defaults.tolerance is None
    text = settings_toml()
    for name in ("max_speed", "min_cameras", "tolerance"):
        assert f"# {name} = ...  # " in text
    assert settings_from_dict(tomllib.loads(text)).pipeline == defaults


def test_predicted_radii_are_read_and_written_with_nan_at_the_smallest_dt():
    spec = tomllib.loads("[linking]\npredicted_radii = [nan, 1.7e-4, 1.3e-4]\n")
    read = settings_from_dict(spec)
    radii = read.pipeline.predicted_radii
    assert math.isnan(radii[0]) and radii[1:] == (1.7e-4, 1.3e-4)
    again = settings_from_dict(tomllib.loads(settings_toml(read)))
    assert math.isnan(again.pipeline.predicted_radii[0])
    assert again.pipeline.predicted_radii[1:] == radii[1:]
