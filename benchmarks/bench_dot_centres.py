"""Plate dot centres: synptv's ``find_dots`` beside OpenPTV's target recognition.

Two parts (docs/calibration.md §11):

- **The real plate** (``examples/openptv-multiplane``, 4 cameras × 4 planes, 405 dots
  each): synptv's centres (``find_dots``, seeded as ``synptv calibrate`` seeds them)
  against the ``.crd`` centres OpenPTV shipped, raw and with OpenPTV's half-pixel origin
  removed; whether ``optv``'s own ``target_recognition`` (with the dataset's
  ``detect_plate.par``) gives the shipped ``.crd`` back; what the plate's dots are like
  (grey levels, blob areas, edge pixels, background noise); and, unless ``quick``, the
  Table 1 figures of ``synptv calibrate`` on the ``.crd`` lists with and without the
  half-pixel.
- **Synthetic plates with known centres**: a 27 × 15 grid at 47 px pitch (the real
  plate's median), each dot's centre jittered uniformly over a pixel so that every sub-pixel
  position occurs. A dot is a disc of diameter D, area-sampled (16 × 16 samples per
  pixel), convolved with a Gaussian of σ_b (the blur), on a background with a contrast,
  Gaussian noise, rounded to 8 bits. Cases: the real plate's own drawing (a 13-pixel
  diamond at the rounded centre, binary 0/255), the same-size disc binarised at half
  coverage, and grey discs of D = 4.07 px (the real dots' area, 13 px²) and 10 px with
  σ_b = 0, 0.5, 1 px and 0 or 2 DN of noise (on these synptv also runs with ``margin=1``,
  a tighter centroid window). Both estimators are compared with the true
  centres: mean bias per axis, rms per axis, median |error|, and the peak-locking
  amplitude (the first harmonic of the error against the true centre's sub-pixel phase).

OpenPTV's estimator is its ``targ_rec``: the 4-connected region above the grey
threshold ``t`` grown from a local maximum, centre = Σ(g − t)·x / Σ(g − t) + 0.5 (its
origin is the top-left pixel's corner). With ``optv`` installed (``pip install
".[peers]"`` in the clone) its ``target_recognition`` is run; without it, the same formula in
NumPy (``_openptv_numpy``), and the JSON says which. The grey threshold is the
dataset's (10 DN above a background of 0) and, on grey plates, also half the contrast.

Run: ``python -m benchmarks.bench_dot_centres [--quick]``; prints one JSON object.
"""

import contextlib
import io
import json
import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np
from scipy import ndimage
from scipy.spatial import cKDTree

from ptv.calibration.dot_lists import read_openptv_dots
from ptv.calibration.plate import PlateDescription
from ptv.calibration.plate_images import find_traverse_dots, plate_setup, read_image
from ptv.calibration.targets import find_dots

EXAMPLE = Path(__file__).parents[1] / "examples" / "openptv-multiplane"
CAMERAS, PLANES = 4, 4
#: OpenPTV's detect_plate.par of the example (parametersMultiPlane): grey thresholds per
#: camera, discontinuity, pixel count, x and y extent bounds, minimum grey sum.
DETECT_PLATE = {
    "thresholds": [5, 10, 10, 10],
    "discont": 500,
    "pixels": (9, 400),
    "xsize": (3, 50),
    "ysize": (3, 50),
    "sumg_min": 100,
}
SHAPE = (1200, 1920)  # rows, columns: the real plate's images
PITCH_PX = 47.0  # the real plate's dot spacing on its images (median), px
GRID = ((-13, 13), (-7, 7))  # 27 × 15 dots, as the real plate
SUPERSAMPLE = 16
MATCH_PX = 2.0
SEEDS = ((-10, -4), (10, -4), (10, 4), (-10, 4))


# --------------------------------------------------------------------------- OpenPTV


