"""Mutations of iterative particle reconstruction (docs/claims.md §5, claims #55–#57).

Shaking switched off, the measured OTF 10 % too wide, the ghost threshold twice what
it should be (halved, it is measured in docs/claims.md §5 but not registered: no claim or
check sees it at these densities), and the defocus law's σ² taken for σ. Their probes
reconstruct a few particles drawn on lpt-challenge-small's four sensors (one of them at a
quarter of the others' light, which the honest threshold removes, one at half, which it
keeps), measure their OTF per depth, and evaluate the defocus law on exact widths.
"""

from dataclasses import replace

import numpy as np

from ptv.reconstruct import (
    IPRSettings,
    OpticalTransferFunction,
    defocus_law,
    draw_spots,
    reconstruct,
    refine_otf,
)
from simulator.rigs import load_rig
from validation.mutations.base import Mutation
from validation.mutations.patching import Patch, edited

#: Factor of the widened OTF's σ.
WIDER = 1.1
#: The probe: particles, their images' σ (px), integrated intensity, background and
#: noise (DN), and the relative light of its faint particle (between half the honest
#: ghost threshold, 0.35, and the threshold) and of its dim one (between the threshold
#: and twice it).
PROBE_PARTICLES = 30
PROBE_SIGMA = 0.7
PROBE_INTENSITY = 2000.0
PROBE_BACKGROUND = 100.0
PROBE_NOISE = 2.0
PROBE_FAINT = 0.25
PROBE_DIM = 0.5
#: Outer iterations of the probe's reconstruction (it finds every particle in the first;
#: the faint one, found and removed again in each, keeps it from converging).
PROBE_ITERATIONS = 4


def _probe_scene():
    """The probe's cameras, box, particles, images and an OTF without depth per camera."""
    rig = load_rig("lpt-challenge-small")
    centre, size = np.asarray(rig.sheet.centre), np.asarray(rig.sheet.size)
    box = (tuple(centre - size / 2), tuple(centre + size / 2))
    rng = np.random.default_rng(0)
    points = rng.uniform(box[0], box[1], (PROBE_PARTICLES, 3))
    flux = np.full(PROBE_PARTICLES, PROBE_INTENSITY)
    flux[0] *= PROBE_FAINT
    flux[1] *= PROBE_DIM
    images, xy, otfs = [], [], []
    for camera in rig.cameras:
        rows, columns = camera.lens.sensor_size[1], camera.lens.sensor_size[0]
        image = rng.normal(PROBE_BACKGROUND, PROBE_NOISE, (rows, columns))
        images.append(draw_spots(image, camera.project(points), flux, PROBE_SIGMA, PROBE_SIGMA))
        xy.append(camera.project(points))
        otfs.append(
            OpticalTransferFunction.uniform(
                (rows, columns),
                PROBE_SIGMA,
                intensity=PROBE_INTENSITY,
                background=PROBE_BACKGROUND,
                noise=PROBE_NOISE,
            )
        )
    return rig.cameras, box, points, images, np.stack(xy), otfs


def _reconstructed() -> np.ndarray:
    """The probe's particles and intensities as IPR reconstructs them."""
    cameras, box, _, images, _, otfs = _probe_scene()
    found = reconstruct(
        images, cameras, otfs, box, settings=IPRSettings(outer_iterations=PROBE_ITERATIONS)
    )
    return np.concatenate([found.positions.ravel(), found.intensities])


def _measured_otf() -> np.ndarray:
    """σ_x of the probe's OTF measured per depth from its true particles."""
    _, _, points, images, xy, otfs = _probe_scene()
    refined = refine_otf(images, points, xy, otfs, depth_slabs=1, min_per_cell=1)
    return np.array([otf.sigma_x.ravel() for otf in refined])


def _defocus_law_probe() -> np.ndarray:
    """The defocus law's σ through the middle of images σ² = 0.4 + z² px² at z = ±1…±2."""
    depth = np.concatenate([np.linspace(-2.0, -1.0, 5), np.linspace(1.0, 2.0, 5)])
    return defocus_law(depth, np.sqrt(0.4 + depth**2), np.array([-0.5, 0.0, 0.5]))


def _wider(original):
    """The measured OTF with every σ :data:`WIDER` times the fitted one."""

    def refine(*args, **kwargs):
        return [
            replace(otf, sigma_x=WIDER * otf.sigma_x, sigma_y=WIDER * otf.sigma_y)
            for otf in original(*args, **kwargs)
        ]

    return refine


RECONSTRUCTION_MUTATIONS: tuple[Mutation, ...] = (
    Mutation(
        "ipr-shaking-off",
        "iterative particle reconstruction shakes no particle: every shaking pass, in the "
        "outer iterations and after them, returns at once",
        (
            Patch(
                "ptv.reconstruct.ipr:_shake",
                edited("if passes == 0 or state.n == 0:", "if True:"),
            ),
        ),
        ("ipr.reconstruction",),
        ("ipr",),
        _reconstructed,
    ),
    Mutation(
        "ipr-otf-ten-percent-wide",
        "the OTF measured per depth slab is 10 % wider than the fitted particle images "
        "(every σ × 1.1), and the reconstruction uses it",
        (Patch("ptv.reconstruct.otf_measure:refine_otf_pooled", _wider),),
        ("ipr.otf_measured",),
        ("ipr",),
        _measured_otf,
    ),
    Mutation(
        "ipr-ghost-threshold-doubled",
        "iterative particle reconstruction removes as ghosts the particles fainter than "
        "twice its intensity threshold (0.7 of a typical particle's light, not 0.35)",
        (
            Patch(
                "ptv.reconstruct.ipr:_prune",
                edited(
                    "bright = state.energy > s.intensity_threshold",
                    "bright = state.energy > 2 * s.intensity_threshold",
                ),
            ),
        ),
        ("ipr.reconstruction",),
        ("ipr",),
        _reconstructed,
    ),
    Mutation(
        "otf-defocus-law-unsquared",
        "the defocus law that fills a depth slab without isolated images gives σ² where σ "
        "belongs (the square root of the fitted σ² left out)",
        (
            Patch(
                "ptv.reconstruct.otf_measure:defocus_law",
                edited(
                    "np.where(value > 0, np.sqrt(np.maximum(value, 0.0)), np.nan)",
                    "np.where(value > 0, np.maximum(value, 0.0), np.nan)",
                ),
            ),
        ),
        ("ipr.defocus_law",),
        ("ipr",),
        _defocus_law_probe,
    ),
)
