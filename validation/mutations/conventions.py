"""Mutations of the conventions: the r a separation bin reports, and Δt in files.

Each moves a comparison by a fraction of a percent or less, inside the statistics
claims' tolerances; the ``conventions.*`` claims (docs/claims.md #47, #48) see them.
"""

import tempfile
from pathlib import Path
from types import SimpleNamespace

import h5py
import numpy as np

from ptv.bins import LogBins
from ptv.detect.store import DetectionStore, write_index
from ptv.stats import pairs
from simulator.rigs import load_rig
from validation.mutations.base import Mutation
from validation.mutations.patching import Patch, edited
from validation.mutations.probes import run_statistics_probe
from validation.run import render_dataset
from validation.truth import truth_file

#: A Δt with more digits than four, s.
_DT = 1.23456789e-4


def _pair_counts() -> np.ndarray:
    """Pairs per bin of 40 random points, 1–50 mm in six bins."""
    x = np.random.default_rng(1).uniform(0.0, 0.05, (40, 3))
    return pairs.pair_sums(x, np.zeros_like(x), LogBins(1e-3, 5e-2, 6)).count


def _described_dt() -> list[float]:
    """Δt as experiment.json states it."""
    plate = SimpleNamespace(z_nominal=[0.0])
    description = render_dataset._experiment_description(
        load_rig("paper-stereo"),
        plate,
        np.array([_DT]),
        render_dataset.RenderSettings(),
        images=True,
    )
    return description["dt"]


def _truth_dt() -> float:
    """Δt of a run as truth.h5 stores it."""
    run = truth_file.TruthRun(
        dt=_DT, positions=np.zeros((1, 2, 1, 3)), velocity=np.zeros((1, 1, 3)), xy={}, visible={}
    )
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "truth.h5"
        writer = truth_file.TruthWriter(
            path,
            header=lambda f: None,
            cameras=[],
            planes=2,
            chunks=[(0, 1)],
            frames=1,
            shared_first_frame=False,
        )
        writer.write_chunk(0, [run])
        with h5py.File(path, "r") as f:
            return float(f["particles/dt0"].attrs["dt"])


def _store_dt() -> np.ndarray:
    """Δt as a detection store's index gives it back."""
    with tempfile.TemporaryDirectory() as tmp:
        write_index(
            Path(tmp),
            cameras=["cam1"],
            dt=np.array([_DT]),
            frames=[1],
            shared_first_frame=False,
            detector={},
            chunks=[(0, 1)],
            source="probe",
        )
        return DetectionStore(tmp).dt


CONVENTION_MUTATIONS: tuple[Mutation, ...] = (
    Mutation(
        "bin-r-geometric-centre",
        "ε(r) of the run statistics put at each bin's geometric centre, not at its pairs' "
        "mean separation (ε about 1–2 % off per bin)",
        (
            Patch(
                "ptv.stats.run_statistics:compute_statistics",
                edited("np.where(np.isfinite(sf.r), sf.r, bins.centres)", "bins.centres"),
            ),
        ),
        ("conventions.bin_separation",),
        ("conventions",),
        lambda: run_statistics_probe().profile.r,
    ),
    Mutation(
        "pair-bins-from-one-percent-above",
        "the pair kernel's log bins run from 1.01 r_min to r_max (each edge up to 1 % "
        "out, each bin's S2 up to 0.7 % off its nominal bin's)",
        (
            Patch(
                "ptv.stats.pairs:_start_chunks",
                edited("log_r_min = log(r_min)", "log_r_min = log(1.01 * r_min)"),
            ),
        ),
        ("conventions.bin_separation",),
        ("conventions", "stats"),
        _pair_counts,
    ),
    Mutation(
        "dt-json-four-digits",
        "experiment.json states Δt to four significant digits",
        (
            Patch(
                "validation.run.render_dataset:_experiment_description",
                edited('"dt": [float(d) for d in dt],', '"dt": [float(f"{d:.4g}") for d in dt],'),
            ),
        ),
        ("conventions.dt_round_trip",),
        ("conventions",),
        _described_dt,
    ),
    Mutation(
        "dt-float32-in-truth",
        "truth.h5 stores each run's Δt in single precision",
        (
            Patch(
                "validation.truth.truth_file:TruthWriter._write_run",
                edited('group.attrs["dt"] = run.dt', 'group.attrs["dt"] = np.float32(run.dt)'),
            ),
        ),
        ("conventions.dt_round_trip",),
        ("conventions",),
        _truth_dt,
    ),
    Mutation(
        "store-dt-microseconds",
        "a detection store's index rounds Δt to the microsecond",
        (
            Patch(
                "ptv.detect.store:write_index",
                edited('"dt": [float(v) for v in dt],', '"dt": [round(float(v), 6) for v in dt],'),
            ),
        ),
        ("conventions.dt_round_trip",),
        ("conventions",),
        _store_dt,
    ),
)
