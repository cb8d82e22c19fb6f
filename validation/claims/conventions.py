"""The conventions claims (docs/claims.md #47, #48): what r a separation bin reports, and
Δt through the files that carry it.

A bin's S2 is the mean of q over the pairs the bin holds, and a reader compares it with
a model at the r the bin reports; that comparison is right when the model at that r is
the model averaged over the bin's own pairs. #47 runs the run statistics
(:func:`ptv.stats.run_statistics.compute_statistics`, the path of ``synptv run``) on
exact positions and displacements and checks, with every pair enumerated apart from the
stack (:func:`scipy.spatial.distance.pdist`, edges by
:func:`validation.truth.independent.log_edges`): the pairs per bin; the exact D_LL at
the r the stack reports against D_LL at the bin's mean pair separation; and the latter
against D_LL averaged over the bin's pairs. #48 writes a small dataset as ``synptv
render`` does and reads every Δt back as ``synptv ptv`` does.
"""

import tempfile
from pathlib import Path

import h5py
import numpy as np
from scipy.interpolate import CubicSpline
from scipy.spatial.distance import pdist

from ptv.detect.store import DetectionStore, write_index
from ptv.io.dataset import open_dataset
from ptv.settings import StatisticsSettings
from ptv.stats.links import RunParticles
from ptv.stats.run_statistics import compute_statistics
from simulator.particles import ANALYSIS_VOLUME
from simulator.rigs import load_rig
from simulator.spectra import PopeSpectrum
from validation.claims.base import Claim, ClaimResult, result
from validation.claims.context import BINS, ClaimContext
from validation.run.render_dataset import RenderSettings, build_dataset
from validation.truth.independent import exact_dll, log_edges
from validation.truth.truth_file import TruthFile

#: The largest error a bin's r convention may put into a comparison of S2 with a model
#: at that r: the size of bias the multi-Δt method exists to remove (docs/claims.md #47).
CONVENTION_ERROR = 0.002
#: Snapshots of the KS sample whose pairs #47 enumerates (about 2·10⁵ pairs each).
CONVENTION_SNAPSHOTS = 10
#: Pairs closer to a bin edge than this relative distance may fall either side of it
#: by round-off; a count may differ from the reference's by at most their number.
EDGE_ROUND_OFF = 1e-12
#: Nodes per e-fold of r of the spline through ln D_LL(ln r) (interpolation error
#: 1e-10 of D_LL on the claims' range).
NODES_PER_E_FOLD = 100


def _exact_snapshots(ctx: ClaimContext) -> list[tuple[np.ndarray, np.ndarray]]:
    """X(t) inside the analysis volume and the exact velocity there, per snapshot."""
    run = ctx.sample.runs[0]
    out = []
    chosen = slice(CONVENTION_SNAPSHOTS)
    for x, u in zip(run.positions[chosen, 0], run.velocity[chosen, 0], strict=True):
        inside = ANALYSIS_VOLUME.contains(x)
        out.append((x[inside], u[inside]))
    return out


def _pair_reference(snapshots, edges: np.ndarray, dll) -> tuple[np.ndarray, ...]:
    """Per bin of ``edges``: pairs, pairs within round-off of an edge, and the means of
    |r_ij| (m) and of D_LL(|r_ij|) (m²/s²) over the bin's pairs (every pair of every
    snapshot, by pdist); each of shape (B,)."""
    b = edges.size - 1
    count, near_edge = np.zeros(b, np.int64), np.zeros(b, np.int64)
    sum_r, sum_d = np.zeros(b), np.zeros(b)
    log_edge = np.log(edges)
    for x, _ in snapshots:
        r = pdist(x)
        r = r[(r >= edges[0]) & (r < edges[-1])]
        bin_of = np.searchsorted(edges, r, side="right") - 1
        count += np.bincount(bin_of, minlength=b)
        sum_r += np.bincount(bin_of, weights=r, minlength=b)
        sum_d += np.bincount(bin_of, weights=dll(r), minlength=b)
        gap = np.min(np.abs(np.log(r)[:, None] - log_edge[None, :]), axis=1)
        near_edge += np.bincount(bin_of, weights=gap < EDGE_ROUND_OFF, minlength=b).astype(np.int64)
    with np.errstate(invalid="ignore", divide="ignore"):
        return count, near_edge, sum_r / count, sum_d / count


