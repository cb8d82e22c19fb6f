"""Every mutation makes the claims it names fail (slow: one claims run per mutation)."""

import os

import pytest

from validation.claims import CLAIMS
from validation.mutations import MUTATIONS, mutation
from validation.mutations.runner import failing_claims


@pytest.mark.slow
@pytest.mark.parametrize("name", [m.name for m in MUTATIONS])
def test_the_mutation_is_killed_by_its_expected_claims(name):
    chosen = mutation(name)
    if not chosen.expected and chosen.run_checks:
        pytest.skip(
            f"out of every claim's reach; tests/mutations/test_dns_kills.py shows the run's "
            f"{', '.join(chosen.run_checks)} kill it"
        )
    registered = {c.id for c in CLAIMS}
    expected = [c for c in chosen.expected if c in registered]
    if chosen.expected and not expected:
        pytest.xfail(f"its killers {', '.join(chosen.expected)} are not in the registry yet")
    failures = failing_claims(name, "quick", 0, os.cpu_count() or 1)
    assert failures.failed, f"{name} survived every claim of {', '.join(chosen.groups)}"
    assert set(expected) <= set(failures.failed)
