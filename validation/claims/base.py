"""What a claim is and what checking it gives (docs/claims.md)."""

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from validation.claims.context import ClaimContext


@dataclass(frozen=True)
class ClaimResult:
    """The outcome of one claim."""

    id: str
    source: str
    statement: str
    value: float
    tolerance: str
    passed: bool
    limit: float | None = None

    def as_dict(self) -> dict:
        """JSON-able form: id, source, statement, value, tolerance, passed, limit."""
        return {
            "id": self.id,
            "source": self.source,
            "statement": self.statement,
            "value": float(self.value),
            "tolerance": self.tolerance,
            "passed": bool(self.passed),
            "limit": None if self.limit is None else float(self.limit),
        }


@dataclass(frozen=True)
class Claim:
    """A statement of the paper and how to check it."""

    id: str
    source: str
    statement: str
    check: Callable[["Claim", "ClaimContext"], ClaimResult]


def result(
    claim: Claim, value: float, tolerance: str, passed: bool, *, limit: float | None = None
) -> ClaimResult:
    """The result of ``claim``: its measured value, the tolerance in words, pass or fail.

    ``limit``, where the claim compares its value with one number, is that number (for a
    two-sided tolerance, the bound on the value's side): the room a change of the code
    leaves the claim is then |limit − value| (``synptv claims --audit``).
    """
    return ClaimResult(
        claim.id, claim.source, claim.statement, value, tolerance, bool(passed), limit
    )
