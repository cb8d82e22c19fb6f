"""A peer side by side: synptv's IPR and OpenLPT 2.2.4's IPR on the same dense images.

Rig: ``lpt-challenge-small`` (four Scheimpflug cameras at −30°, −10°, +10°, +30°,
512 × 512 px, a 20 × 25 × 30 mm volume lit through its depth, a voxel of about 60 µm)
in two variants: ``window``, the preset (cameras in air behind the tank's 10 mm glass
wall, particles in water: refraction), and ``no window``, the same rig with
``[tank] kind = "free"`` (cameras and particles in one medium). For each variant:

1. ``synptv render`` of a small dataset with the rig's plate (13 × 13 dots on a 2.5 mm
   pitch) at every step of its traverse through the whole 30 mm depth (7 positions 5 mm
   apart), as a careful experimentalist would traverse;
   from it the two camera sets of ``synptv export --format openlpt``
   (:mod:`validation.export.openlpt_cameras`): **plates**, an OpenCV pinhole without
   distortion fitted to the plate dots (what OpenLPT's plate calibration gives: no
   refraction, no tilt), and **true**, each true camera as OpenLPT's POLYNOMIAL fitted to
   its exact projection (≤ 0.01 px: the same camera information synptv's true-camera
   rung gets, as far as OpenLPT's models hold it). Their errors on the truth's particles
   are reported.
2. One sparse snapshot (0.005 particles per pixel) and one snapshot per density,
   particles uniform in the lit volume, N = ppp × the mean image area the volume covers
   (:func:`validation.studies.density.image_area`), bench_ipr's tracers, light level and
   sensor; the same images for both codes.
3. **synptv**: :func:`ptv.reconstruct.reconstruct` with the default
   :class:`ptv.reconstruct.IPRSettings` through the true cameras, and through the plate
   pinholes (the very cameras OpenLPT's ``plates`` files hold); its OTF measured on the
   sparse snapshot through the same cameras as bench_ipr does (per image region, then
   per region and depth slab from what IPR reconstructs on it; 2 × 1 regions and 3 slabs
   on these small images).
4. **OpenLPT**: the exported layout (:mod:`validation.export.openlpt`: images less their
   background level, image lists whose first five lines are the sparse snapshot, on
   which OpenLPT estimates its own OTF, then one line per density; its GUI's default IPR
   settings, 4 IPR loops of 4 shake loops, one camera dropped in 2 reduced loops; the
   export's 2-D peak threshold) run by the export's ``run_ipr.py`` (its Python API,
   ``openlpt.IPR.runIPR``) in OpenLPT's own virtual environment, one subprocess per
   snapshot, OpenMP on 2 threads.

Both reconstruct in the export's view volume (the lit volume plus 2 voxels) and are
scored by bench_ipr's scorer, the LPT Challenge's: one to one within one voxel on each
axis; ``found`` = true positives / true particles, ``ghosts`` = unmatched reconstructed
/ reconstructed, rms error of the true positives in µm (3-D) and px (projected through
the true cameras). Time: wall time of one snapshot's reconstruction (OpenLPT: of
``runIPR``, its configuration and OTF estimate apart). Each code reconstructs each
snapshot in a fresh process of its own (synptv: a spawned Python process that first reconstructs the
sparse snapshot, loading its compiled kernels; OpenLPT: ``run_ipr.py``). Memory: that
process's peak resident set during the reconstruction (the peak reset through
``/proc/self/clear_refs`` just before), ``peak_rss_mb``, and its growth over the resident
set before it (the images loaded), ``added_mb``.

OpenLPT is never a synptv dependency: its environment is ``--venv`` (default
``../peers/openlpt-venv`` beside the repository), created with ``pip install openlpt
opencv-python`` (about 1 GB, a few minutes) when it lacks OpenLPT.

Run: ``python -m benchmarks.bench_peer_openlpt [--quick] [--venv PATH]``: one JSON object,
then a markdown table. ``--quick``: 0.01 and 0.05 ppp (38 minutes on the shared 2-core
machine, 34 of them OpenLPT's IPR at 0.05 ppp through its polynomial cameras, which it
inverts iteratively for every line of sight); full: the Challenge's 0.005–0.16 (hours).
``--ppp 0.08,0.12`` runs those densities; ``--true-up-to 0.025`` runs the true-camera set
only up to 0.025 ppp (the plate pinholes at every density).
"""

import argparse
import contextlib
import json
import multiprocessing
import os
import re
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
import tifffile

