"""Score your own PTV code against a rendered dataset, end to end, from Python.

    python examples/score_your_code.py [--dataset DIR] [--out DIR]

1. **Render** a dataset with ``synptv render`` (the paper-stereo rig in the 10 Hz flow,
   500 tracers, 2 frame pairs per Δt, 3 plate positions: about half a minute), or take
   one you rendered with ``--dataset``.
2. **Your code** turns the dataset's particle images (``DIR/images``) into 3-D positions
   with a track id each. Here :func:`your_code` is a stand-in of known error, so that
   the scores printed can be checked: it reads the truth, misses 5 % of the tracers,
   adds 10 µm of noise per component, puts 20 ghosts in every frame and gives 2 % of
   the tracks the wrong particle in frame b. Replace it with a call to your code.
3. **Score** the positions (yield, ghosts, errors per Δt) and their links (correct,
   wrong, broken) against the dataset's ``truth.h5``, as ``synptv score --tracks``
   does (docs/score.md).

docs/python.md §1 walks through the scoring calls; docs/benchmark-your-code.md does the
same with the command line and converters for OpenPTV's and MyPTV's files.
"""

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

import validation

#: The stand-in's errors: tracers missed, noise per component (m), ghosts per frame,
#: tracks whose frame-b particle is another's.
MISSED, NOISE, GHOSTS, SWAPPED = 0.05, 10e-6, 20, 0.02


def render(folder: Path) -> Path:
    """A small dataset rendered by ``synptv render`` into ``folder/dataset``."""
    dataset = folder / "dataset"
    command = [sys.executable, "-m", "validation.cli", "render", "--out", str(dataset)]
    size = ["--frames", "2", "--particles", "500", "--planes", "3", "--quiet"]
    subprocess.run([*command, *size], check=True)
    return dataset


def your_code(dataset: Path, positions_csv: Path, seed: int = 0) -> None:
    """Stand-in for your PTV code: writes ``positions_csv`` (header
    ``dt,snapshot,frame,x,y,z,track``; m, in the dataset's world frame) from the truth
    with the errors of the module docstring. Your code would read the images instead."""
    truth, rng = validation.TruthFile(dataset), np.random.default_rng(seed)
    sheet = truth.rig.sheet
    with open(positions_csv, "w") as f:
        print("dt,snapshot,frame,x,y,z,track", file=f)
        for k, run in enumerate(truth.runs(0, truth.frames)):  # positions (M, 2, P, 3), m
            snapshots, _, particles, _ = run.positions.shape
            for m in range(snapshots):
                track = np.arange(particles)
                swapped = np.flatnonzero(rng.random(particles) < SWAPPED)
                for frame in (0, 1):
                    if frame == 1:  # a wrong link: the track goes on with another particle
                        track[swapped] = np.roll(track[swapped], 1)
                    kept = rng.random(particles) > MISSED
                    x = run.positions[m, frame][kept] + rng.normal(0.0, NOISE, (kept.sum(), 3))
                    ghosts = sheet.sample(GHOSTS, rng)
                    ghost_ids = 10**6 * (frame + 1) + np.arange(GHOSTS)  # linked to none
                    ids = np.concatenate([track[kept], ghost_ids])
                    for (a, b, c), i in zip(np.vstack([x, ghosts]), ids, strict=True):
                        f.write(f"{k},{m},{'ab'[frame]},{a:.9f},{b:.9f},{c:.9f},{i}\n")


def score(dataset: Path, positions_csv: Path) -> dict:
    """The scores of the positions and their links, printed and returned."""
    truth = validation.TruthFile(dataset)
    positions = validation.read_positions(positions_csv, tracks=True)
    validation.check_positions(
        positions, n_dt=len(truth.dt), snapshots=truth.frames, sheet=truth.rig.sheet
    )
    box = ((-0.035, -0.035, -0.004), (0.035, 0.035, 0.004))  # synptv run's analysis volume, m
    scored = validation.score_positions(positions, truth, voxel=1e-4, min_cameras=2, box=box)
    for row in validation.scores_per_dt(scored.frames, truth.dt):
        rms = ", ".join(f"{v:.1f}" for v in row["position_rms_um"].values())
        print(
            f"Δt = {row['dt_s'] * 1e6:3.0f} µs: yield {row['yield']:.3f}, "
            f"ghosts {row['ghost_fraction']:.3f}, rms x, y, z {rms} µm"
        )
    links = validation.track_scores(positions, scored.frames)
    print(
        f"links: {links['correct_fraction']:.3f} correct, {links['wrong_fraction']:.3f} "
        f"wrong; {links['broken_fraction']:.3f} of the particles found in both frames broken"
    )
    return {"summary": validation.score_summary(scored.frames), "links": links}


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dataset", type=Path, help="a dataset rendered by synptv")
    parser.add_argument("--out", type=Path, help="folder for positions.csv (default: temp)")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="synptv-example-") as temporary:
        out = args.out or Path(temporary)
        out.mkdir(parents=True, exist_ok=True)
        dataset = args.dataset or render(out)
        your_code(dataset, out / "positions.csv")
        return score(dataset, out / "positions.csv")


if __name__ == "__main__":
    main()
