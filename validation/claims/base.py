"""What a claim is and what checking it gives (docs/claims.md)."""

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from validation.claims.context import ClaimContext


@dataclass(frozen=True)
class ClaimResult:
    """The outcome of one claim.

    Attributes
    ----------
    id, source, statement : str
        The claim: its id, where the paper makes it, what it states.
    value : float
        What the check measured (its unit in ``tolerance``).
    tolerance : str
        The tolerance in words, and where it comes from.
    passed : bool
        Whether the value is within the tolerance.
    limit : float or None
        The one number the value is compared with, where there is one.

    Examples
    --------
    >>> import validation
    >>> ctx = validation.ClaimContext("quick")
    >>> result = validation.run_claims(ctx, ids=["optics.snell"])[0]
    >>> result.id, result.source, result.passed
    ('optics.snell', "§2 (the tank's windows; docs/optics.md §4)", True)
    >>> result.statement
    "the simulated cameras refract by Snell's law with the indices the rig states"
    >>> sorted(result.as_dict())  # as synptv claims --json prints it
    ['id', 'limit', 'passed', 'source', 'statement', 'tolerance', 'value']
    """

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
