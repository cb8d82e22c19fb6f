"""The kill table of a mutation run, in words."""

from collections.abc import Sequence

from validation.mutations.runner import Outcome


def kill_rate(outcomes: Sequence[Outcome]) -> tuple[int, int]:
    """Mutations killed by at least one claim, and mutations run."""
    return sum(bool(o.killed_by) for o in outcomes), len(outcomes)


def kill_table(outcomes: Sequence[Outcome]) -> list[str]:
    """One line per mutation (name, killed by, expected, status), then the kill rate."""
    lines = [f"{'mutation':34s} {'status':16s} killed by / expected"]
    for o in outcomes:
        killers = ", ".join(o.killed_by) or "-"
        lines.append(f"{o.mutation.name:34s} {o.status:16s} {killers}")
        expected = ", ".join(
            c + (" (not registered)" if c in o.awaiting else "") for c in o.mutation.expected
        )
        if not expected and o.mutation.run_checks:
            expected = "the run's " + ", ".join(o.mutation.run_checks) + " (not claims)"
        lines.append(f"{'':34s} {'':16s} expected: {expected or '- (out of scope)'}")
        lines.extend(
            f"{'':34s} {'':16s} {claim} raised {error}" for claim, error in o.errors.items()
        )
    killed, total = kill_rate(outcomes)
    waiting = sum(o.status == "awaiting claims" for o in outcomes)
    lines.append(
        f"{killed} of {total} mutations killed ({killed / max(total, 1):.0%}); "
        f"{waiting} waiting for claims not in the registry"
    )
    return lines
