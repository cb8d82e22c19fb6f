"""Every option of ``synptv ptv`` in one TOML file (``--settings``; ``--print-settings``).

Sections and the fields of the :mod:`ptv.settings` dataclasses they fill, under the
fields' own names (SI units: m, s, m/s, m/s²)::

    [detection]    DetectorSettings: threshold_sigmas, saturation, particles, background,
                   tophat_radius, median_frames, min_peak, min_size, diameter
    [matching]     PipelineSettings: volume, tolerance, min_cameras
    [linking]      PipelineSettings: max_speed, predicted_radii, position_noise,
                   max_acceleration, track_gap, outlier_threshold, outlier_neighbours
    [statistics]   StatisticsSettings: analysis_volume, r_min, r_max, n_bins, binning, plateau,
                   plateau_method, kolmogorov_c2, n_boot, eulerian_cells,
                   min_cell_count, trajectory_threshold, snapshot_block, seed
    [run]          PipelineSettings: snapshots
    [tracks]       TrackFitSettings: fit_window, min_points (``--tracks`` only)

A missing section or field keeps its default. Boxes are ``[[x0, y0, z0], [x1, y1, z1]]``
(lower and upper corners). TOML has no null: a field whose default is "none"
(``saturation``: the image type's maximum; ``diameter``: spots of about 3 px;
``snapshots``: all; ``max_speed`` and ``predicted_radii``: measured on the data
(``nan`` at the smallest Δt, TOML's float); ``min_cameras``: from the
camera count; ``fit_window``: chosen from the data; ``snapshot_block``: from the
correlation of successive snapshots) is left out for that default, and
``outlier_threshold`` or ``trajectory_threshold`` = false turns that test off. Unknown
sections or fields, wrong types and values the settings refuse are
:class:`SettingsError` naming the file, the section and the field.
"""

import dataclasses
import math
import tomllib
from pathlib import Path

from ptv.settings import (
    DetectorSettings,
    PipelineSettings,
    PtvSettings,
    StatisticsSettings,
    TrackFitSettings,
)

__all__ = ["SettingsError", "load_settings", "settings_from_dict", "settings_toml"]

#: Section → (settings class, fields of it that the section holds).
SECTIONS = {
    "detection": (DetectorSettings, tuple(f.name for f in dataclasses.fields(DetectorSettings))),
    "matching": (PipelineSettings, ("volume", "tolerance", "min_cameras")),
    "linking": (
        PipelineSettings,
        (
            "max_speed",
            "predicted_radii",
            "position_noise",
            "max_acceleration",
            "track_gap",
            "outlier_threshold",
            "outlier_neighbours",
        ),
    ),
    "statistics": (
        StatisticsSettings,
        tuple(f.name for f in dataclasses.fields(StatisticsSettings)),
    ),
    "run": (PipelineSettings, ("snapshots",)),
    "tracks": (TrackFitSettings, ("fit_window", "min_points")),
}
#: Fields whose "none" is written as false (a test turned off).
_OFF_WITH_FALSE = ("outlier_threshold", "trajectory_threshold")
#: Fields whose "none" is their absence.
_NONE_WHEN_ABSENT = (
    "saturation",
    "diameter",
    "snapshots",
    "tolerance",
    "max_speed",
    "predicted_radii",
    "min_cameras",
    "fit_window",
    "snapshot_block",
)
#: Units and meaning written beside each field by :func:`settings_toml`.
_COMMENTS = {
    "threshold_sigmas": "detection threshold, noise σ above the background",
    "saturation": "saturation level, DN (left out: the image type's maximum)",
    "particles": '"bright" on a dark background, or "dark" on a bright one (back-lit)',
    "background": 'removed first: "none", "tophat" (each frame), "median" (of the sequence)',
    "tophat_radius": "top-hat disc radius, px (above the largest particle image radius)",
    "median_frames": "frames spread over the recording whose per-pixel median is the background",
    "min_peak": "particles peaking less than this above the background are dropped, DN",
    "min_size": "particles with fewer pixels above threshold are dropped",
    "diameter": "expected particle image diameter, px (left out: about 3 px); from 6 px the "
    "particles are detected at that scale",
    "volume": "matching volume: lower and upper corners, m",
    "tolerance": "largest ray distance from a matched point, m (left out: 1.5 pixel footprints, "
    "or 6 median ray distances of the matches when the calibration's error is larger)",
    "min_cameras": "fewest cameras a match must use (left out: all but one of 4 or more, else 2)",
    "max_speed": "largest particle speed, m/s: link radius max_speed·Δt + 5·position_noise "
    "(left out: measured on the links of the smallest Δt)",
    "predicted_radii": "with a shared first frame, the radius around each link's prediction "
    "from the next smaller Δt, m, in Δt order, nan for the smallest (left out: measured)",
    "position_noise": "expected position noise, one component, m",
    "max_acceleration": "largest particle acceleration, m/s², for --tracks: radius "
    "max_acceleration·τ² + 5√6·position_noise",
    "track_gap": "frames a track may miss and still be continued, for --tracks",
    "outlier_threshold": "normalised median test on the displacements (false: off)",
    "outlier_neighbours": "neighbours of the median test",
    "analysis_volume": "statistics box by X(t): lower and upper corners, m",
    "r_min": "smallest separation bin edge, m",
    "r_max": "largest separation bin edge, m",
    "n_bins": "log-spaced separation bins",
    "binning": 'pairs binned by their separation at t, "start", or by the chord "midpoint"',
    "plateau": "r range of the plateau ε, m",
    "plateau_method": '"mean" of ε(r) over the plateau range, or its "max"',
    "kolmogorov_c2": "C2 in S2 = C2 (εr)^(2/3)",
    "n_boot": "bootstrap replicates over snapshots (at least 2)",
    "eulerian_cells": "cells of the mean-flow grid over the analysis volume",
    "min_cell_count": "displacements a cell needs at every Δt",
    "trajectory_threshold": "trajectory test, times the median residual (false: off)",
    "snapshot_block": "consecutive snapshots the bootstrap draws together (left out: from the "
    "correlation of successive snapshots, 1 for independent ones)",
    "seed": "seed of the bootstrap",
    "snapshots": "process only the first N snapshots per Δt (left out: all)",
    "fit_window": "points per track fit, odd, >= 5, for --tracks (left out: chosen from the "
    "noise and the tracks)",
    "min_points": "fewest points of a track that is fitted, >= 5",
}


