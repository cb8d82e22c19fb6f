"""The sensitivity audit covers every setting and constant of the chain, and its
perturbations change what they name."""

import ast
import dataclasses
import importlib
import math
import re
from pathlib import Path

import pytest

from ptv.settings import DetectorSettings, PipelineSettings, StatisticsSettings
from validation.audit import AUDITED, AuditRow, audit_table, perturbations
from validation.audit.catalogue import Audited

ROOT = Path(__file__).resolve().parents[2]
#: The chain's code whose public module constants the audit must list: packages and
#: single modules.
CHAIN = (
    "ptv/settings.py",
    "ptv/bins.py",
    "ptv/detect",
    "ptv/matching",
    "ptv/tracking",
    "ptv/stats",
    "ptv/pipeline",
    "simulator/render",
)
TARGETS = {a.target for a in AUDITED}


@pytest.mark.parametrize("cls", [PipelineSettings, DetectorSettings, StatisticsSettings])
def test_every_settings_field_is_audited(cls):
    for field in dataclasses.fields(cls):
        assert f"{cls.__module__}:{cls.__name__}.{field.name}" in TARGETS, field.name


def _public_constants(path: Path) -> list[str]:
    names = []
    for node in ast.parse(path.read_text()).body:
        targets = node.targets if isinstance(node, ast.Assign) else [getattr(node, "target", None)]
        for target in targets:
            if isinstance(target, ast.Name) and re.fullmatch(r"[A-Z][A-Z0-9_]*", target.id):
                names.append(target.id)
    return names


def test_every_public_constant_of_the_chain_is_audited():
    missing = []
    for package in CHAIN:
        where = ROOT / package
        for path in [where] if where.is_file() else sorted(where.glob("*.py")):
            module = ".".join(path.relative_to(ROOT).with_suffix("").parts)
            missing += [
                f"{module}:{name}"
                for name in _public_constants(path)
                if f"{module}:{name}" not in TARGETS
            ]
    assert not missing, f"add to validation/audit/catalogue.py: {missing}"


def test_entries_not_run_say_why_and_the_others_name_their_claims():
    for audited in AUDITED:
        if audited.kind == "not run":
            assert audited.reason and not perturbations(audited)
        else:
            assert audited.groups and len(perturbations(audited)) >= 1


@pytest.mark.parametrize(
    "audited", [a for a in AUDITED if a.kind != "not run"], ids=lambda a: a.target
)
def test_each_perturbation_changes_its_target_and_restores_it(audited):
    module, _, path = audited.target.partition(":")

    def current():
        owner = importlib.import_module(module)
        if audited.is_field:
            cls_name, field_name = path.split(".")
            return getattr(getattr(owner, cls_name)(), field_name)
        return getattr(owner, path)

    before = current()
    for chosen in perturbations(audited):
        with chosen.applied():
            assert current() != before
        assert current() == before


def test_the_table_says_what_each_perturbation_did():
    tolerance = Audited("m:Settings.tolerance", "tolerance")
    rows = [
        AuditRow(tolerance, "×0.5", ("image.linking",)),
        AuditRow(tolerance, "×2", (), 0.05, "image.crowded_ghosts"),
        AuditRow(Audited("m:FACTOR", "physical"), "+10 %", (), 0.4, "image.detection_rms"),
        AuditRow(Audited("m:FORMAT", "not run", (), reason="a file format's name")),
    ]
    assert [r.verdict for r in rows] == ["killed", "within a tenth", "gap", "not run"]
    table = audit_table(rows)
    assert "0.40 of its room" in table and "a file format's name" in table
    assert "`m.FACTOR`" in table and "`Settings.tolerance`" in table
    assert "3 perturbations of 2 settings run: 1 killed, 1 within a tenth" in table
    assert math.isnan(AuditRow(tolerance, "×2").effect)
