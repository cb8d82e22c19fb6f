"""The IPR driver an OpenLPT export ships as ``run_ipr.py`` (run with OpenLPT's Python).

OpenLPT's command line (``openlpt config.txt``) runs Shake-the-Box over a frame range;
double-frame snapshots are independent pairs, which STB cannot link, so the export adds
a small script that runs OpenLPT's own IPR (``openlpt.IPR.runIPR``, its Python API) on
each frame of a configuration and writes the particles it finds. It imports nothing of
synptv: it runs in the Python environment where OpenLPT is installed. The script's text
is :data:`DRIVER`; its usage is in its own docstring.
"""

#: ``run_ipr.py``: OpenLPT's IPR on every frame of a configuration file.
DRIVER = r'''"""OpenLPT's IPR on each frame of an OpenLPT configuration (written by synptv export).

Run it with the Python where OpenLPT is installed (pip install openlpt), from anywhere:

    python run_ipr.py config_dt0.txt [--frames FIRST LAST] [--out ipr.csv]
                      [--positions positions.csv --dt K] [--summary summary.json]
    python run_ipr.py config_dt0.txt --project points.csv --out projected.csv

It changes into the configuration's folder (OpenLPT reads the paths of a configuration
relative to the working folder), reads the configuration and its tracer configuration
(which also estimates OpenLPT's OTF on the first five frames of the image lists), then
runs OpenLPT's IPR on each frame FIRST ... LAST (default: the configuration's frame
range; frames are lines of the image lists, from 0).

Outputs (relative paths are taken from the configuration's folder):
  --out FILE        CSV "frame,x_mm,y_mm,z_mm": every particle found, mm (default:
                    <output folder of the configuration>/ipr.csv)
  --positions FILE  the same particles as synptv score reads them, "dt,snapshot,frame,
                    x,y,z" in metres, with frames.csv (beside the configuration) turning
                    the frame (line) numbers of Δt index K into snapshots and a/b
  --summary FILE    JSON: seconds to read the configuration and estimate the OTF, and
                    per frame the particles found, the seconds of runIPR, the process's
                    resident memory before it and its peak during it (MiB, Linux)
  --project FILE    instead of IPR: project the points of FILE (CSV "x_mm,y_mm,z_mm")
                    with every camera of the configuration (Camera.project) and write
                    "camera,x_px,y_px" rows to --out
OpenMP uses every core unless OMP_NUM_THREADS is set.
"""

import argparse
import csv
import json
import os
import sys
import time
from pathlib import Path


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("config")
    parser.add_argument("--frames", nargs=2, type=int, metavar=("FIRST", "LAST"))
    parser.add_argument("--out")
    parser.add_argument("--positions")
    parser.add_argument("--dt", type=int)
    parser.add_argument("--summary")
    parser.add_argument("--project")
    args = parser.parse_args(argv)
    if args.positions and args.dt is None:
        parser.error("--positions needs --dt (the Δt index of the configuration)")
    import openlpt as lpt

    config = Path(args.config).resolve()
    os.chdir(config.parent)
    t0 = time.perf_counter()
    basic = lpt.BasicSetting()
    if not basic.readConfig(str(config)):
        sys.exit(f"{config}: OpenLPT could not read it")
    if args.project:
        with open(args.project) as stream:
            points = [
                [float(r[k]) for k in ("x_mm", "y_mm", "z_mm")] for r in csv.DictReader(stream)
            ]
        rows = []
        for c, cam in enumerate(basic._cam_list):
            for x, y, z in points:
                p = cam.project(lpt.Pt3D(x, y, z))
                rows.append((c, repr(p[0]), repr(p[1])))
        _write(args.out or "projected.csv", ["camera", "x_px", "y_px"], rows)
        return 0
    tracer = lpt.TracerConfig()
    tracer.readConfig(basic._object_config_paths[0], basic)
    seconds_config = time.perf_counter() - t0
    first, last = args.frames or (basic._frame_start, basic._frame_end)
    readers = [lpt.ImageIO("", path) for path in basic._image_file_paths]
    found, frames = [], []
    for frame in range(first, last + 1):
        images = [reader.loadImg(frame) for reader in readers]
        ipr = lpt.IPR(basic._cam_list)
        before = _reset_peak_memory()
        t1 = time.perf_counter()
        objects = ipr.runIPR(tracer, images)
        seconds = time.perf_counter() - t1
        for o in objects:
            found.append((frame, o._pt_center[0], o._pt_center[1], o._pt_center[2]))
        frames.append(
            {
                "frame": frame,
                "particles": len(objects),
                "seconds_ipr": seconds,
                "rss_before_mb": before,
                "peak_rss_mb": _memory("VmHWM"),
            }
        )
    out = args.out or os.path.join(basic._output_path, "ipr.csv")
    _write(out, ["frame", "x_mm", "y_mm", "z_mm"], [(f, *map(repr, p)) for f, *p in found])
    if args.positions:
        with open("frames.csv") as stream:
            names = {
                int(r["frame_index"]): (r["snapshot"], r["frame"])
                for r in csv.DictReader(stream)
                if int(r["dt"]) == args.dt
            }
        rows = [
            (args.dt, *names[f], *(repr(v / 1000.0) for v in p))
            for f, *p in found
            if f in names
        ]
        _write(args.positions, ["dt", "snapshot", "frame", "x", "y", "z"], rows)
    if args.summary:
        Path(args.summary).write_text(
            json.dumps({"seconds_config_and_otf": seconds_config, "frames": frames}, indent=2)
        )
    return 0


def _memory(field):
    """A memory figure of this process from /proc/self/status, MiB (None if unreadable)."""
    try:
        with open("/proc/self/status") as stream:
            for line in stream:
                if line.startswith(field + ":"):
                    return int(line.split()[1]) / 1024
    except OSError:
        return None
    return None


def _reset_peak_memory():
    """Reset the process's peak resident set (Linux: 5 to /proc/self/clear_refs) and
    return its resident set now, MiB."""
    try:
        with open("/proc/self/clear_refs", "w") as stream:
            stream.write("5")
    except OSError:
        pass
    return _memory("VmRSS")


def _write(path, header, rows):
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="") as stream:
        writer = csv.writer(stream)
        writer.writerow(header)
        writer.writerows(rows)


if __name__ == "__main__":
    sys.exit(main())
'''
