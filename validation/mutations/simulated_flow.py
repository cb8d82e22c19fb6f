"""Mutations of the simulator's flow and particles (``simulator.ks_field``,
``simulator.particles``).

The statistics claims see them: their references come from the flow's prescribed
spectrum (the exact D_LL, the input ε and its plateau deficit) and from the particles'
exact velocities (the brute-force S2_ref), so a flow that does not carry its stated
energy, or particles that do not move with it, show.
"""

from dataclasses import replace

import numpy as np

from simulator.ks_field import draw_ks_field
from simulator.particles import Box, KSFlow
from simulator.presets import flow_preset
from simulator.spectra import PopeSpectrum
from validation.mutations.base import Mutation
from validation.mutations.patching import Patch, edited

#: The mutated amplitude of every KS mode (u′ and the energy 5 % and 10 % high).
AMPLITUDE = 1.05


def _louder(original):
    def draw(*args, **options):
        field = original(*args, **options)
        return replace(field, a=AMPLITUDE * field.a, b=AMPLITUDE * field.b)

    return draw


def _followed():
    """Positions and velocities of three tracers of the 10 Hz flow over 0.5 ms."""
    flow = KSFlow(PopeSpectrum(flow_preset("lem-10hz").parameters), n_modes=50)
    box = Box((0.01, 0.01, 0.01), (0.0, 0.0, 0.0))
    positions, velocity, _ = flow.follow_snapshot(
        0, np.random.default_rng(0), box, 3, np.array([0.0, 5e-4])
    )
    return np.concatenate([positions.ravel(), velocity.ravel()])


def _velocity():
    spectrum = PopeSpectrum(flow_preset("lem-10hz").parameters)
    field = draw_ks_field(spectrum, n_modes=50, rng=0)
    return field.velocity(np.array([[0.001, 0.002, 0.0]]))


FLOW_MUTATIONS: tuple[Mutation, ...] = (
    Mutation(
        "ks-amplitudes-five-percent-high",
        "every KS mode's amplitude 5 % above what its share of the spectrum's energy gives "
        "(u′ 5 %, the energy 10 % high)",
        (Patch("simulator.ks_field:draw_ks_field", _louder),),
        ("stats.epsilon_recovered",),
        ("stats",),
        _velocity,
    ),
    Mutation(
        "advection-half-time",
        "tracers advected over half the time between frames, which keep their stated times",
        (
            Patch(
                "simulator.particles:KSFlow.follow_snapshot",
                edited("integrate(flow, x0, times,", "integrate(flow, x0, 0.5 * times,"),
            ),
        ),
        ("stats.c1_matches_truth",),
        ("stats",),
        _followed,
    ),
)
