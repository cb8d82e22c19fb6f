"""A stationary DNS as the flow of a virtual experiment (docs/dns.md §10).

:func:`build_stationary_field` spins the flow up and writes its snapshots, one per
snapshot of the experiment, to a field file (``field.h5``), with the exact two-point
statistics of every snapshot (``statistics.h5``, :func:`snapshot_statistics`).
:class:`DnsTracerFlow` is then a :class:`simulator.particles.TracerFlow`: snapshot m of
the experiment seeds its tracers in snapshot m of the file and advances flow and tracers
together (:mod:`simulator.dns.tracers`).
"""

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

from simulator.dns.field_statistics import direction_increments, shell_energies
from simulator.dns.fieldfile import FieldFileWriter, read_snapshot
from simulator.dns.forcing import DEFAULT_BAND, ConstantPowerForcing
from simulator.dns.grid import DEFAULT_KMAX_ETA, DnsSetup, dns_setup
from simulator.dns.solver import FlowState, NavierStokesSolver
from simulator.dns.spinup import DEFAULT_SPACING, stationary_flow
from simulator.dns.tracers import follow_tracers

#: The files of a stationary field's folder.
FIELD_FILE = "field.h5"
STATISTICS_FILE = "statistics.h5"

#: Separations of the axis statistics: about this many, log-spaced, from one grid spacing
#: to half the box.
SEPARATIONS = 24


@dataclass(frozen=True)
class DnsSpec:
    """What a stationary DNS is built from.

    Attributes
    ----------
    nu : float
        ν, m²/s.
    epsilon : float
        Injected power ε, m²/s³.
    n : int
        Grid points per axis.
    snapshots : int
        Snapshots kept (one per snapshot of the experiment).
    kmax_eta : float
        Resolution k_max η.
    spacing : float
        Snapshots apart, in eddy times T_L = L_int/u′.
    seed : int
        Seed of the initial noise.
    band : float
        Forced band k_f/(2π/L).
    """

    nu: float
    epsilon: float
    n: int
    snapshots: int
    kmax_eta: float = DEFAULT_KMAX_ETA
    spacing: float = DEFAULT_SPACING
    seed: int = 0
    band: float = DEFAULT_BAND

    def setup(self) -> DnsSetup:
        """The grid and box (checked, memory included)."""
        return dns_setup(self.nu, self.epsilon, self.n, kmax_eta=self.kmax_eta)

    def solver(self, *, workers: int = 1) -> NavierStokesSolver:
        """A solver of this flow (grid, ν, the forcing)."""
        setup = self.setup()
        forcing = ConstantPowerForcing(self.epsilon, self.band)
        return NavierStokesSolver(setup.grid, nu=self.nu, forcing=forcing, workers=workers)


def separation_shifts(n: int) -> np.ndarray:
    """About :data:`SEPARATIONS` log-spaced shifts from 1 to N/2 grid spacings, distinct."""
    return np.unique(np.rint(np.geomspace(1, n // 2, SEPARATIONS)).astype(np.int64))


def snapshot_statistics(
    solver: NavierStokesSolver, state: FlowState, shifts: np.ndarray, band: float
) -> dict[str, np.ndarray]:
    """The exact two-point statistics of one state.

    Returns
    -------
    dict of ndarray
        ``shell_energy`` (S,) and ``band_energy`` (S_f,) (:func:`shell_energies`, m²/s²),
        and ``s2``, ``s3``, ``du_da``, ``dul_dal`` (R,) averaged over directions at ``shifts``
        (:func:`~simulator.dns.field_statistics.direction_increments`).
    """
    fields = solver.fields(state)
    moments = direction_increments(fields.velocity, shifts, acceleration=fields.acceleration())
    _, energy = shell_energies(state.velocity_hat, solver.grid)
    _, band_energy = shell_energies(state.velocity_hat, solver.grid, band=band)
    return {"shell_energy": energy, "band_energy": band_energy, **moments}


def build_stationary_field(
    spec: DnsSpec,
    folder: Path,
    *,
    workers: int = 1,
    progress: Callable[[float, float], None] | None = None,
):
    """Spin the flow up, write its snapshots and their statistics into ``folder``.

    Parameters
    ----------
    spec : DnsSpec
    folder : Path
        An existing folder; receives :data:`FIELD_FILE` and :data:`STATISTICS_FILE`.
    workers : int
        FFT threads.
    progress : callable(done, total), optional

    Returns
    -------
    StationaryRun
        The window (its measured scales, the snapshot times, every step's history).
    """
    setup = spec.setup()
    shifts = separation_shifts(spec.n)
    fields_solver = spec.solver(workers=workers)
    rows: list[dict[str, np.ndarray]] = []
    with FieldFileWriter(
        folder / FIELD_FILE,
        n=spec.n,
        box_side=setup.grid.box_side,
        nu=spec.nu,
        epsilon=spec.epsilon,
    ) as writer:

        def take(state: FlowState) -> None:
            writer.append(state.time, fields_solver.velocity(state))
            rows.append(snapshot_statistics(fields_solver, state, shifts, spec.band))

        _, run = stationary_flow(
            setup,
            snapshots=spec.snapshots,
            spacing=spec.spacing,
            rng=spec.seed,
            band=spec.band,
            workers=workers,
            on_snapshot=take,
            progress=progress,
        )
        writer.close(run.parameters)
    k, _ = shell_energies(np.zeros((3, *setup.grid.spectral_shape), complex), setup.grid)
    k_band, _ = shell_energies(
        np.zeros((3, *setup.grid.spectral_shape), complex), setup.grid, band=spec.band
    )
    with h5py.File(folder / STATISTICS_FILE, "w") as f:
        f.attrs["epsilon"] = spec.epsilon
        f.attrs["nu"] = spec.nu
        f.attrs["box_side"] = setup.grid.box_side
        f["r"] = shifts * setup.grid.spacing
        f["shell_k"] = k
        f["band_k"] = k_band
        for name in rows[0]:
            f[name] = np.stack([row[name] for row in rows])
        for name in ("times", "energy", "dissipation", "steps"):
            f[f"history/{name}"] = getattr(run.history, name)
    return run


@dataclass(frozen=True)
class DnsTracerFlow:
    """Tracers in the snapshots of a stationary field (:class:`simulator.particles.TracerFlow`).

    Attributes
    ----------
    spec : DnsSpec
        The flow the file holds.
    field_file : Path
        Its snapshots (:func:`build_stationary_field`).
    u_rms : float
        The measured u′, m/s (the margin of the seeding box).
    """

    spec: DnsSpec
    field_file: Path
    u_rms: float

    def follow_snapshot(
        self, m: int, rng: np.random.Generator, seed_box, n_seed: int, times: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Tracers seeded from ``rng`` in ``seed_box`` at snapshot m of the file, followed
        with the flow over ``times`` (:func:`simulator.dns.tracers.follow_tracers`)."""
        x0 = seed_box.sample(n_seed, rng)
        solver = self.spec.solver()
        time, velocity = read_snapshot(self.field_file, m)
        truth, _ = follow_tracers(solver, solver.state(velocity, time=time), x0, times)
        return truth.positions, truth.velocity, truth.acceleration
