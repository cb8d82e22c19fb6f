"""Navier–Stokes turbulence: pseudo-spectral DNS of forced isotropic turbulence (docs/dns.md).

Modules (one job each): ``grid`` (the periodic grid, units from ν, ε, N and k_max η, the
memory check), ``forcing`` (constant-power forcing of the lowest wavenumbers),
``transforms`` (pruned real FFTs), ``spectral_kernels`` (compiled elementwise work),
``solver`` (the right-hand side, RK4 with an integrating factor, the stage hook, fields),
``diagnostics`` (spectrum, energy budget, measured scales), ``spinup`` (noise,
spin-up, upsampling, the stationary window), ``fieldfile`` (the HDF5 field series),
``interpolate`` (the fields at tracer positions).
"""

from simulator.dns.diagnostics import MeasuredParameters, energy_spectrum
from simulator.dns.fieldfile import (
    FieldFileWriter,
    PeriodicFieldSeries,
    read_field_file,
    write_field_file,
)
from simulator.dns.forcing import ConstantPowerForcing
from simulator.dns.grid import DnsSetup, Grid, dns_setup, memory_estimate
from simulator.dns.solver import (
    CFL_NUMBER,
    FlowFields,
    FlowState,
    NavierStokesSolver,
    landing_step,
)
from simulator.dns.spinup import (
    History,
    StationaryRun,
    initial_state,
    spin_up,
    stationary_flow,
    stationary_window,
    upsample,
)

__all__ = [
    "CFL_NUMBER",
    "ConstantPowerForcing",
    "DnsSetup",
    "FieldFileWriter",
    "FlowFields",
    "FlowState",
    "Grid",
    "History",
    "MeasuredParameters",
    "NavierStokesSolver",
    "PeriodicFieldSeries",
    "StationaryRun",
    "dns_setup",
    "energy_spectrum",
    "initial_state",
    "landing_step",
    "memory_estimate",
    "read_field_file",
    "spin_up",
    "stationary_flow",
    "stationary_window",
    "upsample",
    "write_field_file",
]
