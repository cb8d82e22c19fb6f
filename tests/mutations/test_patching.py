"""Every mutation changes what it patches while applied, and leaves no trace after."""

import numpy as np
import pytest

import validation.claims  # noqa: F401  (the modules the claims use, loaded before patching)
from ptv.stats.dissipation import epsilon_estimate
from validation.claims import CLAIMS
from validation.mutations import MUTATIONS, mutation
from validation.mutations.image_stack import DETECTION, LINKING, MATCHING
from validation.mutations.patching import Patch, applied, edited

NAMES = [m.name for m in MUTATIONS]
#: Claims expected by mutations that other work adds to the registry.
PENDING = set(DETECTION + MATCHING + LINKING)


def test_the_registry_has_at_least_twenty_uniquely_named_mutations():
    assert len(NAMES) >= 20
    assert len(set(NAMES)) == len(NAMES)


@pytest.mark.parametrize("name", NAMES)
def test_expected_killers_are_claims_of_the_groups_the_mutation_runs(name):
    chosen = mutation(name)
    registered = {c.id for c in CLAIMS}
    assert set(chosen.expected) <= registered | PENDING
    assert {c.split(".")[0] for c in chosen.expected} <= set(chosen.groups)


@pytest.mark.parametrize("name", NAMES)
def test_the_probe_changes_under_the_mutation_and_is_restored_after_it(name):
    chosen = mutation(name)
    originals = [p.original() for p in chosen.patches]
    before = np.asarray(chosen.probe(), dtype=float)
    with chosen.applied():
        assert all(p.original() is not o for p, o in zip(chosen.patches, originals, strict=True))
        during = np.asarray(chosen.probe(), dtype=float)
    after = np.asarray(chosen.probe(), dtype=float)
    assert all(p.original() is o for p, o in zip(chosen.patches, originals, strict=True))
    assert before.shape != during.shape or not np.array_equal(before, during, equal_nan=True)
    np.testing.assert_array_equal(after, before)


def test_a_patched_function_is_replaced_where_it_was_imported_by_name():
    import ptv.triangulate
    import validation.truth.calibration_errors as errors

    original = ptv.triangulate.triangulate
    with applied((Patch("ptv.triangulate:triangulate", lambda f: "patched"),)):
        assert errors.triangulate == "patched" == ptv.triangulate.triangulate
    assert errors.triangulate is original is ptv.triangulate.triangulate


def test_a_source_edit_must_name_text_that_occurs_exactly_once():
    with pytest.raises(ValueError, match="occurs 0 times"):
        edited("no such text", "x")(np.linalg.norm)
    with pytest.raises(ValueError, match=r"occurs [2-9] times"):
        edited("kolmogorov_c2", "1.5")(epsilon_estimate)