def _openptv_numpy(image: np.ndarray, threshold: float) -> np.ndarray:
    """OpenPTV's targ_rec centres (its pixel origin): 4-connected regions of pixels above
    ``threshold``, weights (g − threshold), the pixel-count and extent bounds of
    DETECT_PLATE, regions touching the image border dropped, + 0.5 px."""
    g = image.astype(float)
    labels, n = ndimage.label(g > threshold)  # 4-connectivity
    if n == 0:
        return np.zeros((0, 2))
    index = np.arange(1, n + 1)
    w = np.where(labels > 0, g - threshold, 0.0)
    rows, cols = np.indices(g.shape)
    s = ndimage.sum(w, labels, index)
    x = ndimage.sum(w * cols, labels, index) / s + 0.5
    y = ndimage.sum(w * rows, labels, index) / s + 0.5
    count = ndimage.sum(np.ones_like(g), labels, index)
    boxes = ndimage.find_objects(labels)
    nx = np.array([b[1].stop - b[1].start for b in boxes])
    ny = np.array([b[0].stop - b[0].start for b in boxes])
    edge = np.array(
        [
            b[0].start == 0 or b[1].start == 0 or b[0].stop == g.shape[0] or b[1].stop == g.shape[1]
            for b in boxes
        ]
    )
    lo, hi = DETECT_PLATE["pixels"]
    keep = (
        (count >= lo)
        & (count <= hi)
        & (nx >= DETECT_PLATE["xsize"][0])
        & (nx <= DETECT_PLATE["xsize"][1])
        & (ny >= DETECT_PLATE["ysize"][0])
        & (ny <= DETECT_PLATE["ysize"][1])
        & (ndimage.sum(g, labels, index) > DETECT_PLATE["sumg_min"])
        & ~edge
    )
    return np.column_stack([x, y])[keep]


def _optv_available() -> bool:
    try:
        import optv.segmentation  # noqa: F401
    except ImportError:
        return False
    return True


def _openptv(image: np.ndarray, threshold: int) -> np.ndarray:
    """OpenPTV's dot centres on an 8-bit image, its pixel origin: optv's
    target_recognition when installed, else :func:`_openptv_numpy`."""
    if not _optv_available():
        return _openptv_numpy(image, threshold)
    from optv.parameters import ControlParams, TargetParams
    from optv.segmentation import target_recognition

    control = ControlParams(1)
    control.set_image_size((image.shape[1], image.shape[0]))
    control.set_pixel_size((0.00586, 0.00586))
    params = TargetParams()
    params.set_grey_thresholds([int(threshold), 0, 0, 0])
    params.set_max_discontinuity(DETECT_PLATE["discont"])
    params.set_pixel_count_bounds(DETECT_PLATE["pixels"])
    params.set_xsize_bounds(DETECT_PLATE["xsize"])
    params.set_ysize_bounds(DETECT_PLATE["ysize"])
    params.set_min_sum_grey(DETECT_PLATE["sumg_min"])
    params.set_cross_size(2)
    found = target_recognition(np.ascontiguousarray(image, dtype=np.uint8), params, 0, control)
    return np.array([found[i].pos() for i in range(len(found))]).reshape(-1, 2)


# --------------------------------------------------------------------------- real plate


def _dot_properties(image: np.ndarray, pixels: np.ndarray) -> dict:
    """Grey levels, blob areas and edge of the dots of one binary-looking plate image."""
    levels = np.unique(image)
    lit = image > 0.5 * float(image.max())
    labels, _ = ndimage.label(lit, structure=np.ones((3, 3)))
    areas = np.bincount(labels.ravel())[1:]
    background = image[~ndimage.binary_dilation(lit, iterations=4)].astype(float)
    mad = float(np.median(np.abs(background - np.median(background))))
    return {
        "grey_levels": [int(v) for v in levels[:8]],
        "areas": areas,
        "intermediate_pixels": int(np.count_nonzero((image > levels[0]) & (image < levels[-1]))),
        "background_noise_dn": 1.4826 * mad,
        "contrast_dn": float(image.max()) - float(np.median(background)),
        "dots": len(pixels),
    }


