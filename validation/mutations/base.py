"""What a mutation is: a named, deliberate break of the code and the claims that must catch it."""

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

from validation.mutations.patching import Patch, applied


@dataclass(frozen=True)
class Mutation:
    """One deliberate break of the code (docs/claims.md §5).

    Attributes
    ----------
    name : str
        Short name (kebab case).
    description : str
        What is broken, in words.
    patches : tuple of Patch
        The objects replaced while the mutation is applied.
    expected : tuple of str
        Claim ids that must fail with the mutation applied (empty: out of every
        claim's scope, docs/claims.md §5 says why).
    groups : tuple of str
        Claim groups (the id's prefix before the first dot: ``calib``, ``stats``,
        ``optics``, ``image``, ...) that can see the mutation; only their claims are
        run, for time.
    probe : callable
        A cheap computation through the patched code, returning numbers that differ
        with the mutation applied (proof that the patch reaches what it names).
    run_checks : tuple of str
        For a mutation out of every claim's reach (``expected`` empty): the required
        checks of ``synptv run`` that fail with it (ids of the run's verdict), shown by
        a test of their own (``tests/mutations/test_dns_kills.py``), not by the claims
        runner.
    """

    name: str
    description: str
    patches: tuple[Patch, ...]
    expected: tuple[str, ...]
    groups: tuple[str, ...]
    probe: Callable[[], Any]
    run_checks: tuple[str, ...] = ()

    @contextmanager
    def applied(self) -> Iterator[None]:
        """The code with this mutation, for the duration of the block."""
        with applied(self.patches):
            yield