class SettingsError(ValueError):
    """A settings file that cannot be used; the message names file, section and field."""


def _value(name: str, value: object):
    """A TOML value as the settings field expects it (lists to tuples, false to None)."""
    if value is False and name in _OFF_WITH_FALSE:
        return None
    if isinstance(value, list):
        return tuple(_value(name, v) for v in value)
    return value


def _section_values(table: object, section: str, source: str) -> dict:
    if not isinstance(table, dict):
        raise SettingsError(f"{source}: [{section}] must be a table")
    known = SECTIONS[section][1]
    unknown = [key for key in table if key not in known]
    if unknown:
        raise SettingsError(
            f"{source}: [{section}] unknown field {unknown[0]!r}; known: {', '.join(known)}"
        )
    return {key: _value(key, value) for key, value in table.items()}


def settings_from_dict(spec: dict, *, source: str = "<settings>") -> PtvSettings:
    """Settings from a parsed file (module docstring for the layout).

    Raises
    ------
    SettingsError
        Unknown sections or fields, or values the settings refuse.
    """
    unknown = [key for key in spec if key not in SECTIONS]
    if unknown:
        raise SettingsError(
            f"{source}: unknown section [{unknown[0]}]; known: {', '.join(SECTIONS)}"
        )
    values = {s: _section_values(spec.get(s, {}), s, source) for s in SECTIONS}
    # Each section on its own first, so that an error names the section it comes from.
    built = {}
    for section, (cls, _) in SECTIONS.items():
        try:
            built[section] = cls(**values[section])
        except (TypeError, ValueError) as err:
            raise SettingsError(f"{source}: [{section}] {err}") from None
    pipeline = PipelineSettings(
        **values["matching"], **values["linking"], **values["run"], statistics=built["statistics"]
    )
    return PtvSettings(detection=built["detection"], pipeline=pipeline, tracks=built["tracks"])


def load_settings(path: str | Path) -> PtvSettings:
    """The settings in a TOML file (module docstring).

    Parameters
    ----------
    path : path-like
        The file: sections ``[detection]``, ``[matching]``, ``[linking]``,
        ``[statistics]``, ``[run]``, ``[tracks]``, each optional (SI units).

    Returns
    -------
    PtvSettings
        The file's values, the defaults for what it leaves out.

    Raises
    ------
    SettingsError
        Missing, unreadable or invalid file; the message names file, section and field.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> import ptv
    >>> tmp = tempfile.TemporaryDirectory()
    >>> path = pathlib.Path(tmp.name) / "ptv.toml"
    >>> _ = path.write_text('''
    ... [detection]
    ... threshold_sigmas = 8.0
    ... [linking]
    ... max_speed = 0.5
    ... ''')
    >>> settings = ptv.load_settings(path)
    >>> settings.detection.threshold_sigmas, settings.pipeline.max_speed  # σ, m/s
    (8.0, 0.5)
    >>> _ = path.write_text("[linking]\\nmax_sped = 0.5")
    >>> ptv.load_settings(path)
    Traceback (most recent call last):
    ...
    ptv.pipeline.settings_file.SettingsError: ...: [linking] unknown field 'max_sped'; known: ...
    >>> tmp.cleanup()
    """
    path = Path(path)
    if not path.is_file():
        raise SettingsError(f"settings file {str(path)!r} does not exist")
    try:
        spec = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as err:
        raise SettingsError(f"{path}: not a readable TOML file ({err})") from None
    return settings_from_dict(spec, source=str(path))


def _toml(value: object) -> str:
    """A settings value written as TOML."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return repr(value) if math.isfinite(value) else str(value)
    if isinstance(value, str):
        return f'"{value}"'
    return "[" + ", ".join(_toml(v) for v in value) + "]"


def settings_toml(
    settings: PtvSettings | None = None, *, left_out: dict[str, str] | None = None
) -> str:
    """The settings (default: the defaults) as a commented TOML file that
    :func:`load_settings` reads back; the fields of ``left_out`` (name → what takes
    their place when they are left out) are written commented out, with that text."""
    settings = PtvSettings() if settings is None else settings
    objects = {
        DetectorSettings: settings.detection,
        PipelineSettings: settings.pipeline,
        StatisticsSettings: settings.pipeline.statistics,
        TrackFitSettings: settings.tracks,
    }
    lines = ["# synptv ptv settings (SI units). Missing fields keep their defaults."]
    for section, (cls, names) in SECTIONS.items():
        lines += ["", f"[{section}]"]
        for name in names:
            value = getattr(objects[cls], name)
            comment = _COMMENTS[name]
            if name in (left_out or {}):
                lines.append(f"# {name} = ...  # {comment} (left out: {left_out[name]})")
                continue
            if value is None and name in _NONE_WHEN_ABSENT:
                lines.append(f"# {name} = ...  # {comment}")
                continue
            text = "false" if value is None else _toml(value)
            lines.append(f"{name} = {text}  # {comment}")
    return "\n".join(lines) + "\n"
