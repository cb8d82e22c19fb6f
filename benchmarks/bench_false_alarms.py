"""How often an honest run fails each check: every check's false-alarm rate, counted.

Every statistical check of ``synptv run`` is set for 0.1 % false alarms
(docs/claims.md §4): over N honest runs, a check may fail about N/1000 times. This
benchmark runs a scenario over many seeds (independent flows, particles and noise) and
counts, check by check, how many seeds fail it.

Two chains:

- ``points`` (cheap: no image is drawn): the exact trajectories (the exact rung) and
  the stack through the true cameras on points, each particle's exact image centre on
  every camera that sees it plus white Gaussian noise of the detection's measured size
  (``--centre-noise``, px) standing for its detection
  (:attr:`validation.run.particle_chunks.ParticleJob.centre_noise`), matched, linked and
  tested as ``synptv run`` does, and the truth-paired detections (the detection rung);
  the checks of the true-camera rung and of the run, and the exact rung's comparisons
  with the ensemble (the sample's own fluctuation, the checks most at risk of crying
  wolf).
- ``rendered``: ``synptv run`` end to end (images, detection, calibration), the
  required checks of the method under test.

Usage::

    python -m benchmarks.bench_false_alarms --scenario ci --chain points --seeds 100 \\
        --workers 2 --out synptv-false-alarms

One JSON per seed goes to ``<out>/<scenario>-<chain>/seed-NNNN.json`` as it finishes (a
rerun computes only the missing seeds); then the table of failures per check, printed as
JSON, with the binomial limit: at 0.1 % over N seeds, P(more than L failures) < 1 %.
``python -m benchmarks false_alarms`` (the benchmark suite) runs a few seeds of the
points chain on ``ci``.
"""

import argparse
import json
import os
import shutil
import sys
import tempfile
import time
from collections.abc import Iterable
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
from pathlib import Path

from scipy.stats import binom

from validation.score.tolerances import FALSE_ALARM as RATE

#: The binomial limit: the most failures N honest seeds may show where the rate holds,
#: exceeded with probability below this.
LIMIT_PROBABILITY = 0.01
#: Centre noise of the points chain, px: the detection error measured on ``ci``.
CENTRE_NOISE = 0.056
#: Checks of the exact rung counted: its comparisons with the ensemble and the sample.
EXACT_CHECKS = (
    "stats.epsilon_recovered",
    "stats.c1_matches_independent_truth",
    "stats.epsilon_matches_input_deficit",
    "stats.mean_linear_in_dt",
)


def allowed_failures(seeds: int, rate: float = RATE) -> int:
    """The most failures of one check that ``seeds`` honest runs may show: the smallest
    L with P(X > L) < :data:`LIMIT_PROBABILITY` for X ~ Binomial(seeds, rate)."""
    limit = 0
    while binom.sf(limit, seeds, rate) >= LIMIT_PROBABILITY:
        limit += 1
    return limit


def _verdicts(rows: Iterable[dict], suffix: str = "") -> dict:
    """{check id: passed} of required check rows (a rung's informative rows left out)."""
    return {f"{row['id']}{suffix}": bool(row["passed"]) for row in rows if "informative" not in row}


class ScaledCamera:
    """A camera whose calibration carries a uniform scale error: every point it
    triangulates lies ``scale`` times as far from the origin as the particle (a PTV bias
    of (1 + 2s) on ε, docs/statistics.md §9, s = scale − 1).

    Parameters
    ----------
    camera : CameraModel
        The true camera.
    scale : float
        1 + s.
    """

    def __init__(self, camera, scale: float) -> None:
        self.camera = camera
        self.scale = scale

    def project(self, points):
        """Pixels (N, 2) of points (N, 3) in the scaled world, m."""
        return self.camera.project(points / self.scale)

    def pixel_to_ray(self, xy):
        """Rays (N) of pixels (N, 2), in the scaled world."""
        from ptv.rays import Rays

        rays = self.camera.pixel_to_ray(xy)
        return Rays(rays.origins * self.scale, rays.directions)


#: The files of a points seed its checks are computed from, kept beside its JSON so that
#: ``--recheck`` can judge them again with changed checks.
KEPT = ("summary.json", "population.json", "detection.json", "matching.json")


