"""Apply each mutation, rerun the claims it can affect on a fresh context, record what fails.

Every mutation runs in a process of its own (spawned, one task per process), so nothing a
mutation leaves behind (patched references, compiled kernels, caches of the context or
of any module) can reach the next one; a first run without mutation (the control) gives
the claims that fail anyway, which no mutation is credited with.
"""

import os
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from contextlib import nullcontext
from dataclasses import dataclass, field
from multiprocessing import get_context

import numba

from validation.claims import CLAIMS, ClaimContext
from validation.mutations import MUTATIONS, Mutation, mutation


def claim_group(claim_id: str) -> str:
    """The group of a claim: its id up to the first dot (``calib``, ``stats``, ...)."""
    return claim_id.split(".", 1)[0]


@dataclass(frozen=True)
class ClaimFailures:
    """The claims that failed in one run (with or without a mutation).

    Attributes
    ----------
    name : str or None
        The mutation (None: the control run).
    failed : tuple of str
        Ids of the claims that failed or raised.
    errors : dict
        Claim id → the exception a claim raised (those count as failed).
    checked : tuple of str
        Ids of the claims run.
    seconds : float
        Wall time of the run.
    values : dict
        Claim id → its measured value, and (``limits``) its limit where it has one.
    limits : dict
    """

    name: str | None
    failed: tuple[str, ...]
    errors: dict[str, str]
    checked: tuple[str, ...]
    seconds: float
    values: dict[str, float] = field(default_factory=dict)
    limits: dict[str, float] = field(default_factory=dict)


def failing_claims(
    name: str | None, size: str, seed: int, threads: int, *, lookup: Callable = mutation
) -> ClaimFailures:
    """Run the claims of the groups ``name`` can affect (all without a mutation) on a
    fresh :class:`~validation.claims.ClaimContext` with the mutation applied.

    ``lookup`` finds the :class:`Mutation` of a name (the registry's, or the sensitivity
    audit's perturbations: :func:`validation.audit.perturbation`).
    """
    numba.set_num_threads(max(1, min(threads, numba.config.NUMBA_NUM_THREADS)))
    start = time.perf_counter()
    chosen = lookup(name) if name is not None else None
    claims = [c for c in CLAIMS if chosen is None or claim_group(c.id) in chosen.groups]
    errors: dict[str, str] = {}
    passed: set[str] = set()
    values: dict[str, float] = {}
    limits: dict[str, float] = {}
    with chosen.applied() if chosen is not None else nullcontext():
        try:
            ctx = ClaimContext(size, seed=seed)
        except Exception as err:  # no claim can be checked: every one has caught it
            errors = {c.id: f"{type(err).__name__}: {err}" for c in claims}
        else:
            for claim in claims:
                try:
                    outcome = claim.check(claim, ctx)
                except Exception as err:  # a claim the mutation makes crash has caught it
                    errors[claim.id] = f"{type(err).__name__}: {err}"
                    continue
                values[claim.id] = float(outcome.value)
                if outcome.limit is not None:
                    limits[claim.id] = float(outcome.limit)
                if outcome.passed:
                    passed.add(claim.id)
    failed = tuple(c.id for c in claims if c.id not in passed)
    return ClaimFailures(
        name,
        failed,
        errors,
        tuple(c.id for c in claims),
        time.perf_counter() - start,
        values,
        limits,
    )


def run_separately(
    names: Sequence[str],
    size: str,
    seed: int,
    workers: int,
    progress: Callable[[ClaimFailures], None] | None = None,
    *,
    lookup: Callable = mutation,
) -> dict[str | None, ClaimFailures]:
    """:func:`failing_claims` of a control (key None) and of each name, every run in a
    spawned process of its own, ``workers`` at once, the CPU's threads shared out."""
    threads = max(1, (os.cpu_count() or 1) // workers)
    runs: dict[str | None, ClaimFailures] = {}
    with ProcessPoolExecutor(
        workers, mp_context=get_context("spawn"), max_tasks_per_child=1
    ) as pool:
        futures = [
            pool.submit(failing_claims, name, size, seed, threads, lookup=lookup)
            for name in [None, *names]
        ]
        for future in as_completed(futures):
            done = future.result()
            runs[done.name] = done
            if progress is not None:
                progress(done)
    return runs


@dataclass(frozen=True)
class Outcome:
    """What one mutation did to the claims.

    Attributes
    ----------
    mutation : Mutation
        The mutation.
    killed_by : tuple of str
        Claims that failed with it and pass without it.
    registered : tuple of str
        Ids of the claims in the registry (those a missing expected killer is not among).
    errors : dict
        Claim id → exception raised under the mutation.
    seconds : float
        Wall time of its run.
    """

    mutation: Mutation
    killed_by: tuple[str, ...]
    registered: tuple[str, ...]
    errors: dict[str, str]
    seconds: float

    @property
    def awaiting(self) -> tuple[str, ...]:
        """Expected killers not in the registry (yet)."""
        return tuple(c for c in self.mutation.expected if c not in self.registered)

    @property
    def missed(self) -> tuple[str, ...]:
        """Expected killers in the registry that passed."""
        return tuple(
            c for c in self.mutation.expected if c in self.registered and c not in self.killed_by
        )

    @property
    def status(self) -> str:
        """``killed``; ``partly killed`` (an expected killer passed); ``survived``;
        ``awaiting claims`` (no expected killer registered yet); ``out of scope`` (no
        claim is expected to catch it, docs/claims.md §5); ``run checks`` (no claim
        can, required checks of a run do: ``Mutation.run_checks``, shown by their own
        test)."""
        if self.missed:
            return "partly killed" if self.killed_by else "survived"
        if self.killed_by:
            return "killed"
        if self.awaiting:
            return "awaiting claims"
        return "run checks" if self.mutation.run_checks else "out of scope"

    @property
    def ok(self) -> bool:
        """Whether the claims did what the mutation expects of them."""
        return self.status in ("killed", "awaiting claims", "out of scope", "run checks")

    def as_dict(self) -> dict:
        """JSON-able form: mutation, description, killed_by, expected_killers, killed,
        status, errors, seconds."""
        return {
            "mutation": self.mutation.name,
            "description": self.mutation.description,
            "killed_by": list(self.killed_by),
            "expected_killers": list(self.mutation.expected),
            "killed": bool(self.killed_by),
            "status": self.status,
            "errors": self.errors,
            "seconds": round(self.seconds, 1),
        }


def run_mutations(
    size: str = "quick",
    *,
    seed: int = 0,
    names: Sequence[str] | None = None,
    workers: int = 2,
    progress: Callable[[ClaimFailures], None] | None = None,
) -> tuple[ClaimFailures, list[Outcome]]:
    """The control run and every mutation's outcome, in registry order.

    Parameters
    ----------
    size : {"quick", "full"}
        Sample sizes of the claims.
    seed : int
        Seed of every run.
    names : sequence of str, optional
        Mutations to run (default all).
    workers : int
        Processes run at once; each gets the CPU's threads shared out evenly.
    progress : callable, optional
        Called with each run's failures as it completes.
    """
    chosen = [mutation(n) for n in names] if names is not None else list(MUTATIONS)
    runs = run_separately([m.name for m in chosen], size, seed, workers, progress)
    control = runs[None]
    outcomes = [
        Outcome(
            m,
            tuple(c for c in runs[m.name].failed if c not in control.failed),
            control.checked,
            runs[m.name].errors,
            runs[m.name].seconds,
        )
        for m in chosen
    ]
    return control, outcomes
