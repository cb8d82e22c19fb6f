"""``synptv flow``: a KS flow's prescribed and realized statistics (docs/flow.md §8)."""

import argparse
import json
import sys

from simulator.presets import FLOW_PRESETS, flow_preset
from simulator.spectra import SPECTRA
from simulator.turbulence import NU_WATER, TurbulenceParameters
from validation.commands.common import SEED, UsageError, size
from validation.truth.flow_summary import FlowSettings, summarize_flow
from validation.workflow.progress import ProgressBar


def _flow_parameters(args: argparse.Namespace) -> TurbulenceParameters:
    given = [v is not None for v in (args.u_rms, args.epsilon)]
    if any(given) and not all(given):
        raise UsageError("give both --u-rms and --epsilon, or a --preset")
    if all(given):
        return TurbulenceParameters(u_rms=args.u_rms, epsilon=args.epsilon, nu=args.nu)
    return flow_preset(args.preset).parameters


def _print_flow(summary: dict) -> None:
    p, r, s = summary["prescribed"], summary["realized"], summary["spectrum"]
    print(
        f"spectrum        {s['kind']}, {s['n_modes']} modes, "
        f"k = {s['k_min']:.4g} … {s['k_max']:.4g} 1/m"
    )
    print(
        f"                modes carry {s['modes_energy_over_k_t']:.4f} k_t and "
        f"{s['modes_dissipation_over_epsilon']:.4f} epsilon"
    )
    print(
        f"prescribed      u' = {p['u_rms']:.4g} m/s   epsilon = {p['epsilon']:.4g} m^2/s^3   "
        f"nu = {p['nu']:.3g} m^2/s"
    )
    print(
        f"                eta = {p['eta'] * 1e6:.1f} um   tau_eta = {p['tau_eta'] * 1e3:.3f} ms   "
        f"R_lambda = {p['R_lambda']:.1f}   L_int = u'^3/eps = {p['L_int'] * 100:.2f} cm"
    )
    print(f"realized        u' = {r['u_rms']:.4g} ± {r['u_rms_stderr']:.2g} m/s")
    lo, hi = r["s2_r_range"]
    print(
        f"                sample-truth S2 vs exact D_LL over {lo * 1e3:.2f} … {hi * 1e3:.1f} mm: "
        f"max |rel. error| = {100 * r['s2_max_rel_err']:.2f} % "
        f"(largest standard error {100 * r['s2_max_rel_stderr']:.2f} %)"
    )


def run_flow(args: argparse.Namespace) -> int:
    """Sample the flow and print (or ``--json``) its summary."""
    settings = FlowSettings(
        parameters=_flow_parameters(args),
        spectrum=args.spectrum,
        particles=args.particles,
        snapshots=args.snapshots,
        n_modes=args.modes,
        unsteadiness=args.unsteadiness,
        seed=args.seed,
    )
    bar = ProgressBar("flow", enabled=not args.quiet)
    summary = summarize_flow(settings, progress=bar)
    if args.json:
        json.dump(summary, sys.stdout, indent=2, allow_nan=False)
        print()
    else:
        _print_flow(summary)
    return 0


def add_flow_parser(sub) -> None:
    """The ``synptv flow`` subcommand."""
    flow = sub.add_parser(
        "flow",
        help="build a KS flow, sample particles, print prescribed and realized statistics",
        description="Build a kinematic-simulation flow from a preset of the paper's Table 3 "
        "(or from --u-rms and --epsilon), sample particles in the analysis volume, and "
        "compare the realized u' and sample-truth S2 with the prescribed values.",
    )
    flow.add_argument("--preset", default="lem-10hz", help=f"one of {', '.join(FLOW_PRESETS)}")
    flow.add_argument("--u-rms", type=float, help="u' in m/s (with --epsilon, instead of a preset)")
    flow.add_argument("--epsilon", type=float, help="dissipation rate in m^2/s^3")
    flow.add_argument("--nu", type=float, default=NU_WATER, help="kinematic viscosity, m^2/s")
    flow.add_argument("--spectrum", default="pope", choices=sorted(SPECTRA))
    flow.add_argument(
        "--particles", type=size("count"), default=2000, help="particles per snapshot"
    )
    flow.add_argument(
        "--snapshots", type=size("frames"), default=1000, help="independent realizations"
    )
    flow.add_argument("--modes", type=size("modes"), default=200, help="KS modes")
    flow.add_argument("--unsteadiness", type=float, default=0.5, help="lambda in omega_n")
    flow.add_argument("--seed", type=SEED, default=0)
    flow.add_argument("--json", action="store_true", help="print one JSON object")
    flow.add_argument("--quiet", action="store_true", help="no progress bar")
    flow.set_defaults(run=run_flow)