from benchmarks.bench_ipr import OTF_PPP, lighting, score
from benchmarks.machine import machine
from ptv.reconstruct import IPRSettings, measure_otf, reconstruct, refine_otf
from validation.export.openlpt import (
    OTF_FRAMES,
    TracerSettings,
    config_text,
    image_levels,
    image_list,
    peak_threshold,
)
from validation.export.openlpt_cameras import (
    MM,
    plate_calibrations,
    plate_camera_files,
    true_camera_files,
    true_images,
    view_volume,
)
from validation.export.openlpt_driver import DRIVER
from validation.studies.density import image_area

QUICK_DENSITIES = (0.01, 0.05)
#: The LPT Challenge's densities.
DENSITIES = (0.005, 0.025, 0.05, 0.08, 0.12, 0.16)
RIG = "lpt-challenge-small"
VARIANTS = ("window", "no window")
#: OpenMP threads of OpenLPT (the machine's 2 cores; synptv's numba uses them too).
THREADS = 2
#: Longest OpenLPT run of one snapshot before it is reported as timed out, s.
OPENLPT_TIMEOUT = 3600
#: bench_ipr's OTF procedure on 512 × 512 images: image regions (rows × columns) and
#: depth slabs (finer cells leave too few isolated particle images in a cell).
OTF_REGIONS = (2, 1)
DEPTH_SLABS = 3
#: The camera sets: OpenLPT's camera folder and configuration for each.
SETS = {"true": "camFileTrue", "plates": "camFile"}
DEFAULT_VENV = Path(__file__).resolve().parents[2] / "peers" / "openlpt-venv"


# -- OpenLPT's environment -----------------------------------------------------------------


def openlpt_python(venv: Path) -> Path:
    """The Python of ``venv``, created with ``pip install openlpt opencv-python`` when
    ``import openlpt`` fails there."""
    python = venv / "bin" / "python"
    if python.is_file() and _run([python, "-c", "import openlpt"]).returncode == 0:
        return python
    print(f"creating OpenLPT's environment in {venv} ...", file=sys.stderr)
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
    pip = [str(python), "-m", "pip", "install", "--quiet"]
    subprocess.run([*pip, "--upgrade", "pip"], check=True)
    subprocess.run([*pip, "openlpt", "opencv-python"], check=True)
    return python


def _run(argv, **options) -> subprocess.CompletedProcess:
    return subprocess.run([str(a) for a in argv], capture_output=True, text=True, **options)


def openlpt_version(python: Path) -> str:
    done = _run([python, "-c", "import importlib.metadata as m; print(m.version('openlpt'))"])
    return done.stdout.strip() or "unknown"


# -- memory --------------------------------------------------------------------------------


def _status_mb(field: str) -> float:
    """A figure of /proc/self/status, MiB."""
    text = Path("/proc/self/status").read_text()
    return int(re.search(rf"^{field}:\s+(\d+)", text, re.M).group(1)) / 1024


def _reset_peak() -> float:
    """Reset this process's peak resident set; its resident set now, MiB."""
    Path("/proc/self/clear_refs").write_text("5")
    return _status_mb("VmRSS")


# -- the rig, the dataset and the images -----------------------------------------------------


def rig_file(variant: str, work: Path) -> str:
    """The rig of a variant: the preset's name, or a copy of its file without the tank."""
    if variant == "window":
        return RIG
    preset = Path(__file__).resolve().parents[1] / "simulator" / "rig_presets" / f"{RIG}.toml"
    text = re.sub(r"\[tank\]\n(?:[^\[\n].*\n)*", '[tank]\nkind = "free"\n\n', preset.read_text())
    text = re.sub(r'^name = ".*"', f'name = "{RIG}-no-window"', text, count=1, flags=re.M)
    path = work / f"{RIG}-no-window.toml"
    path.write_text(text)
    return str(path)


def render_dataset(rig: str, folder: Path) -> None:
    """``synptv render``: the plate at every step of the rig's traverse through the lit
    volume's depth, a few particles (for the camera files' error on the truth)."""
    from simulator.rigs import load_rig
    from validation.cli import main

    spec = load_rig(rig)
    planes = round(spec.sheet.size[2] / spec.plane_spacing) + 1
    argv = ["render", "--rig", rig, "--out", str(folder), "--frames", "2"]
    argv += ["--particles", "300", "--planes", str(planes), "--workers", "1", "--quiet"]
    with contextlib.redirect_stdout(sys.stderr):  # stdout is the benchmark's JSON
        status = main(argv)
    if status != 0:
        raise RuntimeError(f"synptv render {' '.join(argv)} failed")


