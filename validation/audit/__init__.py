"""The sensitivity audit (``synptv claims --audit``, docs/claims.md §6): every named
setting and constant of the chain perturbed, the claims that can see it rerun, and
what each perturbation did: killed by a claim, or the most it moved any claim's value
against the room that claim's limit left it."""

from validation.audit.catalogue import AUDITED, Audited, perturbation, perturbations
from validation.audit.runner import AuditRow, run_audit
from validation.audit.table import audit_table

__all__ = [
    "AUDITED",
    "AuditRow",
    "Audited",
    "audit_table",
    "perturbation",
    "perturbations",
    "run_audit",
]