def _table1_with_shift(shift: float) -> dict:
    """``synptv calibrate`` (model-free, pinhole) on the example's .crd lists, every
    coordinate moved by ``shift`` px first (0.5: the half-pixel left in)."""
    from validation.cli import main as synptv

    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp) / "openptv"
        shutil.copytree(EXAMPLE / "openptv", folder)
        for crd in (folder / "cal").glob("*.crd"):
            rows = np.loadtxt(crd)
            rows[:, 1:] += shift
            np.savetxt(crd, rows, fmt="%.5f")
        out = io.StringIO()
        argv = ["calibrate", "--dataset", str(folder), "--methods", "model-free,pinhole"]
        argv += ["--out", f"{tmp}/cal", "--json", "--quiet"]
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(io.StringIO()):
            if synptv(argv) != 0:
                raise RuntimeError("synptv calibrate failed on the .crd lists")
    result = json.loads(out.getvalue())
    return {
        method: {
            "d_um": round(t["nominal"]["d_um"], 3),
            "leave_one_plane_out_um": round(result["leave_one_plane_out"][method]["d_um"], 3),
        }
        for method, t in result["table1"].items()
    }


def _real_plate(quick: bool) -> dict:
    setup = plate_setup(EXAMPLE)
    found = find_traverse_dots(setup)
    raw, corrected, optv_vs_crd = [], [], []
    areas, props = [], []
    for c, (name, planes) in enumerate(found.items(), start=1):
        for j, dots in enumerate(planes):
            stem = EXAMPLE / "openptv" / "cal" / f"plane{j + 1}_cam{c}.tif"
            crd_xy = np.loadtxt(f"{stem}.crd")[:, 1:3]
            indices, crd_synptv = read_openptv_dots(
                Path(f"{stem}.crd"), Path(f"{stem}.fix"), setup.plate, setup.z[j], SHAPE[::-1]
            )
            mine = {tuple(k): p for k, p in zip(dots.indices.tolist(), dots.pixels, strict=True)}
            rows = [k for k, ij in enumerate(indices.tolist()) if tuple(ij) in mine]
            ours = np.array([mine[tuple(indices[k])] for k in rows])
            corrected.append(ours - crd_synptv[rows])
            raw.append(ours - crd_xy[rows])
            image = read_image(setup.images[name][j])
            props.append(_dot_properties(image, dots.pixels))
            areas.append(props[-1]["areas"])
            theirs = _openptv(image, DETECT_PLATE["thresholds"][c - 1])
            d, _ = cKDTree(theirs).query(crd_xy)
            optv_vs_crd.append(d)
    raw, corrected = np.concatenate(raw), np.concatenate(corrected)
    areas = np.concatenate(areas)
    values, counts = np.unique(areas, return_counts=True)
    mode_area = int(values[np.argmax(counts)])
    out = {
        "dots_compared": len(raw),
        "synptv_minus_crd_raw_px": {
            "mean_xy": np.round(raw.mean(axis=0), 4).tolist(),
            "median_abs_px": round(float(np.median(np.linalg.norm(raw, axis=1))), 4),
        },
        "synptv_minus_crd_after_half_pixel_px": {
            "mean_xy": np.round(corrected.mean(axis=0), 4).tolist(),
            "median_abs_px": round(float(np.median(np.linalg.norm(corrected, axis=1))), 4),
            "max_abs_px": round(float(np.linalg.norm(corrected, axis=1).max()), 4),
        },
        "openptv_rerun_vs_shipped_crd_max_px": round(float(np.concatenate(optv_vs_crd).max()), 4),
        "plate": {
            "grey_levels": sorted({v for p in props for v in p["grey_levels"]}),
            "intermediate_grey_pixels": int(sum(p["intermediate_pixels"] for p in props)),
            "background_noise_dn": round(max(p["background_noise_dn"] for p in props), 3),
            "contrast_dn": round(float(np.median([p["contrast_dn"] for p in props])), 1),
            "blob_area_mode_px": mode_area,
            "blobs_of_mode_area": round(float(counts.max() / counts.sum()), 4),
            "equivalent_diameter_px": round(float(np.sqrt(4 * mode_area / np.pi)), 3),
            "pitch_px_median": round(_median_pitch(found), 2),
        },
    }
    if not quick:
        out["table1_crd_half_pixel_removed"] = _table1_with_shift(0.0)
        out["table1_crd_half_pixel_left_in"] = _table1_with_shift(0.5)
    return out


