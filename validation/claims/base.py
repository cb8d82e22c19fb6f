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

    def as_dict(self) -> dict:
        """JSON-able form: id, source, statement, value, tolerance, passed."""
        return {
            "id": self.id,
            "source": self.source,
            "statement": self.statement,
            "value": float(self.value),
            "tolerance": self.tolerance,
            "passed": bool(self.passed),
        }


@dataclass(frozen=True)
class Claim:
    """A statement of the paper and how to check it."""

    id: str
    source: str
    statement: str
    check: Callable[["Claim", "ClaimContext"], ClaimResult]


def result(claim: Claim, value: float, tolerance: str, passed: bool) -> ClaimResult:
    """The result of ``claim``: its measured value, the tolerance in words, pass or fail."""
    return ClaimResult(claim.id, claim.source, claim.statement, value, tolerance, bool(passed))
