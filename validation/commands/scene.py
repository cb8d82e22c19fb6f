"""``synptv scene``: a picture of a rig (docs/rigs.md §7)."""

import argparse

import numpy as np

from simulator.rigs import load_rig, rig_presets
from validation.commands.common import integer_at_least


def run_scene(args: argparse.Namespace) -> int:
    """Draw the rig (with its plate and particles in its own sheet) into a PNG."""
    from simulator.scene import render_scene
    from simulator.target import PlateDesign, build_plate, traverse_positions
    from validation.report.png import check_png_path, save_picture

    check_png_path(args.out)
    rig = load_rig(args.rig)
    plate = build_plate(PlateDesign(), traverse_positions()) if args.plate else None
    particles = (
        rig.sheet.sample(args.particles, np.random.default_rng(0)) if args.particles else None
    )
    picture = render_scene(rig, plate=plate, plate_plane=6, particles=particles)
    out = save_picture(picture, args.out)
    print(f"scene picture written to {out}")
    return 0


def add_scene_parser(sub) -> None:
    """The ``synptv scene`` subcommand."""
    scene = sub.add_parser(
        "scene",
        help="draw a picture of a rig: tank, windows, cameras, laser sheet, plate",
        description="Render an offscreen picture (pyrender, EGL) of a rig: its tank "
        "(icosahedron or box), the part of each window its camera looks through, the "
        "cameras with their names, frusta and refracted corner rays, the laser sheet, the "
        "labelled axes, optionally the calibration plate and particles.",
    )
    scene.add_argument(
        "--rig", default="paper-stereo", help=f"{', '.join(rig_presets())} or a .toml file"
    )
    scene.add_argument("--out", default="scene.png", help="PNG file to write")
    scene.add_argument("--plate", action="store_true", help="draw the calibration plate")
    scene.add_argument(
        "--particles", type=integer_at_least(0), default=300, help="particles to draw (0: none)"
    )
    scene.set_defaults(run=run_scene)