def render(rig, sheet, n: int, rng: np.random.Generator):
    """``n`` particles uniform in the lit volume and every camera's image: positions
    (n, 3) m and C images (H, W) DN."""
    from simulator.render.camera_frames import record_particles, rig_lighting
    from simulator.render.sensor import Sensor

    light = rig_lighting(lighting(), rig)
    positions = rng.uniform(*sheet, (n, 3))
    images = [
        record_particles(cam, positions, lighting=light, sensor=Sensor(), rng=rng).image
        for cam in rig.cameras
    ]
    return positions, images


# -- the two codes ---------------------------------------------------------------------------


def synptv_ipr(images, cameras, otfs, box, warm) -> tuple[np.ndarray, dict]:
    """synptv's IPR on one snapshot in a fresh process (as OpenLPT's runs), after a
    reconstruction of the sparse snapshot ``warm`` there (which loads the compiled
    kernels): positions (N, 3) m and its figures."""
    with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")) as pool:
        positions, seconds, peak, before = pool.submit(
            _reconstruct_alone, images, cameras, otfs, box, warm
        ).result()
    figures = {"seconds": round(seconds, 1), "peak_rss_mb": round(peak)}
    return positions, {**figures, "added_mb": round(peak - before)}


def _reconstruct_alone(images, cameras, otfs, box, warm):
    """In the child of :func:`synptv_ipr`: positions, seconds, peak and prior RSS (MiB)."""
    reconstruct(warm, cameras, otfs, box)
    before = _reset_peak()
    t0 = time.perf_counter()
    result = reconstruct(images, cameras, otfs, box, settings=IPRSettings())
    seconds = time.perf_counter() - t0
    return result.positions, seconds, _status_mb("VmHWM"), before


def synptv_otf(sparse, cameras, box):
    """bench_ipr's OTF procedure on the sparse snapshot through ``cameras``."""
    flat = measure_otf(sparse, regions=OTF_REGIONS)
    first = reconstruct(sparse, cameras, flat, box)
    return refine_otf(sparse, first.positions, first.xy, flat, depth_slabs=DEPTH_SLABS)


def write_case(folder: Path, names, files: dict, sparse, snapshots, volume) -> dict:
    """OpenLPT's files for one variant (module docstring); what was chosen."""
    from simulator.render.sensor import Sensor

    levels = [image_levels(image) for image in sparse]
    offsets = [round(v.background) for v in levels]
    for key, cams in files.items():
        for name, f in zip(names, cams, strict=True):
            path = folder / SETS[key] / f"{name}.txt"
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(f.text)
    for c, name in enumerate(names):
        lines = []
        for i, image in enumerate([sparse[c], *(s[c] for s in snapshots)]):
            relative = f"imgFile/{name}/{i:03d}.tif"
            (folder / relative).parent.mkdir(parents=True, exist_ok=True)
            data = np.clip(image.astype(np.int64) - offsets[c], 0, 65535).astype(np.uint16)
            tifffile.imwrite(folder / relative, data, compression=None)
            lines.append(relative)
        lines = [lines[0]] * OTF_FRAMES + lines[1:]
        (folder / "imgFile" / f"{name}ImageNames.txt").write_text(image_list(lines))
    settings = TracerSettings(peak_threshold=peak_threshold(levels))
    (folder / "tracerConfig.txt").write_text(settings.text())
    for key, camera_folder in SETS.items():
        text = config_text(
            frames=(0, OTF_FRAMES + len(snapshots) - 1),
            frame_rate=1,
            cameras=[(f"{camera_folder}/{n}.txt", 2 ** Sensor().bit_depth - 1) for n in names],
            image_lists=[f"imgFile/{name}ImageNames.txt" for name in names],
            volume=volume,
            output=f"Results/{key}/",
            tracer="tracerConfig.txt",
            threads=THREADS,
        )
        (folder / f"config_{key}.txt").write_text(text)
    (folder / "run_ipr.py").write_text(DRIVER)
    return {"background_dn": offsets, "peak_threshold_dn": settings.peak_threshold}


