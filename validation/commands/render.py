"""``synptv render``: a dataset folder any PTV code can read (docs/render.md)."""

import argparse

from simulator.presets import FLOW_PRESETS
from simulator.rigs import load_rig, rig_presets
from validation.commands.common import SEED, UsageError, add_parallel_options, say_took_over, size
from validation.run.scenario import FlowSection
from validation.workflow.files import check_output_folder, hold_new_folder
from validation.workflow.progress import ProgressBar

#: What ``synptv render`` draws when neither these options nor ``--scenario`` say.
RENDER_DEFAULTS = {
    "rig": "paper-stereo",
    "preset": "lem-10hz",
    "frames": 10,
    "particles": 1000,
    "planes": 13,
}


def run_render(args: argparse.Namespace) -> int:
    """Render the dataset of a scenario, or of the options, into a new folder."""
    from validation.run.render_dataset import RenderSettings, write_dataset
    from validation.workflow.parallel import check_parallel_options, executor

    check_parallel_options(args.workers, args.scheduler)
    out = check_output_folder(args.out)
    given = [f"--{name}" for name in RENDER_DEFAULTS if getattr(args, name) is not None]
    if args.scenario is not None:
        from validation.run.experiment import render_settings
        from validation.run.scenario import load_scenario

        if given:
            raise UsageError(
                f"--scenario sets the rig, the flow and the sizes: drop {', '.join(given)}"
            )
        scenario = load_scenario(args.scenario)
        if args.seed is not None:
            scenario = scenario.with_seed(args.seed)
        rig, flow = load_rig(scenario.rig.name), scenario.flow
        settings = render_settings(scenario)
    else:
        chosen = {
            name: default if getattr(args, name) is None else getattr(args, name)
            for name, default in RENDER_DEFAULTS.items()
        }
        rig, flow = load_rig(chosen["rig"]), FlowSection(preset=chosen["preset"])
        settings = RenderSettings(
            frames=chosen["frames"],
            particles=chosen["particles"],
            planes=chosen["planes"],
            seed=0 if args.seed is None else args.seed,
        )
    preset = flow.as_preset()
    print(flow.describe())
    bar = ProgressBar("render", enabled=not args.quiet)
    with hold_new_folder(out, "synptv render") as took_over:
        say_took_over("render", took_over)
        with executor(workers=args.workers, scheduler=args.scheduler) as ex:
            write_dataset(out, rig, preset, settings, executor=ex, progress=bar)
    print(f"dataset written to {out}")
    return 0


def add_render_parser(sub) -> None:
    """The ``synptv render`` subcommand."""
    render = sub.add_parser(
        "render",
        help="render a dataset: plate images, particle image pairs per dt, truth",
        description="Simulate the flow, render the calibration plate at every traverse "
        "position and double-frame particle images at every dt for every camera of a rig, "
        "and write them as 16-bit TIFF with experiment.json and truth.h5 (docs/render.md).",
    )
    render.add_argument(
        "--scenario",
        help="a scenario preset or .toml file: its rig, flow, sizes, plate, lighting and "
        "sensor (instead of --rig, --preset, --frames, --particles and --planes)",
    )
    render.add_argument(
        "--rig", help=f"{', '.join(rig_presets())} or a .toml file (default paper-stereo)"
    )
    render.add_argument("--preset", help=f"one of {', '.join(FLOW_PRESETS)} (default lem-10hz)")
    render.add_argument("--out", required=True, help="new folder to write")
    render.add_argument("--frames", type=size("frames"), help="frame pairs per dt (default 10)")
    render.add_argument(
        "--particles", type=size("count"), help="particles in the sheet (default 1000)"
    )
    render.add_argument(
        "--planes", type=size("planes"), help="calibration traverse positions (default 13)"
    )
    render.add_argument("--seed", type=SEED, help="default 0, or the scenario's seed")
    add_parallel_options(render)
    render.add_argument("--quiet", action="store_true", help="no progress bar")
    render.set_defaults(run=run_render)
