"""Reading a scenario's TOML tables into their dataclasses: typed fields, one error line
naming the file and the field."""

import logging
import math
from dataclasses import fields
from typing import get_args

log = logging.getLogger(__name__)

#: Keys that a scenario's tables once had, read under the settings' names they now share
#: (:mod:`ptv.settings`): table → old key → the new key, or the new keys that the old
#: key's list of values is split into.
RENAMED = {
    "ptv": {
        "r_range": ("r_min", "r_max"),
        "bins": ("n_bins",),
        "analysis_volume": ("analysis_size",),
    }
}


class ScenarioError(ValueError):
    """A scenario file or name that cannot be used; the message names file and field."""


def renamed_keys(spec: dict, source: str) -> dict:
    """``spec`` with the old keys of its tables (:data:`RENAMED`) read under their new
    names, each with a warning that names the old and the new keys.

    Raises
    ------
    ScenarioError
        An old key beside one of its new keys, or an old list of the wrong length.
    """
    spec = dict(spec)
    for key, renamed in RENAMED.items():
        table = spec.get(key)
        if not isinstance(table, dict) or not renamed.keys() & table.keys():
            continue
        table = dict(table)
        for old, new in renamed.items():
            if old not in table:
                continue
            value = table.pop(old)
            names = " and ".join(f"{key}.{n}" for n in new)
            both = [n for n in new if n in table]
            if both:
                raise ScenarioError(
                    f"{source}: {key}.{old} is the old name of {names}: give {key}.{both[0]} only"
                )
            if len(new) == 1:
                table[new[0]] = value
            elif isinstance(value, list | tuple) and len(value) == len(new):
                table.update(zip(new, value, strict=True))
            else:
                raise ScenarioError(
                    f"{source}: {key}.{old} must be a list of {len(new)} numbers, got {value!r}"
                )
            log.warning("%s: %s.%s is an old name, read as %s: write that", source, key, old, names)
        spec[key] = table
    return spec


def typed(value: object, kind: type, where: str):
    """``value`` as ``kind`` (an integer is a float too), or a ScenarioError naming ``where``."""
    if kind is float and isinstance(value, int) and not isinstance(value, bool):
        value = float(value)
    if type(value) is not kind:
        raise ScenarioError(f"{where} must be {kind.__name__}, got {value!r}")
    if kind is float and not math.isfinite(value):
        raise ScenarioError(f"{where} must be a finite number, got {value!r}")
    return value


def section(cls, table: object, source: str, key: str):
    """The section dataclass ``cls`` from TOML table ``[key]`` of ``source``; each field
    typed as its default is."""
    if not isinstance(table, dict):
        raise ScenarioError(f"{source}: [{key}] must be a table")
    where = f"{source}: {key}"
    known = {f.name: f for f in fields(cls)}
    unknown = sorted(set(table) - set(known))
    if unknown:
        raise ScenarioError(
            f"{where}: unknown field(s) {', '.join(map(repr, unknown))}; known: {', '.join(known)}"
        )
    values = {}
    for name, value in table.items():
        default = getattr(cls(), name)
        if value is None and default is None:  # as written by Scenario.as_dict
            values[name] = None
            continue
        if isinstance(default, tuple):
            if not isinstance(value, list | tuple):
                raise ScenarioError(f"{where}.{name} must be a list, got {value!r}")
            item = type(default[0])
            value = tuple(typed(v, item, f"{where}.{name}") for v in value)
            if item is float and len(value) != len(default):
                raise ScenarioError(
                    f"{where}.{name} must be a list of {len(default)} numbers, got {list(value)}"
                )
        else:  # a default of None stands for a value the run measures or derives
            kind = type(default)
            if default is None:
                kind = next(a for a in get_args(known[name].type) if a is not type(None))
            value = typed(value, kind, f"{where}.{name}")
        values[name] = value
    try:
        return cls(**values)
    except ValueError as err:
        raise ScenarioError(f"{where}: {err}") from None
