"""Mutations of the Navier–Stokes flow (``simulator.dns``): out of every claim's reach.

The claims run on kinematic simulation and never build a DNS, so no claim can see these;
the required checks of a run on a DNS do (``Mutation.run_checks``), and
``tests/mutations/test_dns_kills.py`` shows it on a 32³ flow (docs/claims.md §5):

- the Lagrangian acceleration a = ∂u/∂t + (u·∇)u formed with the transposed gradient,
  ∂u/∂t + u_j ∂_i u_j = ∂u/∂t + ∇(|u|²/2), whose flux ⟨δu·δa⟩ is ½ ∂_t⟨|δu|²⟩ ≈ 0 instead
  of about −2ε: ``dns.tracer_flux`` (the flux of the tracers' acceleration fitted to their
  positions, which never passes through this code);
- the forcing's coefficient ε/(2E_f) doubled, which injects 2ε while the files say ε:
  ``dns.energy_budget`` (the dissipation settles at 2ε) and ``dns.karman_howarth``
  (S3 follows −(4/5)(2ε)r).
"""

import tempfile
from pathlib import Path

import numpy as np

from simulator.dns.fieldfile import FieldFileWriter
from simulator.dns.forcing import ConstantPowerForcing, ForcedBand
from simulator.dns.grid import Grid
from simulator.dns.series_flow import SeriesInterpolator
from simulator.dns.solver import NavierStokesSolver
from simulator.dns.spinup import initial_state
from simulator.dns.tracers import truth_at
from validation.mutations.base import Mutation
from validation.mutations.patching import Patch, edited

#: The probes' flow: 32³ points in a 10 mm box, water, ε = 10⁻⁵ m²/s³.
_N, _BOX, _NU, _EPSILON = 32, 0.01, 1e-6, 1e-5
#: Three points inside the probes' box, m.
_POINTS = np.array([[0.001, 0.002, 0.003], [0.004, 0.0075, 0.0011], [0.0093, 0.0052, 0.0068]])


def _solver() -> NavierStokesSolver:
    forcing = ConstantPowerForcing(_EPSILON)
    return NavierStokesSolver(Grid(_N, _BOX), nu=_NU, forcing=forcing)


def _acceleration() -> np.ndarray:
    """The acceleration of a random 32³ field: on the grid (first points), at three
    points (:func:`truth_at`) and from a four-snapshot field file
    (:meth:`SeriesInterpolator.truth`)."""
    solver = _solver()
    state = initial_state(solver, rng=0)
    grid = solver.fields(state).acceleration()[:, :2, :2, :2].ravel()
    _, at_points = truth_at(solver, state, _POINTS)
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "field.h5"
        with FieldFileWriter(path, n=_N, box_side=_BOX, nu=_NU, epsilon=_EPSILON) as writer:
            for step in range(4):
                writer.append(0.01 * step, solver.velocity(state) * (1.0 + 0.1 * step))
        _, in_series = SeriesInterpolator(path).truth(_POINTS, 0.015)
    return np.concatenate([grid, at_points.ravel(), in_series.ravel()])


def _injection() -> np.ndarray:
    """The forcing's power and coefficient on a random 32³ field (ε by construction)."""
    solver = _solver()
    state = initial_state(solver, rng=0)
    band = ForcedBand(solver.grid, solver.forcing)
    return np.array([solver.injection(state), band.coefficient(state.velocity_hat)])


DNS_MUTATIONS: tuple[Mutation, ...] = (
    Mutation(
        "dns-acceleration-gradient-transposed",
        "the DNS's Lagrangian acceleration (on the grid, at the tracers, from a field "
        "file) takes u_j ∂_i u_j for u_j ∂_j u_i: ∂u/∂t + ∇(|u|²/2), whose ⟨δu·δa⟩ is ≈ 0",
        (
            Patch(
                "simulator.dns.solver:FlowFields.acceleration",
                edited('"jxyz,ijxyz->ixyz"', '"jxyz,jixyz->ixyz"'),
            ),
            Patch("simulator.dns.tracers:truth_at", edited('"pj,pij->pi"', '"pj,pji->pi"')),
            Patch(
                "simulator.dns.series_flow:SeriesInterpolator.truth",
                edited('"pj,pij->pi"', '"pj,pji->pi"'),
            ),
        ),
        (),
        (),
        _acceleration,
        run_checks=("dns.tracer_flux",),
    ),
    Mutation(
        "dns-forcing-doubled",
        "the DNS's forcing coefficient ε/(2E_f) doubled: it injects 2ε where the "
        "scenario and the files say ε",
        (
            Patch(
                "simulator.dns.forcing:ForcedBand.coefficient",
                edited(
                    "return self.forcing.epsilon / (2.0 * e_f)",
                    "return 2.0 * self.forcing.epsilon / (2.0 * e_f)",
                ),
            ),
        ),
        (),
        (),
        _injection,
        run_checks=("dns.energy_budget", "dns.karman_howarth"),
    ),
)
