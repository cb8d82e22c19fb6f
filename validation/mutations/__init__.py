"""Named mutations: deliberate breaks of the code that the claims must catch (docs/claims.md §5).

Each :class:`Mutation` patches the stack (or the simulator, or the claims' synthetic
inputs) for the duration of a ``with mutation.applied():`` block and names the claims
that must fail; :mod:`validation.mutations.runner` applies each in a fresh process,
builds a fresh :class:`validation.claims.ClaimContext` and records which claims fail.
"""

from validation.mutations.base import Mutation
from validation.mutations.calibration import CALIBRATION_MUTATIONS
from validation.mutations.conventions import CONVENTION_MUTATIONS
from validation.mutations.crowding import CROWDING_MUTATIONS
from validation.mutations.dns import DNS_MUTATIONS
from validation.mutations.formation import FORMATION_MUTATIONS
from validation.mutations.image_stack import IMAGE_MUTATIONS
from validation.mutations.optics import OPTICS_MUTATIONS
from validation.mutations.reconstruction import RECONSTRUCTION_MUTATIONS
from validation.mutations.simulated_flow import FLOW_MUTATIONS
from validation.mutations.statistics import STATISTICS_MUTATIONS
from validation.mutations.tracks import TRACK_MUTATIONS

__all__ = ["MUTATIONS", "Mutation", "mutation"]

MUTATIONS: tuple[Mutation, ...] = (
    STATISTICS_MUTATIONS
    + FLOW_MUTATIONS
    + CALIBRATION_MUTATIONS
    + OPTICS_MUTATIONS
    + IMAGE_MUTATIONS
    + FORMATION_MUTATIONS
    + CROWDING_MUTATIONS
    + CONVENTION_MUTATIONS
    + DNS_MUTATIONS
    + TRACK_MUTATIONS
    + RECONSTRUCTION_MUTATIONS
)


def mutation(name: str) -> Mutation:
    """The mutation called ``name``."""
    for candidate in MUTATIONS:
        if candidate.name == name:
            return candidate
    raise ValueError(f"unknown mutation {name!r}; known: {', '.join(m.name for m in MUTATIONS)}")
