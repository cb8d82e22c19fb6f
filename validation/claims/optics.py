"""The optics claim: the simulator refracts by Snell's law with the rig's indices.

The calibration claims cannot see a wrong refractive index in the simulator: the dots,
the true cameras of the noise floor and the truth all come from the same cameras. This
claim follows each camera's ray of every dot image back through its windows in plain
NumPy (:mod:`validation.truth.refraction`) and measures how far it passes from the dot.
"""

import numpy as np

from validation.claims.base import Claim, ClaimResult, result
from validation.claims.context import RIGS, ClaimContext
from validation.truth.refraction import snell_miss, stated_indices

#: Largest distance of a dot from its recomputed ray, m: the simulator solves the
#: refraction to 1e-12 rad and inverts the lens to 1e-12 (1e-12 m over the ≈ 1.2 m
#: path), and the plain-NumPy trace adds rounding of the same order; an index 1e-4 off
#: moves the rays by ≈ 0.15 µm.
MISS_LIMIT = 1e-9


def _snell(claim: Claim, ctx: ClaimContext) -> ClaimResult:
    points = np.concatenate([ctx.plate.dot_centres(j) for j in range(len(ctx.plate.poses))])
    worst, rays = 0.0, 0
    for name in RIGS:
        rig = ctx.rig(name)
        for camera, spec in zip(rig.cameras, rig.spec["cameras"], strict=True):
            pixels = camera.project(points)
            seen = np.isfinite(pixels).all(axis=1)
            stack = camera.interfaces
            planes = (np.zeros(3), np.empty(0)) if stack is None else (stack.normal, stack.offsets)
            miss = snell_miss(
                camera.center,
                camera.pixel_directions(pixels[seen]),
                *planes,
                stated_indices(spec, rig.spec.get("tank")),
                points[seen],
            )
            worst, rays = max(worst, float(miss.max())), rays + int(seen.sum())
    return result(
        claim,
        worst * 1e6,
        f"max distance of a dot from its ray ≤ {MISS_LIMIT * 1e6:g} µm over {rays} rays of "
        f"{', '.join(RIGS)} (Newton and lens inversion to 1e-12; an index 1e-4 off: ≈ 0.15 µm)",
        worst <= MISS_LIMIT,
    )


OPTICS_CLAIMS: tuple[Claim, ...] = (
    Claim(
        "optics.snell",
        "§2 (the tank's windows; docs/optics.md §4)",
        "the simulated cameras refract by Snell's law with the indices the rig states",
        _snell,
    ),
)
