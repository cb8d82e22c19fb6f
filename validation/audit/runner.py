"""Run the audit's perturbations, each in a process of its own, against one control."""

from collections.abc import Callable
from dataclasses import dataclass

from validation.audit.catalogue import AUDITED, Audited, perturbation, perturbations
from validation.mutations.runner import ClaimFailures, run_separately

#: A survivor moving a claim's value by more than this fraction of the room its limit
#: left it is a gap (docs/claims.md §6).
GAP_FRACTION = 0.1


@dataclass(frozen=True)
class AuditRow:
    """One perturbation's outcome (or an entry not run).

    Attributes
    ----------
    audited : Audited
        The setting or constant.
    label : str
        The perturbation (``×0.5``, ``+10 %``, ...; empty when not run).
    killed_by : tuple of str
        Claims that failed with it and pass in the control.
    effect : float
        Survivors: the largest |Δ value| / |limit − value| over the claims run that
        have a limit (nan when none moved or none has one).
    moved : str
        The claim of that largest effect (empty when no claim's value moved).
    """

    audited: Audited
    label: str = ""
    killed_by: tuple[str, ...] = ()
    effect: float = float("nan")
    moved: str = ""

    @property
    def verdict(self) -> str:
        """``killed``, ``within a tenth``, ``gap`` or ``not run``."""
        if self.audited.kind == "not run":
            return "not run"
        if self.killed_by:
            return "killed"
        return "gap" if not self.effect <= GAP_FRACTION else "within a tenth"


def _effect(control: ClaimFailures, run: ClaimFailures) -> tuple[float, str]:
    worst, claim = float("nan"), ""
    for claim_id, value in run.values.items():
        limit = control.limits.get(claim_id)
        before = control.values.get(claim_id)
        if limit is None or before is None or limit == before:
            continue
        effect = abs(value - before) / abs(limit - before)
        if not worst >= effect:
            worst, claim = effect, claim_id if effect > 0 else ""
    return worst, claim


def run_audit(
    size: str = "quick",
    *,
    seed: int = 0,
    workers: int = 2,
    progress: Callable[[ClaimFailures], None] | None = None,
) -> list[AuditRow]:
    """Every entry of :data:`AUDITED`: its perturbations run against a control run."""
    runs_of = {a.target: perturbations(a) for a in AUDITED}
    names = [m.name for ms in runs_of.values() for m in ms]
    runs = run_separately(names, size, seed, workers, progress, lookup=perturbation)
    control = runs[None]
    rows = []
    for audited in AUDITED:
        if not runs_of[audited.target]:
            rows.append(AuditRow(audited))
            continue
        for chosen in runs_of[audited.target]:
            run = runs[chosen.name]
            killed = tuple(c for c in run.failed if c not in control.failed)
            effect, moved = _effect(control, run) if not killed else (float("nan"), "")
            label = chosen.name.removeprefix(audited.target).strip()
            rows.append(AuditRow(audited, label, killed, effect, moved))
    return rows
