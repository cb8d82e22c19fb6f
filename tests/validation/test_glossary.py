"""docs/glossary.md names every check id ``synptv run`` can print and every claim id: the
ids are read from the code (the literal first argument of each check-row builder, the
recording's check table, the Δt subsets, the claims), so a new check or claim without its
line fails here."""

import ast
import inspect
from pathlib import Path

from validation.claims import CLAIMS
from validation.report import recording_report
from validation.run import verdict
from validation.run.checks import SUBSET_TOLERANCES

GLOSSARY = Path(__file__).resolve().parents[2] / "docs" / "glossary.md"
#: The functions that build a check row from its id (first argument).
ROW_BUILDERS = {"_row", "_check", "_relative_check"}


def check_ids() -> set[str]:
    """Every check id the frame-pair and the recording verdicts can emit."""
    ids = set()
    for module in (verdict, recording_report):
        for node in ast.walk(ast.parse(inspect.getsource(module))):
            if isinstance(node, ast.Call) and getattr(node.func, "id", None) in ROW_BUILDERS:
                first = node.args[0]
                if isinstance(first, ast.Constant):
                    ids.add(first.value)
                elif isinstance(first, ast.JoinedStr):  # "stats.dt_subsets: {name}"
                    prefix = first.values[0]
                    assert isinstance(prefix, ast.Constant), ast.unparse(first)
                    assert prefix.value == "stats.dt_subsets: ", ast.unparse(first)
                    ids |= {f"stats.dt_subsets: {name}" for name in SUBSET_TOLERANCES}
            if isinstance(node, ast.Dict):
                for key, value in zip(node.keys, node.values, strict=True):
                    if (
                        isinstance(key, ast.Constant)
                        and key.value == "id"
                        and isinstance(value, ast.Constant)
                    ):
                        ids.add(value.value)
    return ids | {row[0] for row in recording_report.TRACK_CHECKS}


def test_every_check_id_is_in_the_glossary():
    ids = check_ids()
    assert len(ids) >= 32  # the scan still finds what it found when written
    text = GLOSSARY.read_text()
    missing = sorted(i for i in ids if f"| `{i}` |" not in text)
    assert not missing, f"docs/glossary.md lacks {missing}"


def test_every_claim_id_is_in_the_glossary():
    claims = GLOSSARY.read_text().split("## 3. Claims")[1]
    missing = sorted(c.id for c in CLAIMS if f"| `{c.id}` |" not in claims)
    assert not missing, f"docs/glossary.md §3 lacks {missing}"


def test_the_glossary_names_no_id_the_code_does_not_emit():
    listed = {
        line.split("`")[1] for line in GLOSSARY.read_text().splitlines() if line.startswith("| `")
    }
    assert listed == check_ids() | {c.id for c in CLAIMS}