def openlpt_ipr(python: Path, folder: Path, key: str, frame: int) -> tuple[np.ndarray, dict]:
    """OpenLPT's IPR on one line of the image lists: positions (N, 3) m and its figures."""
    out, summary = f"Results/{key}_{frame}.csv", f"Results/{key}_{frame}.json"
    argv = [python, "run_ipr.py", f"config_{key}.txt", "--frames", frame, frame]
    argv += ["--out", out, "--summary", summary]
    try:
        with open(folder / "openlpt.log", "a") as log:
            done = subprocess.run(
                [str(a) for a in argv],
                cwd=folder,
                env=dict(os.environ, OMP_NUM_THREADS=str(THREADS)),
                stdout=log,
                stderr=subprocess.STDOUT,
                timeout=OPENLPT_TIMEOUT,
                check=False,
            )
    except subprocess.TimeoutExpired:
        return np.zeros((0, 3)), {"error": f"timed out after {OPENLPT_TIMEOUT} s"}
    if done.returncode != 0:
        return np.zeros((0, 3)), {"error": f"exit status {done.returncode}, see openlpt.log"}
    table = np.loadtxt(folder / out, delimiter=",", skiprows=1, ndmin=2)
    found = table[:, 1:4] / MM if len(table) else np.zeros((0, 3))
    info = json.loads((folder / summary).read_text())
    row = info["frames"][0]
    return found, {
        "seconds": round(row["seconds_ipr"], 1),
        "peak_rss_mb": round(row["peak_rss_mb"]),
        "added_mb": round(row["peak_rss_mb"] - row["rss_before_mb"]),
        "seconds_config_and_otf": round(info["seconds_config_and_otf"], 2),
    }


def _camera_errors(files) -> list[dict]:
    return [
        {"rms_px": float(f"{f.rms_px:.3g}"), "max_px": float(f"{f.max_px:.3g}"), "how": f.detail}
        for f in files
    ]


def camera_sets(ppp: float, true_up_to: float) -> list[str]:
    """The camera sets run at ``ppp``: the plate pinholes always, the true cameras up to
    ``true_up_to`` (OpenLPT inverts its POLYNOMIAL for every line of sight: 1120 s for
    one 0.05 ppp snapshot here, hours above)."""
    return [key for key in SETS if key == "plates" or ppp <= true_up_to]


def run_variant(variant: str, densities, python: Path, work: Path, true_up_to: float) -> dict:
    """Both codes on one variant's snapshots (module docstring)."""
    from validation.export.source import read_source

    dataset = work / f"dataset-{variant.replace(' ', '-')}"
    render_dataset(rig_file(variant, work), dataset)
    source = read_source(dataset)
    rig = source.rig
    truth_images = true_images(dataset, source.cameras)
    pinholes = plate_calibrations(source)
    volume = view_volume(rig)
    files = {
        "true": true_camera_files(rig, volume, truth_images),
        "plates": plate_camera_files(pinholes, truth_images),
    }
    cameras = {"true": list(rig.cameras), "plates": list(pinholes.values())}
    box = (volume.lower, volume.upper)
    half = np.asarray(rig.sheet.size) / 2
    sheet = (np.asarray(rig.sheet.centre) - half, np.asarray(rig.sheet.centre) + half)
    area = image_area(rig.cameras, sheet, rng=np.random.default_rng(1))
    _, sparse = render(rig, sheet, int(OTF_PPP * area), np.random.default_rng(2))
    otfs = {key: synptv_otf(sparse, cams, box) for key, cams in cameras.items()}
    truths, snapshots = [], []
    for i, ppp in enumerate(densities):
        positions, images = render(rig, sheet, round(ppp * area), np.random.default_rng(100 + i))
        truths.append(positions)
        snapshots.append(images)
    case = work / f"openlpt-{variant.replace(' ', '-')}"
    chosen = write_case(case, rig.camera_names, files, sparse, snapshots, volume)
    rows = []
    for i, ppp in enumerate(densities):
        row = {"ppp": ppp, "particles": len(truths[i])}
        for key in camera_sets(ppp, true_up_to):
            found, figures = synptv_ipr(snapshots[i], cameras[key], otfs[key], box, sparse)
            row[f"synptv_{key}"] = {
                **score(truths[i], found, volume.voxel, rig.cameras),
                **figures,
            }
            found, figures = openlpt_ipr(python, case, key, OTF_FRAMES + i)
            row[f"openlpt_{key}"] = {
                **score(truths[i], found, volume.voxel, rig.cameras),
                **figures,
            }
        print(json.dumps({"variant": variant, **row}), file=sys.stderr, flush=True)
        rows.append(row)
    return {
        "rig": rig.name,
        "footprint_px": round(area),
        "voxel_um": round(volume.voxel * 1e6, 2),
        "camera_files_error_px": {key: _camera_errors(f) for key, f in files.items()},
        "openlpt_inputs": chosen,
        "densities": rows,
    }