def points_seed(scenario, folder: Path, kept: Path, scale_error: float = 0.0) -> dict:
    """The checks of the points chain on one seed of ``scenario`` (module docstring):
    ``checks`` {id: passed} and ``values`` (:func:`_values`); the files they come from
    are copied to ``kept``. With ``scale_error`` s, the true-camera rung sees through
    cameras that scale the world by 1 + s (:class:`ScaledCamera`): a biased PTV, for the
    power of the checks rather than their false alarms."""
    from validation.run.experiment import ExperimentRun
    from validation.truth.truth_file import TruthFile
    from validation.workflow.parallel import InProcess

    run = ExperimentRun(scenario, folder, InProcess(), None, False)
    run.render = replace(run.render, centre_noise=CENTRE_NOISE)
    folder.mkdir(parents=True, exist_ok=True)
    run.prepare_flow()
    dataset, detections = run.dataset_and_detections()
    truth_file = TruthFile(dataset.folder)
    truth_stage = run.truth(dataset, truth_file)
    builder = run.rung_builder(detections, truth_stage, truth_file)
    if scale_error:
        builder.true_cameras = {
            name: ScaledCamera(camera, 1.0 + scale_error)
            for name, camera in builder.true_cameras.items()
        }
    for variant in ("exact", "detection", "true-cameras"):
        rung = run.rung(variant, builder, detections, None, folder / "ptv" / variant).folder
        (kept / variant).mkdir(parents=True, exist_ok=True)
        for name in KEPT:
            if (rung / name).is_file():
                shutil.copy(rung / name, kept / variant / name)
    shutil.copy(truth_stage.folder / "truth.json", kept / "truth.json")
    return judge_points(scenario, kept)


def judge_points(scenario, kept: Path) -> dict:
    """The checks of a points seed from its kept files (:func:`points_seed`)."""
    from validation.run.rung_comparisons import compare_rungs
    from validation.run.verdict import run_checks, rung_checks

    truth = json.loads((kept / "truth.json").read_text())
    detection = json.loads((kept / "detection" / "detection.json").read_text())
    folders = {v: kept / v for v in ("exact", "detection", "true-cameras")}
    compared = compare_rungs(scenario, truth, detection, folders)
    comparisons = compared.comparisons
    verdicts = _verdicts(run_checks(detection, comparisons["detection"], None))
    verdicts |= _verdicts(
        rung_checks(comparisons["true-cameras"], compared.matching["true-cameras"]),
        " (true-cameras)",
    )
    exact = _verdicts(rung_checks(comparisons["exact"], {"yield": 1.0, "ghost_fraction": 0.0}))
    verdicts |= {
        f"{name} (exact)": passed
        for name, passed in exact.items()
        if name.split(":")[0] in EXACT_CHECKS
    }
    return {"checks": verdicts, "values": _values(comparisons)}


def _values(comparisons: dict) -> dict:
    """The deviations behind the main checks, in their standard errors (for the figure):
    ε and u′ of the true-camera rung against the exact rung (paired), the exact rung's ε
    against the ensemble, and the largest c1 deviation over its allowance."""
    rung, exact = comparisons["true-cameras"], comparisons["exact"]
    eps, up = rung["epsilon"], rung.get("u_prime")
    off = eps.get("sample_off_ensemble") or {}
    return {
        "epsilon_vs_exact": eps.get("relative_to_exact_rung"),
        "se_epsilon_vs_exact": eps.get("se_relative"),
        "u_prime_vs_exact": None if up is None else up["relative_to_exact_rung"],
        "se_u_prime_vs_exact": None if up is None else up["se_relative"],
        "sample_off_ensemble_se": off.get("in_se"),
        "c1_worst_excess": rung["c1"]["worst_excess"],
        "exact_epsilon_vs_d_ll": exact["epsilon"]["relative_to_exact_d_ll"],
    }


def rendered_seed(scenario, folder: Path, kept: Path, scale_error: float = 0.0) -> dict:
    """The required checks of ``synptv run`` on one seed of ``scenario``: ``checks``
    {id: passed}; its results.json is copied to ``kept``."""
    if scale_error:
        raise ValueError("a scale error is a points-chain option")
    from validation.run.experiment import run_stages
    from validation.run.run_report import write_report

    stages = run_stages(scenario, folder)
    write_report(scenario, stages, folder)
    kept.mkdir(parents=True, exist_ok=True)
    shutil.copy(folder / "results.json", kept / "results.json")
    return judge_rendered(scenario, kept)