def _median_pitch(found: dict) -> float:
    steps = []
    for planes in found.values():
        for dots in planes:
            at = {tuple(k): p for k, p in zip(dots.indices.tolist(), dots.pixels, strict=True)}
            steps += [
                np.linalg.norm(at[(i + 1, j)] - p) for (i, j), p in at.items() if (i + 1, j) in at
            ]
    return float(np.median(steps))


# --------------------------------------------------------------------------- synthetic


def _true_centres(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Grid indices (i, j) and true centres (x, y), synptv's convention (px)."""
    (i0, i1), (j0, j1) = GRID
    ii, jj = np.meshgrid(np.arange(i0, i1 + 1), np.arange(j0, j1 + 1))
    ij = np.column_stack([ii.ravel(), jj.ravel()])
    centre = np.array([(SHAPE[1] - 1) / 2, (SHAPE[0] - 1) / 2])
    xy = centre + PITCH_PX * ij * np.array([1.0, -1.0])
    return ij, xy + rng.uniform(-0.5, 0.5, xy.shape)


def _disc_patch(offset: np.ndarray, diameter: float, blur: float, half: int) -> np.ndarray:
    """Pixel values (0..1) of a disc centred ``offset`` px from the centre pixel of a
    (2·half + 1)² patch: area-sampled, convolved with a Gaussian of σ ``blur`` px."""
    n = (2 * half + 1) * SUPERSAMPLE
    s = (np.arange(n) + 0.5) / SUPERSAMPLE - 0.5 - half  # sample positions, px
    fine = ((s[None, :] - offset[0]) ** 2 + (s[:, None] - offset[1]) ** 2) <= (diameter / 2) ** 2
    fine = fine.astype(np.float32)
    if blur > 0:
        fine = ndimage.gaussian_filter(fine, blur * SUPERSAMPLE, mode="constant", truncate=4.0)
    return fine.reshape(2 * half + 1, SUPERSAMPLE, 2 * half + 1, SUPERSAMPLE).mean(axis=(1, 3))


def _render(case: dict, xy: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """An 8-bit plate image of ``case`` with its dots at ``xy``."""
    light = np.zeros(SHAPE)
    kind = case["kind"]
    if kind == "diamond":  # the real plate's drawing: |dx| + |dy| <= 2 at the rounded centre
        dy, dx = np.mgrid[-2:3, -2:3]
        inside = np.abs(dx) + np.abs(dy) <= 2
        for x, y in np.rint(xy).astype(int):
            light[y - 2 : y + 3, x - 2 : x + 3][inside] = 1.0
    else:
        half = int(np.ceil(case["diameter"] / 2 + 4 * case["blur"] + 2))
        for p in xy:
            base = np.rint(p).astype(int)
            patch = _disc_patch(p - base, case["diameter"], case["blur"], half)
            if kind == "binary":
                patch = (patch >= 0.5).astype(float)
            x, y = base
            light[y - half : y + half + 1, x - half : x + half + 1] += patch
    image = case["background"] + case["contrast"] * light
    if case["noise"] > 0:
        image = image + rng.normal(0.0, case["noise"], image.shape)
    return np.clip(np.rint(image), 0, 255).astype(np.uint8)


def _errors(found: np.ndarray, truth: np.ndarray) -> dict:
    """Each true centre's nearest estimate within MATCH_PX: error figures, px."""
    if len(found) == 0:
        return {"matched": 0}
    d, k = cKDTree(found).query(truth, distance_upper_bound=MATCH_PX)
    ok = np.isfinite(d)
    e, t = found[k[ok]] - truth[ok], truth[ok]
    phase = 2 * np.pi * (t - np.rint(t))  # sub-pixel position of the true centre
    locking = []
    for axis in range(2):
        a = np.column_stack([np.sin(phase[:, axis]), np.cos(phase[:, axis]), np.ones(len(t))])
        coef, *_ = np.linalg.lstsq(a, e[:, axis], rcond=None)
        locking.append(float(np.hypot(coef[0], coef[1])))
    return {
        "matched": int(ok.sum()),
        "bias_xy_px": np.round(e.mean(axis=0), 4).tolist(),
        "rms_xy_px": np.round(np.sqrt((e**2).mean(axis=0)), 4).tolist(),
        "median_abs_px": round(float(np.median(np.linalg.norm(e, axis=1))), 4),
        "peak_locking_px": round(max(locking), 4),
    }


def _cases(quick: bool) -> list[dict]:
    real = {"diameter": 4.07, "blur": 0.0, "background": 0, "contrast": 255, "noise": 0.0}
    cases = [
        {"name": "real plate's drawing (diamond at the rounded centre)", "kind": "diamond", **real},
        {"name": "binary disc, same area", "kind": "binary", **real},
    ]
    diameters = (4.07,) if quick else (4.07, 10.0)
    blurs = (0.5,) if quick else (0.0, 0.5, 1.0)
    noises = (2.0,) if quick else (0.0, 2.0)
    for diameter in diameters:
        for blur in blurs:
            for noise in noises:
                cases.append(
                    {
                        "name": f"grey disc D={diameter:g} px, blur σ={blur:g} px, "
                        f"noise {noise:g} DN",
                        "kind": "grey",
                        "diameter": diameter,
                        "blur": blur,
                        "background": 20,
                        "contrast": 200,
                        "noise": noise,
                    }
                )
    return cases


def _synthetic(quick: bool) -> list[dict]:
    rng = np.random.default_rng(11)
    plate = PlateDescription(pitch=0.005, dot_diameter=0.00046, extent=GRID, dots="bright")
    out = []
    for case in _cases(quick):
        ij, truth = _true_centres(rng)
        image = _render(case, truth, rng)
        at = {tuple(k): p for k, p in zip(ij.tolist(), truth, strict=True)}
        seeds = {s: tuple(np.rint(at[s])) for s in SEEDS}
        dots = find_dots(image, plate, source=case["name"], seeds=seeds)
        thresholds = {"10 DN above background": case["background"] + 10}
        if case["kind"] == "grey":
            thresholds["half the contrast"] = case["background"] + case["contrast"] // 2
        row = {
            **{k: case[k] for k in ("name", "diameter", "blur", "background", "contrast", "noise")},
            "dots": len(truth),
            "synptv": _errors(dots.pixels, truth),
        }
        if case["kind"] == "grey":  # the centroid window: the blob grown by 1 px, not 3
            tight = find_dots(image, plate, source=case["name"], seeds=seeds, margin=1)
            row["synptv, margin 1"] = _errors(tight.pixels, truth)
        for label, t in thresholds.items():
            theirs = _openptv(image, t) - 0.5  # OpenPTV's origin → synptv's
            row[f"openptv, threshold {label} ({t} DN)"] = _errors(theirs, truth)
            if label.startswith("10 DN"):
                d, _ = cKDTree(theirs).query(dots.pixels, distance_upper_bound=MATCH_PX)
                row["synptv_vs_openptv_median_px"] = round(float(np.median(d[np.isfinite(d)])), 4)
        out.append(row)
    return out


def run(quick: bool = False) -> dict:
    """The real plate's comparison and the synthetic plates' errors (see the docstring)."""
    return {
        "openptv_estimator": "optv.target_recognition" if _optv_available() else "numpy",
        "real_plate": _real_plate(quick),
        "synthetic": _synthetic(quick),
    }


if __name__ == "__main__":
    json.dump(run(quick="--quick" in sys.argv[1:]), sys.stdout, indent=2)
    print()