def run(quick: bool, venv: Path = DEFAULT_VENV, densities=None, true_up_to: float = 1.0) -> dict:
    """Both variants at ``densities`` (default: the quick or the full list)."""
    python = openlpt_python(venv)
    if densities is None:
        densities = QUICK_DENSITIES if quick else DENSITIES
    with tempfile.TemporaryDirectory(prefix="bench-openlpt-") as work:
        variants = {v: run_variant(v, densities, python, Path(work), true_up_to) for v in VARIANTS}
    return {
        "machine": machine(),
        "openlpt": openlpt_version(python),
        "openlpt_threads": THREADS,
        "openlpt_settings": {
            k: v for k, v in TracerSettings().__dict__.items() if k != "peak_threshold"
        },
        "synptv_settings": "IPRSettings() defaults, OTF per region and depth slab",
        "variants": variants,
    }


def markdown(figures: dict) -> str:
    """The side-by-side table of :func:`run`'s figures."""
    lines = [
        "| variant | ppp | particles | code, cameras | found | ghosts | rms µm | rms px "
        "| s / snapshot | added MiB |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for variant, v in figures["variants"].items():
        for row in v["densities"]:
            for code in ("synptv", "openlpt"):
                for key in SETS:
                    if f"{code}_{key}" not in row:
                        continue
                    f = row[f"{code}_{key}"]
                    um = "–" if f.get("rms_um") is None else f"{f['rms_um']:.1f}"
                    px = "–" if f.get("rms_px") is None else f"{f['rms_px']:.3f}"
                    lines.append(
                        f"| {variant} | {row['ppp']} | {row['particles']} | {code}, {key} "
                        f"| {f['found']:.3f} | {f['ghosts']:.3f} | {um} | {px} "
                        f"| {f.get('seconds', f.get('error', '–'))} | {f.get('added_mb', '–')} |"
                    )
    return "\n".join(lines)


def figure(rows: list[dict]):
    """Found and ghosts against the density, both codes, per variant and camera set:
    ``rows`` as the benchmark prints them (each density's row with its ``variant``)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11.0, 4.2), layout="constrained")
    styles = {"window": "-", "no window": "--"}
    colours = {"synptv": "C0", "openlpt": "C3"}
    markers = {"plates": "o", "true": "s"}
    for variant in dict.fromkeys(r["variant"] for r in rows):
        for code in colours:
            for key in SETS:
                got = [r for r in rows if r["variant"] == variant and f"{code}_{key}" in r]
                if not got:
                    continue
                ppp = [r["ppp"] for r in got]
                for ax, what in zip(axes, ("found", "ghosts"), strict=True):
                    ax.plot(
                        ppp,
                        [100 * r[f"{code}_{key}"][what] for r in got],
                        ls=styles[variant],
                        marker=markers[key],
                        color=colours[code],
                        label=f"{code}, {key} cameras, {variant}",
                    )
    for ax, label in zip(axes, ("found (%)", "ghosts (% of the points)"), strict=True):
        ax.set_xscale("log")
        ticks = sorted({r["ppp"] for r in rows})
        ax.set_xticks(ticks, [f"{t:g}" for t in ticks], fontsize=8)
        ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        ax.set_xlabel("particles per pixel of the volume's image")
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
    axes[1].legend(fontsize=7)
    fig.suptitle(
        f"IPR on {RIG}, one snapshot per density: synptv (default IPRSettings) beside "
        "OpenLPT (its GUI's IPR defaults), scored alike",
        fontsize=9,
    )
    return fig


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="0.01 and 0.05 ppp only")
    parser.add_argument("--venv", type=Path, default=DEFAULT_VENV, help="OpenLPT's environment")
    parser.add_argument("--ppp", help="densities to run, comma-separated (default: the list)")
    parser.add_argument(
        "--true-up-to",
        type=float,
        default=1.0,
        help="run the true-camera set only up to this density (OpenLPT's POLYNOMIAL is slow)",
    )
    parser.add_argument("--figure", type=Path, help="also draw found and ghosts to this PNG")
    args = parser.parse_args()
    densities = None if args.ppp is None else [float(v) for v in args.ppp.split(",")]
    result = run(args.quick, args.venv, densities, args.true_up_to)
    json.dump(result, sys.stdout, indent=2)
    print()
    print(markdown(result))
    if args.figure is not None:
        figure(
            [{"variant": v, **row} for v, f in result["variants"].items() for row in f["densities"]]
        ).savefig(args.figure, dpi=110)