def judge_rendered(scenario, kept: Path) -> dict:
    """The required checks of a rendered seed, from its kept results.json."""
    results = json.loads((kept / "results.json").read_text())
    return {"checks": _verdicts(results["must_hold"])}


CHAINS = {"points": (points_seed, judge_points), "rendered": (rendered_seed, judge_rendered)}


def _seed_scenario(scenario_name: str, chain: str, seed: int, frames: int | None = None):
    """The scenario of one seed (the points chain draws two plates, none is read), with
    ``frames`` frame pairs per Δt where given (a reduced size)."""
    from validation.run.scenario import load_scenario

    scenario = replace(load_scenario(scenario_name), seed=seed)
    if frames is not None:
        scenario = replace(scenario, particles=replace(scenario.particles, frames=frames))
    if chain == "points":
        scenario = replace(scenario, calibration=replace(scenario.calibration, planes=2))
    return scenario


def one_seed(
    scenario_name: str, chain: str, seed: int, out: Path, scale_error: float, frames: int | None
) -> Path:
    """Run one seed into a scratch folder, write its JSON (and keep the files it was
    judged from), remove the scratch."""
    scenario = _seed_scenario(scenario_name, chain, seed, frames)
    target = out / f"seed-{seed:04d}.json"
    scratch = Path(tempfile.mkdtemp(prefix=f"synptv-fa-{seed}-", dir=out))
    start = time.perf_counter()
    try:
        kept = out / "files" / f"seed-{seed:04d}"
        found = CHAINS[chain][0](scenario, scratch, kept, scale_error)
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    record = {"seed": seed, "seconds": time.perf_counter() - start, **found}
    target.write_text(json.dumps(record, indent=1))
    return target


def recheck(scenario_name: str, chain: str, seed: int, out: Path, frames: int | None) -> None:
    """Judge a finished seed again from its kept files, with the checks as they are now."""
    target = out / f"seed-{seed:04d}.json"
    record = json.loads(target.read_text())
    judged = CHAINS[chain][1](
        _seed_scenario(scenario_name, chain, seed, frames), out / "files" / f"seed-{seed:04d}"
    )
    target.write_text(json.dumps({**record, **judged}, indent=1))


def table(records: list[dict]) -> dict:
    """Failures per check over the seeds, against the binomial limit of :data:`RATE`."""
    seeds = len(records)
    limit = allowed_failures(seeds)
    ids = sorted({name for r in records for name in r["checks"]})
    rows = []
    for name in ids:
        ran = [r["checks"][name] for r in records if name in r["checks"]]
        failures = [r["seed"] for r in records if r["checks"].get(name) is False]
        rows.append(
            {
                "check": name,
                "seeds": len(ran),
                "failures": len(failures),
                "failed_seeds": failures,
                "allowed": allowed_failures(len(ran)),
                "holds": len(failures) <= allowed_failures(len(ran)),
            }
        )
    return {
        "seeds": seeds,
        "rate": RATE,
        "allowed_failures": limit,
        "seconds_per_seed": sum(r["seconds"] for r in records) / seeds if seeds else None,
        "every_check_holds": all(row["holds"] for row in rows),
        "checks": rows,
    }


def measure(
    scenario: str,
    chain: str,
    seeds: range,
    out: Path,
    workers: int,
    *,
    again: bool = False,
    scale_error: float = 0.0,
    frames: int | None = None,
) -> tuple[list[dict], dict]:
    """Every missing seed run (``workers`` at once), then the records and the table of all
    of them (``again``: the finished seeds judged again from their kept files first;
    ``scale_error``: :func:`points_seed`; ``frames``: frame pairs per Δt)."""
    suffix = f"-scale{scale_error:g}" if scale_error else ""
    suffix += f"-frames{frames}" if frames is not None else ""
    folder = out / f"{Path(scenario).stem}-{chain}{suffix}"
    folder.mkdir(parents=True, exist_ok=True)
    done = [s for s in seeds if (folder / f"seed-{s:04d}.json").is_file()]
    if again:
        for s in done:
            recheck(scenario, chain, s, folder, frames)
    todo = [s for s in seeds if s not in done]
    if workers > 1 and len(todo) > 1:
        os.environ.setdefault("NUMBA_NUM_THREADS", "1")
        with ProcessPoolExecutor(workers) as pool:
            for done in pool.map(
                one_seed,
                *zip(
                    *((scenario, chain, s, folder, scale_error, frames) for s in todo),
                    strict=True,
                ),
            ):
                print(f"wrote {done}", file=sys.stderr, flush=True)
    else:
        for s in todo:
            written = one_seed(scenario, chain, s, folder, scale_error, frames)
            print(f"wrote {written}", file=sys.stderr, flush=True)
    records = [json.loads((folder / f"seed-{s:04d}.json").read_text()) for s in seeds]
    return records, {
        "scenario": scenario,
        "chain": chain,
        "frames": frames,
        "scale_error": scale_error,
        **table(records),
    }