def _dll_spline(spectrum, r_min: float, r_max: float):
    """D_LL(r) of ``spectrum`` on [r_min, r_max] through a spline in ln r, ln D."""
    nodes = max(8, int(np.ceil(NODES_PER_E_FOLD * np.log(r_max / r_min))))
    ln_r = np.linspace(np.log(r_min) - 0.01, np.log(r_max) + 0.01, nodes)
    spline = CubicSpline(ln_r, np.log(exact_dll(spectrum, np.exp(ln_r))))
    return lambda r: np.exp(spline(np.log(r)))


def _bin_separation(claim: Claim, ctx: ClaimContext) -> ClaimResult:
    """The run statistics' bin r against D_LL averaged over each bin's own pairs."""
    p = ctx.preset.parameters
    snapshots = _exact_snapshots(ctx)
    dt = np.asarray(ctx.preset.dt, dtype=float)
    runs = [
        RunParticles.from_links(k, d, [(x, u * d) for x, u in snapshots]) for k, d in enumerate(dt)
    ]
    settings = StatisticsSettings(r_min=10 * p.eta, r_max=p.L_int / 2, n_bins=BINS, n_boot=20)
    stats = compute_statistics(runs, settings)
    edges = log_edges(10 * p.eta, p.L_int / 2, BINS)
    dll = _dll_spline(PopeSpectrum(p), edges[0], edges[-1])
    count, near_edge, mean_r, mean_dll = _pair_reference(snapshots, edges, dll)
    counted = stats.structure.n_pairs[:, 0]
    counts_agree = bool(np.all(np.abs(counted - count) <= near_edge))
    ok = count > 0
    shift = 0.0
    for r in (stats.structure.r, stats.profile.r):
        shift = max(shift, float(np.max(np.abs(dll(r[ok]) / dll(mean_r[ok]) - 1))))
    jensen = float(np.max(np.abs(dll(mean_r[ok]) / mean_dll[ok] - 1)))
    return result(
        claim,
        shift,
        f"pairs per bin as counted apart from the stack ({int(count.sum())} pairs, "
        f"{'equal' if counts_agree else 'DIFFERENT'}); at the r the stack gives S2 and "
        f"ε(r), D_LL within {CONVENTION_ERROR:.1%} of D_LL at the pairs' mean separation "
        f"(worst {shift:.1e}), which is within {CONVENTION_ERROR:.1%} of D_LL averaged "
        f"over the bin's pairs (worst {jensen:.3%}, ½D″ Var r)",
        counts_agree and shift <= CONVENTION_ERROR and jensen <= CONVENTION_ERROR,
        limit=CONVENTION_ERROR,
    )


def _dt_round_trip(claim: Claim, ctx: ClaimContext) -> ClaimResult:
    """Δt written by the simulator, read back by the stack, bit for bit."""
    dt = np.asarray(ctx.preset.dt, dtype=float)
    settings = RenderSettings(frames=1, planes=2, particles=20, n_modes=20, seed=ctx.seed)
    with tempfile.TemporaryDirectory() as tmp:
        folder = build_dataset(
            Path(tmp) / "dataset", load_rig("paper-stereo"), ctx.preset, settings
        )
        dataset = open_dataset(folder)
        write_index(
            Path(tmp),
            cameras=dataset.cameras,
            dt=dataset.dt,
            frames=dataset.frames,
            shared_first_frame=dataset.shared_first_frame,
            detector={},
            chunks=[(0, 1)],
            source=str(folder),
        )
        with h5py.File(folder / "truth.h5", "r") as f:
            flow_dt = np.asarray(f["flow"].attrs["dt"], dtype=float)
        read = {
            "experiment.json": dataset.dt,
            "truth.h5 /flow": flow_dt,
            "truth.h5 /particles": TruthFile(folder / "truth.h5").dt,
            "detections.json": DetectionStore(Path(tmp)).dt,
        }
    wrong = [name for name, values in read.items() if not np.array_equal(values, dt)]
    error = max(
        float(np.max(np.abs(v / dt - 1))) if v.shape == dt.shape else np.inf for v in read.values()
    )
    return result(
        claim,
        error,
        f"every Δt read back from {', '.join(read)} equal to the scenario's bit for bit "
        f"(largest relative difference {error:.1e}"
        + (f"; differs in {', '.join(wrong)})" if wrong else ")"),
        not wrong,
    )


CONVENTION_CLAIMS: tuple[Claim, ...] = (
    Claim(
        "conventions.bin_separation",
        "eq. S2, docs/statistics.md §2",
        "a bin's S2 is reported at the r where the model equals its average over the bin",
        _bin_separation,
    ),
    Claim(
        "conventions.dt_round_trip",
        "§2",
        "Δt is written and read back bit for bit",
        _dt_round_trip,
    ),
)
