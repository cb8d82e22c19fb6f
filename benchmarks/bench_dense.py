"""Detection on dense images, 0.002–0.05 particles per pixel, beside ``trackpy.locate``.

The images are made here, independently of :mod:`simulator` and of :mod:`ptv`: each
particle is a pixel-integrated Gaussian spot (the light of a Gaussian of width σ falling
on each pixel, erf differences), σ uniform in 0.7–1.0 px, with photo-electrons
log-uniform over a decade, 800–8000 e⁻ (peak SNR ≈ 10–110 over the read noise); then
Poisson shot noise on signal plus 5 e⁻ of background, 8 e⁻ rms of Gaussian read noise,
gain 0.4 DN/e⁻, an offset of 10 DN, rounding to a 12-bit uint16. Centres are uniform
over the image (3 px from the border), so close pairs occur as often as chance makes
them: at 0.05 ppp, 30 % of the particles have a neighbour within 1.5 px.

Both detectors get the same images. Scoring: detections and true centres are matched
one to one within 1 px (per connected cluster of candidates, the assignment with the
most matches, then the least summed distance); ``found`` is the fraction of true
particles matched, ``false`` the fraction of detections left unmatched, ``rms_px`` the
2-D rms error of the matched pairs. Times are per image after a warm-up call (numba
compilation is not counted), the best of the passes.

Beside the bound (``cramer_rao``): every particle's Cramér–Rao bound among its
neighbours, their brightness, widths and the background unknown
(:mod:`validation.truth.crowded_bound`). On the found particles whose bound is at most
0.1 px (locatable), the detector's rms error and the rms of their bounds: how far the
detector is from what the image allows where the image allows it. Over all found
particles the bound is no floor: two spots closer than about σ have bounds far above
1 px, and a detector that reports one spot between them is biased and beats them. What
the found fraction and the rms error over all found particles can be is estimated by
an efficient detector that resolves every pair at least 1.0, 1.2 or 1.5 px apart
(``efficient_detector``): the other particles at their bounds, each cluster of closer
ones as one spot at its brightness-weighted centre (:func:`efficient_detector`). How
far dropping blends instead could go is bounded by an oracle that drops every particle
with another closer than 1.0, 1.2 or 1.5 px, knowing from the truth which ones they
are (``rejecting_oracle``, :func:`rejecting_oracle`).

trackpy is tuned as a careful user with synthetic truth would tune it: on separate
tuning images of the same density (other seeds), a grid of ``diameter`` 3, 5, 7 and
``separation`` 2, 3 and the default (diameter + 1), with ``minmass`` set from a
noise-only frame of the same sensor (1.5 × the largest mass trackpy finds there, so
that it reports no noise features, as synptv's 6σ threshold does); the setting with the
most found minus false detections is then used on the measured images. That favours
trackpy (synptv runs with its defaults, untuned).
"""

import itertools
import time
from pathlib import Path

import numpy as np
from scipy.optimize import linear_sum_assignment
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree
from scipy.special import erf

from benchmarks.machine import machine
from ptv.detect import detect_particles
from validation.truth.crowded_bound import crowded_localisation_bound

DENSITIES = (0.002, 0.005, 0.01, 0.02, 0.03, 0.05)
SHAPE = (512, 512)
#: The targets: (largest density, rms px at most, found at least).
TARGETS = ((0.01, 0.08, 0.95), (0.03, 0.1, 0.85))
#: trackpy's grid (``separation`` None: its default, diameter + 1).
TRACKPY_DIAMETERS = (3, 5, 7)
TRACKPY_SEPARATIONS = (2, 3)
GAIN, READ_NOISE, BACKGROUND, OFFSET, MAX_DN = 0.4, 8.0, 5.0, 10.0, 4095
SIGMA_RANGE = (0.7, 1.0)
ELECTRON_RANGE = (800.0, 8000.0)
FIGURE = Path(__file__).resolve().parents[1] / "docs" / "figures" / "dense_detection.png"


