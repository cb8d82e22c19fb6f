"""Reading a scenario's TOML tables into their dataclasses: typed fields, one error line
naming the file and the field."""

import math
from dataclasses import fields
from typing import get_args


class ScenarioError(ValueError):
    """A scenario file or name that cannot be used; the message names file and field."""


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
