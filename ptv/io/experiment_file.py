"""experiment.json, checked against its JSON Schema before anything else is read.

The schema ships with the package (``ptv/schemas/experiment.schema.json``,
:func:`experiment_schema`; docs/experiment.md explains each field). Every problem of a
description is found at once and reported in one line that names the file and each
field (``cameras.cam1.image_size: [2048] is too short; dt: ...``), so an experimentalist
fixes them all in one go, before any image is read.

What a command needs beyond the schema's few required fields is asked for by name
(:data:`NEEDS`): processing particles needs ``dt``, ``frames_per_dt`` and
``particle_images``; calibrating needs ``target``, ``traverse_z``,
``calibration_images`` (or dot lists instead, ``calibration_dots``) and every camera's
``pixel_pitch`` and ``focal_length`` for a plate, and ``target``, ``calibration_images``
and ``calibration_seeds`` for a 3-D target of listed points (:func:`has_point_target`).
"""

import json
from collections.abc import Iterable
from functools import cache
from importlib import resources
from pathlib import Path

from jsonschema import Draft202012Validator

from ptv.errors import DatasetError
from ptv.names import FILE_NAME_RULE, is_file_name

__all__ = [
    "NEEDS",
    "DescriptionError",
    "description_problems",
    "experiment_schema",
    "has_point_target",
    "read_experiment",
]


class DescriptionError(DatasetError):
    """A description that breaks the schema or lacks what a command needs (one line)."""


#: Fields each use of a dataset needs, beyond the schema's required ones; a tuple is a
#: choice (any one of them does).
NEEDS = {
    "particles": ("dt", "frames_per_dt"),
    "calibration": ("target", "traverse_z", ("calibration_images", "calibration_dots")),
}
#: What calibrating needs instead of ``NEEDS["calibration"]`` with a point target.
POINT_TARGET_NEEDS = ("target", "calibration_images", "calibration_seeds")
#: Fields a time-resolved description replaces.
TIME_RESOLVED_REPLACES = ("dt", "frames_per_dt", "particle_images", "shared_first_frame")
#: Fields dot lists (``calibration_dots``) replace.
CALIBRATION_DOTS_REPLACES = ("calibration_images", "calibration_seeds")
#: The file patterns each format of ``calibration_dots`` takes.
DOTS_FORMAT_FIELDS = {"csv": ("files",), "openptv": ("crd", "fix")}
#: What each need is for, as the messages say it.
_VERB = {"particles": "process particle images", "calibration": "calibrate"}
#: Camera fields calibrating needs.
CALIBRATION_CAMERA_FIELDS = ("pixel_pitch", "focal_length")


def has_point_target(spec: object) -> bool:
    """Whether a description's target is a 3-D target of listed points (it has a
    ``points`` file) rather than a plate."""
    target = spec.get("target") if isinstance(spec, dict) else None
    return isinstance(target, dict) and "points" in target


@cache
def experiment_schema() -> dict:
    """The JSON Schema of experiment.json (draft 2020-12)."""
    text = resources.files("ptv").joinpath("schemas/experiment.schema.json").read_text()
    return json.loads(text)


def _where(path: Iterable) -> str:
    """A field path as the user writes it: ``cameras.cam1.image_size``, ``dt[2]`` or
    ``cameras['a b']``."""
    text = ""
    for part in path:
        if isinstance(part, int) or not is_file_name(part):
            text += f"[{part!r}]"  # a name with odd characters stays on one line
        else:
            text += f".{part}" if text else part
    return text or "(top level)"


def _message(error) -> str:
    """The schema's message, or a plainer one where a PTV user needs the reason."""
    path = list(error.absolute_path)
    if path == ["dt"] and error.validator == "minItems":
        return f"{error.instance}: the multi-Δt method needs at least two Δt values"
    if path == ["cameras"] and error.validator == "minProperties":
        return f"3-D PTV needs at least two cameras, got {list(error.instance)!r}"
    if path == ["cameras"] and error.validator == "pattern":  # from propertyNames
        return f"camera name: expected {FILE_NAME_RULE}, got {error.instance!r}"
    if error.validator == "not" and path == ["traverse_z"]:  # a point target has no traverse
        return "a point target is imaged once per camera, not along a traverse: leave it out"
    if error.validator == "not" and path == ["calibration_images"]:
        return (
            f"{error.instance!r}: a point target has one image per camera: use {{camera}} "
            "and no {j}"
        )
    if error.validator == "not" and path == []:  # the fields a dependentSchema refuses
        owner = error.relative_schema_path[1]
        if owner == "calibration_dots":
            given = [f for f in CALIBRATION_DOTS_REPLACES if f in error.instance]
            return f"calibration_dots gives the dots: leave out {', '.join(given)}"
        given = [f for f in TIME_RESOLVED_REPLACES if f in error.instance]
        return (
            f"time_resolved gives the Δt values and the frame pairs: leave out {', '.join(given)}"
        )
    if error.validator == "not" and path == ["calibration_dots"]:  # another format's files
        chosen = error.instance["format"]
        alien = [
            f
            for fields in DOTS_FORMAT_FIELDS.values()
            for f in fields
            if f in error.instance and f not in DOTS_FORMAT_FIELDS[chosen]
        ]
        return f"format {chosen!r} takes {' and '.join(DOTS_FORMAT_FIELDS[chosen])}, not {alien[0]}"
    known = error.schema.get("properties", {})
    if error.validator == "additionalProperties" and known:
        unknown = ", ".join(repr(k) for k in error.instance if k not in known)
        return f"unknown field(s) {unknown}; known: {', '.join(known)}"
    return error.message