def render(xy: np.ndarray, sigma: np.ndarray, electrons: np.ndarray, shape: tuple) -> np.ndarray:
    """Expected photo-electrons per pixel of pixel-integrated Gaussian spots.

    Parameters
    ----------
    xy : ndarray, shape (N, 2)
        Centres (x = column, y = row), px; pixel (r, c) covers [c − ½, c + ½] × [r − ½, r + ½].
    sigma, electrons : ndarray, shape (N,)
        Gaussian widths, px, and photo-electrons of each spot.
    shape : (H, W)
        Image rows and columns.

    Returns
    -------
    ndarray, shape (H, W), float64
        e⁻ per pixel (each spot drawn over ±4σ; the light beyond is < 10⁻⁴ of it).
    """
    image = np.zeros(shape)
    half = int(np.ceil(4.0 * sigma.max()))
    offsets = np.arange(-half, half + 1)
    cols = np.rint(xy[:, :1]).astype(np.int64) + offsets
    rows = np.rint(xy[:, 1:]).astype(np.int64) + offsets
    root2s = np.sqrt(2.0) * sigma[:, None]

    def mass(edge_pixels: np.ndarray, centre: np.ndarray) -> np.ndarray:
        hi = erf((edge_pixels + 0.5 - centre) / root2s)
        return 0.5 * (hi - erf((edge_pixels - 0.5 - centre) / root2s))

    light = electrons[:, None, None] * mass(rows, xy[:, 1:])[:, :, None]
    light = light * mass(cols, xy[:, :1])[:, None, :]
    rr = np.broadcast_to(rows[:, :, None], light.shape)
    cc = np.broadcast_to(cols[:, None, :], light.shape)
    inside = (rr >= 0) & (rr < shape[0]) & (cc >= 0) & (cc < shape[1])
    np.add.at(image, (rr[inside], cc[inside]), light[inside])
    return image


