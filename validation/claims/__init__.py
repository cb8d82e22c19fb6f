"""Every regressable statement of the paper, measured against truth (docs/claims.md).

A claim has an id, its source in the paper, what it states, and a check that measures a
value and compares it with a tolerance whose origin its text states. Checks share the
expensive runs through a :class:`ClaimContext` (one calibration comparison per rig, one
KS multi-Δt experiment on the Pope spectrum with and without a calibration scale error,
one on a band-limited K41 spectrum with and without an injected Δt³ term, one small
rendered case that the image stack measures) and compare
every estimate with a reference it shares no code with
(:mod:`validation.truth.independent`, :mod:`validation.truth.noise_floor`). Three
claims check the simulator itself against closed forms written apart from it: Snell's
law at the windows and the sheet's focus on Scheimpflug mounts (``optics.*``), Pope's
spectrum (``flow.pope_spectrum``); five check the rendered images against their
specification (:mod:`validation.claims.formation`), four the stack's choices where
particles crowd (:mod:`validation.claims.crowding`), two the conventions of a bin's r and
of Δt in files (:mod:`validation.claims.conventions`), and three the time-resolved
stack's track fits and Lagrangian statistics on a short recording of exact trajectories
measured with known noise (``tracks.*``, ``lagrangian.*``:
:mod:`validation.claims.fitted_tracks`), and two iterative particle reconstruction on
dense images: its OTF measured on the images against the optics' specification, and what
it finds (``ipr.*``: :mod:`validation.claims.ipr`). ``quick`` sizes run in CI (about a
minute on an idle 2-core machine); ``full`` sizes take the sample sizes the tolerances
were designed for.

Not regressed here: the calibration claims on rendered plate images
(``synptv calibrate`` and ``synptv run`` measure those; here dots are exact
projections plus noise).
"""

from collections.abc import Callable

from validation.claims.base import Claim, ClaimResult
from validation.claims.calibration import CALIBRATION_CLAIMS
from validation.claims.context import CORRELATION_LENGTH, SIZES, ClaimContext, Sizes
from validation.claims.conventions import CONVENTION_CLAIMS
from validation.claims.crowding import CROWDING_CLAIMS
from validation.claims.fitted_tracks import RECORDING_CLAIMS
from validation.claims.formation import FORMATION_CLAIMS
from validation.claims.image_stack import IMAGE_CLAIMS
from validation.claims.ipr import IPR_CLAIMS
from validation.claims.optics import OPTICS_CLAIMS
from validation.claims.run_statistics import RUN_STATISTICS_CLAIMS
from validation.claims.spectrum import SPECTRUM_CLAIMS
from validation.claims.statistics import FLOW_CLAIMS, STATISTICS_CLAIMS

__all__ = [
    "CLAIMS",
    "CORRELATION_LENGTH",
    "SIZES",
    "Claim",
    "ClaimContext",
    "ClaimResult",
    "Sizes",
    "run_claims",
]

CLAIMS: tuple[Claim, ...] = (
    FLOW_CLAIMS
    + SPECTRUM_CLAIMS
    + CALIBRATION_CLAIMS
    + OPTICS_CLAIMS
    + STATISTICS_CLAIMS
    + RUN_STATISTICS_CLAIMS
    + IMAGE_CLAIMS
    + FORMATION_CLAIMS
    + CROWDING_CLAIMS
    + CONVENTION_CLAIMS
    + RECORDING_CLAIMS
    + IPR_CLAIMS
)


def run_claims(
    ctx: ClaimContext,
    *,
    progress: Callable[[int, int], None] | None = None,
    ids: list[str] | None = None,
) -> list[ClaimResult]:
    """Check the claims (all, or those in ``ids``) in order.

    Parameters
    ----------
    ctx : ClaimContext
        The size, the seed and the runs the claims share.
    progress : callable(done, total), optional
        Called after each claim.
    ids : list of str, optional
        The claims to check (default: every claim of :data:`CLAIMS`).

    Returns
    -------
    list of ClaimResult
        One per claim, in the order of :data:`CLAIMS`.

    Raises
    ------
    ValueError
        An id of no claim.

    Examples
    --------
    Every claim at CI size takes minutes (``synptv claims``); two that check the
    simulator against closed forms take a fraction of a second:

    >>> import validation
    >>> from validation.claims import CLAIMS
    >>> len(CLAIMS), [claim.id for claim in CLAIMS[:3]]
    (56, ['table3.arithmetic', 'flow.pope_spectrum', 'calib.model_free_beats_tsai_scheimpflug'])
    >>> ctx = validation.ClaimContext("quick")
    >>> results = validation.run_claims(ctx, ids=["flow.pope_spectrum", "optics.snell"])
    >>> [(r.id, r.passed) for r in results]
    [('flow.pope_spectrum', True), ('optics.snell', True)]
    >>> validation.run_claims(ctx, ids=["optics.glass"])
    Traceback (most recent call last):
    ...
    ValueError: unknown claim id(s) ['optics.glass']
    """
    chosen = [c for c in CLAIMS if ids is None or c.id in ids]
    unknown = set(ids or ()) - {c.id for c in CLAIMS}
    if unknown:
        raise ValueError(f"unknown claim id(s) {sorted(unknown)}")
    results = []
    for n, claim in enumerate(chosen):
        results.append(claim.check(claim, ctx))
        if progress is not None:
            progress(n + 1, len(chosen))
    return results