def description_problems(spec: object, needs: Iterable[str] = ()) -> list[str]:
    """Every way ``spec`` breaks the schema or misses what ``needs`` asks for.

    Parameters
    ----------
    spec : object
        The parsed experiment.json.
    needs : iterable of str
        Keys of :data:`NEEDS`.

    Returns
    -------
    list of str
        One ``field: problem`` text per problem, in field order; empty when none.
    """
    validator = Draft202012Validator(experiment_schema())
    problems = [
        (list(error.absolute_path), f"{_where(error.absolute_path)}: {_message(error)}")
        for error in validator.iter_errors(spec)
    ]
    if isinstance(spec, dict):
        points = has_point_target(spec)
        for need in needs:
            if need == "particles" and "time_resolved" in spec:
                continue  # it gives the Δt values and the frame pairs
            fields = POINT_TARGET_NEEDS if need == "calibration" and points else NEEDS[need]
            for field in fields:
                choice = (field,) if isinstance(field, str) else field
                if not any(f in spec for f in choice):
                    text = f"{choice[0]}: required to {_VERB[need]}"
                    text += f" (or {', '.join(choice[1:])})" if len(choice) > 1 else ""
                    problems.append(([choice[0]], text))
            if need == "particles" and spec.get("particle_images", "") is None:
                problems.append((["particle_images"], "particle_images: null, no particle images"))
        problems += _listed_images_problems(spec)
        cameras = spec.get("cameras")
        if isinstance(cameras, dict) and not points:
            problems += [
                (
                    ["cameras", name, "window"],
                    f"{_where(['cameras', name, 'window'])}: only a point target's pinhole "
                    "uses a window (a plate's model-free rays need none)",
                )
                for name, info in cameras.items()
                if isinstance(info, dict) and "window" in info
            ]
        if "calibration" in needs and isinstance(cameras, dict) and not points:
            problems += [
                (
                    ["cameras", name, field],
                    f"{_where(['cameras', name, field])}: required to calibrate",
                )
                for name, info in cameras.items()
                if isinstance(info, dict)
                for field in CALIBRATION_CAMERA_FIELDS
                if field not in info
            ]
    problems.sort(key=lambda p: [str(part) for part in p[0]])
    return [text for _, text in problems]


def _listed_images_problems(spec: dict) -> list[tuple[list, str]]:
    """A list of plate images (``calibration_images``) as long as the traverse, no entry
    twice."""
    listed, z = spec.get("calibration_images"), spec.get("traverse_z")
    if not (isinstance(listed, list) and isinstance(z, list)):
        return []
    if not all(isinstance(entry, str) for entry in listed):
        return []  # the schema names the entry
    if len(listed) != len(z):
        text = (
            f"calibration_images: {len(listed)} entries, but traverse_z gives {len(z)} "
            "plate positions (one image pattern per position)"
        )
        return [(["calibration_images"], text)]
    twice = sorted({entry for entry in listed if listed.count(entry) > 1}, key=str)
    if twice:
        return [(["calibration_images"], f"calibration_images: {twice[0]!r} given twice")]
    return []


def read_experiment(folder: str | Path, needs: Iterable[str] = ()) -> dict:
    """Read ``folder``/experiment.json and check it against the schema and ``needs``.

    Parameters
    ----------
    folder : path-like
        The dataset folder.
    needs : iterable of {"particles", "calibration"}
        What the description must allow beyond the schema (:data:`NEEDS`): processing
        particle images, calibrating.

    Returns
    -------
    dict
        The description as parsed from JSON.

    Raises
    ------
    FileNotFoundError
        No experiment.json.
    DescriptionError
        Not JSON, or one or more problems: all of them in one line, naming the file.

    Examples
    --------
    A description of two cameras recording one frame pair at each of two Δt: enough to
    process particle images, not to calibrate.

    >>> import json, pathlib, tempfile
    >>> import ptv
    >>> tmp = tempfile.TemporaryDirectory()
    >>> folder = pathlib.Path(tmp.name)
    >>> spec = {"cameras": {"c1": {"image_size": [48, 32]}, "c2": {"image_size": [48, 32]}},
    ...         "dt": [1e-3, 2e-3], "frames_per_dt": 1, "bit_depth": 12,
    ...         "particle_images": "{camera}_{k}_{m}_{a|b}.tif"}
    >>> _ = (folder / "experiment.json").write_text(json.dumps(spec))
    >>> ptv.read_experiment(folder, needs=("particles",))["dt"]  # s
    [0.001, 0.002]
    >>> ptv.read_experiment(folder, needs=("calibration",))
    Traceback (most recent call last):
    ...
    ptv.io.experiment_file.DescriptionError: ...: 7 problems: ... target: required to calibrate; ...
    >>> tmp.cleanup()
    """
    path = Path(folder) / "experiment.json"
    if not path.is_file():
        raise FileNotFoundError(f"{folder} is not a dataset folder: {path.name} is missing")
    try:
        spec = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as err:
        raise DescriptionError(f"{path}: not readable as JSON ({err})") from None
    problems = description_problems(spec, needs)
    if problems:
        count = f"{len(problems)} problems" if len(problems) > 1 else "1 problem"
        raise DescriptionError(f"{path}: {count}: {'; '.join(problems)}")
    return spec