def record(electrons: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """A 12-bit camera frame, uint16 DN: shot noise, read noise, gain, offset, rounding."""
    counts = rng.poisson(electrons + BACKGROUND) + rng.normal(0.0, READ_NOISE, electrons.shape)
    return np.clip(np.rint(GAIN * counts + OFFSET), 0, MAX_DN).astype(np.uint16)


def spots(ppp: float, shape: tuple, rng: np.random.Generator) -> tuple:
    """Random particles at ``ppp`` per pixel: centres (N, 2), px, Gaussian σ (N,), px,
    and photo-electrons (N,)."""
    rows, cols = shape
    n = round(ppp * rows * cols)
    xy = rng.uniform([3.0, 3.0], [cols - 4.0, rows - 4.0], size=(n, 2))
    sigma = rng.uniform(*SIGMA_RANGE, n)
    electrons = np.exp(rng.uniform(*np.log(ELECTRON_RANGE), n))
    return xy, sigma, electrons


def scene(ppp: float, shape: tuple, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Random particles at ``ppp`` per pixel: true centres (N, 2), px, and the frame."""
    xy, sigma, electrons = spots(ppp, shape, rng)
    return xy, record(render(xy, sigma, electrons, shape), rng)


def bound(xy: np.ndarray, sigma: np.ndarray, electrons: np.ndarray) -> np.ndarray:
    """Cramér–Rao rms error (N,), px, of each spot among its neighbours, for this
    camera (the quantisation's 1/12 DN² counted as read noise)."""
    read = np.sqrt(READ_NOISE**2 + 1.0 / (12.0 * GAIN**2))
    return crowded_localisation_bound(xy, sigma, electrons, BACKGROUND, read, SHAPE)


def _clusters(n: int, i: np.ndarray, j: np.ndarray) -> np.ndarray:
    """Connected-component label of each of n nodes linked by the edges (i, j)."""
    graph = coo_matrix((np.ones(len(i)), (i, j)), shape=(n, n))
    return connected_components(graph, directed=False)[1]


def match(truth: np.ndarray, found: np.ndarray, radius: float = 1.0) -> tuple:
    """One-to-one matching within ``radius`` px: indices into truth and into found.

    Candidate pairs (closer than ``radius``) form clusters; in each, the assignment with
    the most pairs and then the least summed distance is taken.
    """
    if len(truth) == 0 or len(found) == 0:
        return np.empty(0, np.int64), np.empty(0, np.int64)
    pairs = cKDTree(truth).sparse_distance_matrix(cKDTree(found), radius, output_type="ndarray")
    t, f, d = pairs["i"], pairs["j"], pairs["v"]
    if len(t) == 0:
        return np.empty(0, np.int64), np.empty(0, np.int64)
    n_t = len(truth)
    label = _clusters(n_t + len(found), t, n_t + f)
    ti, fi = [], []
    order = np.argsort(label[t], kind="stable")
    bounds = np.flatnonzero(np.diff(label[t][order], prepend=-1, append=-2))
    for a, b in itertools.pairwise(bounds):
        sel = order[a:b]
        rows, r_idx = np.unique(t[sel], return_inverse=True)
        cols, c_idx = np.unique(f[sel], return_inverse=True)
        cost = np.zeros((len(rows), len(cols)))
        cost[r_idx, c_idx] = d[sel] - 2.0 * radius  # every pair beats none
        r, c = linear_sum_assignment(cost)
        ok = cost[r, c] < 0.0
        ti.append(rows[r[ok]])
        fi.append(cols[c[ok]])
    return np.concatenate(ti), np.concatenate(fi)


def score(truths: list, founds: list) -> dict:
    """Found and false fractions and rms error over images, and the error arrays."""
    err, n_true, n_found = [], 0, 0
    for truth, found in zip(truths, founds, strict=True):
        ti, fi = match(truth, found)
        err.append(found[fi] - truth[ti])
        n_true += len(truth)
        n_found += len(found)
    e = np.concatenate(err)
    return {
        "found": round(len(e) / n_true, 4),
        "false": round(1.0 - len(e) / max(n_found, 1), 4),
        "rms_px": round(float(np.sqrt((e**2).sum(axis=1).mean())), 4) if len(e) else None,
    }


def timed(fn, images: list, passes: int) -> tuple[float, list]:
    """Best time per image, ms, over ``passes`` passes after a warm-up, and the results."""
    out = [fn(images[0])]
    best = np.inf
    for _ in range(passes):
        t0 = time.perf_counter()
        out = [fn(im) for im in images]
        best = min(best, (time.perf_counter() - t0) / len(images))
    return best * 1e3, out


def ours(image: np.ndarray) -> np.ndarray:
    """synptv's centres, (N, 2) px."""
    return detect_particles(image).xy


def trackpy_locator(shape: tuple, rng: np.random.Generator):
    """``trackpy.locate`` as a function of (image, diameter, separation) → (N, 2) px, with
    ``minmass`` from a noise-only frame per diameter, and those minmass values."""
    import trackpy

    noise_only = record(np.zeros(shape), rng)
    minmass = {}
    for diameter in TRACKPY_DIAMETERS:
        masses = trackpy.locate(noise_only, diameter, minmass=0)["mass"]
        minmass[diameter] = 1.5 * float(masses.max()) if len(masses) else 0.0

    def locate(image, diameter, separation):
        found = trackpy.locate(image, diameter, minmass=minmass[diameter], separation=separation)
        return found[["x", "y"]].to_numpy()

    return locate, minmass


def tune_trackpy(locate, ppp: float, shape: tuple, seed: int) -> tuple[int, float | None]:
    """(diameter, separation) of the grid with the most found minus false detections on a
    tuning image of density ``ppp`` (not one of the measured images)."""
    truth, image = scene(ppp, shape, np.random.default_rng(seed))
    best, best_score = None, -np.inf
    for diameter in TRACKPY_DIAMETERS:
        for separation in (*TRACKPY_SEPARATIONS, None):
            found = locate(image, diameter, separation)
            got = score([truth], [found]) if len(found) else {"found": 0.0, "false": 0.0}
            if got["found"] - got["false"] > best_score:
                best, best_score = (diameter, separation), got["found"] - got["false"]
    return best


def figure(rows: list, path: Path) -> None:
    """Found fraction, false fraction and rms error against density, both detectors."""
    import matplotlib
    import matplotlib.ticker

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ppp = [r["ppp"] for r in rows]
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.6), constrained_layout=True)
    panels = (("found", "found fraction"), ("false", "false-detection fraction"))
    panels += (("rms_px", "rms error of the found, px"),)
    for ax, (key, label) in zip(axes, panels, strict=True):
        for name, style in (("synptv", "o-"), ("trackpy", "s--")):
            ax.plot(ppp, [r[name][key] for r in rows], style, label=name)
        ax.set_xscale("log")
        ax.set_xticks(ppp, [f"{v:g}" for v in ppp], minor=False)
        ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        ax.set_xlabel("particles per pixel")
        ax.set_title(label)
        ax.grid(True, which="both", alpha=0.3)
    for key, style, label in (
        ("rms_px", "^-", "synptv, particles with a bound <= 0.1 px"),
        ("bound_rms_px", "v:", "their Cramér–Rao bound"),
    ):
        values = [r["synptv"]["cramer_rao"][key] for r in rows]
        axes[2].plot(ppp, values, style, color="grey", label=label)
    drawn = f"{DRAWN_MERGE:g} px"
    references = (  # (row key, entry, label, style, colour)
        (
            "efficient_detector",
            f"pairs from {drawn}",
            "efficient detector resolving pairs from",
            "d-.",
            "tab:green",
        ),
        (
            "rejecting_oracle",
            f"drops pairs closer than {drawn}",
            "oracle dropping pairs closer than",
            "x:",
            "tab:purple",
        ),
    )
    for name, entry, label, style, colour in references:
        for key, ax in (("found", axes[0]), ("rms_px", axes[2])):
            values = [r[name][entry][key] for r in rows]
            ax.plot(ppp, values, style, color=colour, label=f"{label} {drawn}")
    axes[2].legend(fontsize=7)
    for ppp_max, rms_max, found_min in TARGETS:
        axes[0].plot([min(ppp), ppp_max], [found_min] * 2, "k:", lw=1)
        axes[2].plot([min(ppp), ppp_max], [rms_max] * 2, "k:", lw=1)
    axes[0].legend(fontsize=7)
    fig.suptitle(
        "Dense images: pixel-integrated Gaussian spots, σ 0.7–1.0 px, 800–8000 e⁻ "
        "(dotted: the targets)",
        fontsize=10,
    )
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


#: A particle is "locatable" when its Cramér–Rao bound is at most this, px.
LOCATABLE_PX = 0.1
#: Separations, px, below which :func:`efficient_detector` reports particles as one spot
#: (and :func:`rejecting_oracle` drops them); the one drawn in the figure.
MERGE_DISTANCES = (1.0, 1.2, 1.5)
DRAWN_MERGE = 1.2


def efficient_detector(
    truths: list, electrons: list, bounds: list, merge: float, radius: float = 1.0
) -> dict:
    """What an efficient detector that resolves every pair at least ``merge`` px apart
    would score, from the truth alone.

    A particle with no other closer than ``merge`` is found with an error at its
    Cramér–Rao bound. Particles linked by separations below ``merge`` (clusters) are
    reported as one spot at their centre weighted by photo-electrons (where one fitted
    spot lands on a blend), matched as :func:`match` would: to the member nearest to it,
    if within ``radius``. Returns the found fraction and the rms error, px.

    Parameters
    ----------
    truths, electrons, bounds : list of ndarray
        Per image: true centres (N, 2), px; photo-electrons (N,); bounds (N,), px.
    merge : float
        Separation below which two particles are not resolved, px.
    """
    square, found, total = 0.0, 0, 0
    for xy, weight, limit in zip(truths, electrons, bounds, strict=True):
        n = len(xy)
        pairs = cKDTree(xy).query_pairs(merge, output_type="ndarray")
        label = _clusters(n, pairs[:, 0], pairs[:, 1])
        single = np.bincount(label)[label] == 1
        square += float(np.sum(limit[single] ** 2))
        clustered = np.flatnonzero(~single)
        lab = label[clustered]
        mass = np.bincount(lab, weights=weight[clustered], minlength=n).astype(float)
        centre = np.column_stack(
            [
                np.bincount(lab, weights=weight[clustered] * xy[clustered, a], minlength=n)
                for a in (0, 1)
            ]
        ).astype(float)
        centre[mass > 0] /= mass[mass > 0, None]
        gap = np.hypot(*(xy[clustered] - centre[lab]).T)
        nearest = np.full(len(mass), np.inf)
        np.minimum.at(nearest, lab, gap)
        nearest = nearest[np.isfinite(nearest) & (nearest <= radius)]
        square += float(np.sum(nearest**2))
        found += int(single.sum()) + len(nearest)
        total += n
    return {"found": round(found / total, 4), "rms_px": round(float(np.sqrt(square / found)), 4)}


def rejecting_oracle(truths: list, bounds: list, merge: float) -> dict:
    """What a detector would score that knows, as no detector can, which particles have
    another closer than ``merge`` px, and drops them all (instead of reporting a blend),
    locating every other particle at its Cramér–Rao bound.

    A real detector cannot tell such blends from single spots (it would split them if it
    could): it drops single particles with them, or keeps some of them. Returns the
    found fraction and the rms error, px.

    Parameters
    ----------
    truths, bounds : list of ndarray
        Per image: true centres (N, 2), px; bounds (N,), px.
    merge : float
        Separation below which two particles are not resolved, px.
    """
    square, found, total = 0.0, 0, 0
    for xy, limit in zip(truths, bounds, strict=True):
        nearest = cKDTree(xy).query(xy, k=2)[0][:, 1]
        alone = nearest >= merge
        square += float(np.sum(limit[alone] ** 2))
        found += int(alone.sum())
        total += len(xy)
    return {"found": round(found / total, 4), "rms_px": round(float(np.sqrt(square / found)), 4)}


def against_bound(truths: list, bounds: list, founds: list) -> dict:
    """A detector's error beside the Cramér–Rao bound, on the particles it found that
    the bound says can be located to :data:`LOCATABLE_PX`: their fraction of the found,
    the detector's rms error on them and the rms of their bounds, px."""
    errors, limits, count = [], [], 0
    for truth, limit, found in zip(truths, bounds, founds, strict=True):
        ti, fi = match(truth, found)
        keep = limit[ti] <= LOCATABLE_PX
        errors.append(found[fi[keep]] - truth[ti[keep]])
        limits.append(limit[ti[keep]])
        count += len(ti)
    e, b = np.concatenate(errors), np.concatenate(limits)
    return {
        "locatable": round(len(b) / max(count, 1), 4),
        "rms_px": round(float(np.sqrt((e**2).sum(axis=1).mean())), 4),
        "bound_rms_px": round(float(np.sqrt(np.mean(b**2))), 4),
    }


def _measure(ppp: float, n_images: int, passes: int, locate, setting: tuple) -> dict:
    """Both detectors on the same ``n_images`` images of density ``ppp``."""
    truths, images, bounds, brightness = [], [], [], []
    for i in range(n_images):
        rng = np.random.default_rng(1000 * i + 7)
        xy, sigma, electrons = spots(ppp, SHAPE, rng)
        truths.append(xy)
        brightness.append(electrons)
        images.append(record(render(xy, sigma, electrons, SHAPE), rng))
        bounds.append(bound(xy, sigma, electrons))
    ms_ours, found_ours = timed(ours, images, passes)
    diameter, separation = setting
    ms_tp, found_tp = timed(lambda im: locate(im, diameter, separation), images, passes)
    row = {
        "ppp": ppp,
        "particles": int(sum(len(t) for t in truths)),
        "synptv": {**score(truths, found_ours), "ms_per_image": round(ms_ours, 2)},
        "trackpy": {
            "diameter": diameter,
            "separation": separation,
            **score(truths, found_tp),
            "ms_per_image": round(ms_tp, 2),
        },
        "speed_ratio": round(ms_tp / ms_ours, 2),
    }
    row["synptv"]["cramer_rao"] = against_bound(truths, bounds, found_ours)
    row["trackpy"]["cramer_rao"] = against_bound(truths, bounds, found_tp)
    row["efficient_detector"] = {
        f"pairs from {merge:g} px": efficient_detector(truths, brightness, bounds, merge)
        for merge in MERGE_DISTANCES
    }
    row["rejecting_oracle"] = {
        f"drops pairs closer than {merge:g} px": rejecting_oracle(truths, bounds, merge)
        for merge in MERGE_DISTANCES
    }
    return row


def run(quick: bool) -> dict:
    import trackpy

    trackpy.quiet()
    n_images, passes = (1, 2) if quick else (3, 5)
    locate, minmass = trackpy_locator(SHAPE, np.random.default_rng(3))
    rows = []
    for ppp in DENSITIES:
        setting = tune_trackpy(locate, ppp, SHAPE, seed=99)
        rows.append(_measure(ppp, n_images, passes, locate, setting))
    checks = {}
    for ppp_max, rms_max, found_min in TARGETS:
        at = [r["synptv"] for r in rows if r["ppp"] <= ppp_max]
        checks[f"up to {ppp_max} ppp: rms <= {rms_max} px and found >= {found_min}"] = bool(
            all(r["rms_px"] <= rms_max and r["found"] >= found_min for r in at)
        )
    if not quick:
        figure(rows, FIGURE)
    return {
        "machine": machine(),
        "image": f"{SHAPE[1]}x{SHAPE[0]} uint16 (12-bit)",
        "images_per_density": n_images,
        "trackpy_minmass": {str(d): round(m, 1) for d, m in minmass.items()},
        "densities": rows,
        "targets": checks,
        "figure": str(FIGURE.relative_to(FIGURE.parents[2])) if not quick else None,
        "trackpy_version": trackpy.__version__,
    }