def figure(result: dict, records: list[dict], path: Path) -> None:
    """The table as a figure: failures per check against the binomial limit, and the
    paired deviations of ε and u′ and the samples' distance from the ensemble, in their
    standard errors, against the normal law they should follow."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np
    from scipy.stats import norm

    fig, (left, right) = plt.subplots(1, 2, figsize=(13, 5.5))
    rows = result["checks"]
    y = np.arange(len(rows))
    left.barh(y, [r["failures"] for r in rows], color=["C0" if r["holds"] else "C3" for r in rows])
    left.plot([r["allowed"] for r in rows], y, "k|", markersize=12, label="most allowed")
    left.set_yticks(y, [r["check"] for r in rows], fontsize=7)
    left.invert_yaxis()
    left.set_xlabel(f"seeds failing, of {result['seeds']}")
    left.legend(loc="lower right", fontsize=8)
    values = [r.get("values") or {} for r in records]
    series = {
        "ε − exact trajectories' (paired)": ("epsilon_vs_exact", "se_epsilon_vs_exact"),
        "u′ − exact trajectories' (paired)": ("u_prime_vs_exact", "se_u_prime_vs_exact"),
    }
    z = np.linspace(-5, 5, 201)
    bins = np.linspace(-5, 5, 26)
    for label, (key, se) in series.items():
        found = [v[key] / v[se] for v in values if v.get(key) is not None and v.get(se)]
        right.hist(found, bins=bins, histtype="step", density=True, label=f"{label} / σ")
    off = [v["sample_off_ensemble_se"] for v in values if v.get("sample_off_ensemble_se")]
    right.hist(off, bins=bins, histtype="step", density=True, label="exact ε − ensemble / σ")
    right.plot(z, norm.pdf(z), "k--", label="normal")
    right.set_xlabel("deviation in standard errors")
    right.set_ylabel("density over the seeds")
    right.legend(fontsize=8)
    fig.suptitle(
        f"False alarms of synptv run's checks: {result['scenario']}, {result['chain']} chain, "
        f"{result['seeds']} honest seeds (each check set for {100 * RATE:g} %)"
        + (f", scale error {result['scale_error']:g}" if result.get("scale_error") else "")
    )
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def run(quick: bool) -> dict:
    """A few seeds of the points chain on ``ci`` (the benchmark suite's entry)."""
    with tempfile.TemporaryDirectory(prefix="synptv-bench-fa-") as folder:
        return measure("ci", "points", range(2 if quick else 5), Path(folder), workers=1)[1]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.bench_false_alarms")
    parser.add_argument("--scenario", default="ci", help="a preset or a scenario file")
    parser.add_argument("--chain", choices=sorted(CHAINS), default="points")
    parser.add_argument("--seeds", type=int, default=100)
    parser.add_argument("--first-seed", type=int, default=0)
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--out", type=Path, default=Path("synptv-false-alarms"))
    parser.add_argument(
        "--recheck", action="store_true", help="judge the finished seeds again first"
    )
    parser.add_argument(
        "--scale-error",
        type=float,
        default=0.0,
        help="points chain: the true-camera rung's cameras scale the world by 1 + s "
        "(a PTV bias of 2s on ε: how often the checks catch it)",
    )
    parser.add_argument("--frames", type=int, help="frame pairs per Δt (a reduced size)")
    parser.add_argument("--figure", type=Path, help="also draw the table into this PNG")
    args = parser.parse_args(argv)
    seeds = range(args.first_seed, args.first_seed + args.seeds)
    records, result = measure(
        args.scenario,
        args.chain,
        seeds,
        args.out,
        args.workers,
        again=args.recheck,
        scale_error=args.scale_error,
        frames=args.frames,
    )
    if args.figure is not None:
        figure(result, records, args.figure)
    json.dump(result, sys.stdout, indent=2)
    print()
    return 0 if result["every_check_holds"] else 1


if __name__ == "__main__":
    sys.exit(main())
