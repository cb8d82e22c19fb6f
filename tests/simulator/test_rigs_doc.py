"""docs/rigs.md documents every field of a rig file, and its example loads."""

import re
import tomllib
from pathlib import Path

from simulator import rigs

DOC = Path(__file__).resolve().parents[2] / "docs" / "rigs.md"


def _documented_fields() -> set[str]:
    """The field names in the first column of the page's tables (`name` or `[table]`)."""
    fields = set()
    for line in DOC.read_text(encoding="utf-8").splitlines():
        match = re.match(r"\|\s*`\[*(?:cameras\.)?([a-z_]+)\]*`\s*\|", line)
        if match:
            fields.add(match.group(1))
    return fields


def _rig_fields() -> set[str]:
    """Every field a rig file may hold, from the loader's own tables."""
    fields = set(rigs._TOP) | set(rigs._SHEET) | set(rigs._CAMERA) | set(rigs._WINDOW)
    fields |= set(rigs._DISTORTION)
    for tank in rigs._TANKS.values():
        fields |= set(tank)
    return fields


def test_every_rig_field_is_documented():
    missing = _rig_fields() - _documented_fields() - set(rigs._DISTORTION)
    assert not missing, f"rig fields missing from docs/rigs.md: {sorted(missing)}"
    text = DOC.read_text(encoding="utf-8")
    for coefficient in rigs._DISTORTION:  # named in the distortion row and §4.1
        assert re.search(rf"\b{coefficient}\b", text), coefficient


def test_every_documented_range_is_the_loaders():
    """A table row's range is the loader's limit for that field."""
    rows = {}
    for line in DOC.read_text(encoding="utf-8").replace("−", "-").splitlines():
        match = re.match(r"\|\s*`([a-z_]+)`\s*\|\s*[^|]*\|\s*([-0-9.e]+)–([-0-9.e]+)", line)
        if match:
            rows[match.group(1)] = (float(match.group(2)), float(match.group(3)))
    assert set(rigs._LIMITS) <= set(rows), sorted(set(rigs._LIMITS) - set(rows))
    for field, (low, high, _) in rigs._LIMITS.items():
        assert rows[field] == (low, high), field


def test_the_annotated_example_loads():
    text = DOC.read_text(encoding="utf-8")
    block = re.search(r"## 6\. An annotated example.*?```toml\n(.*?)```", text, re.S).group(1)
    rig = rigs.rig_from_dict(tomllib.loads(block), source="docs/rigs.md")
    assert rig.camera_names == ("left", "right")
    assert rig.tank.kind == "free"
    assert rig.sheet.size == (0.080, 0.060, 0.004)
    left, right = rig.cameras
    assert left.lens.k1 == -0.05 and left.lens.p1 == 0.0005
    assert right.interfaces is not None and left.interfaces is not None
