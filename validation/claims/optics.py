"""The optics claims: the simulated cameras refract and focus as the rig file says.

The calibration claims cannot see a wrong refractive index or a dropped sensor tilt in
the simulator: the dots, the true cameras of the noise floor and the truth all come
from the same cameras. ``optics.snell`` follows each camera's ray of every dot image
back through its windows in plain NumPy (:mod:`validation.truth.refraction`) and
measures how far it passes from the dot; ``optics.sheet_in_focus`` measures the
defocus blur of the sheet's plane on every Scheimpflug camera against the diffraction
spot.
"""

import numpy as np

from simulator.optics.scheimpflug import defocus_blur
from validation.claims.base import Claim, ClaimResult, result
from validation.claims.context import RIGS, ClaimContext
from validation.truth.refraction import snell_miss, stated_indices

#: Largest distance of a dot from its recomputed ray, m: the simulator solves the
#: refraction to 1e-12 rad and inverts the lens to 1e-12 (1e-12 m over the ≈ 1.2 m
#: path), and the plain-NumPy trace adds rounding of the same order; an index 1e-4 off
#: moves the rays by ≈ 0.15 µm.
MISS_LIMIT = 1e-9
#: Wavelength of the light sheet, m (frequency-doubled Nd:YAG).
WAVELENGTH = 532e-9


def _sheet_dots(ctx: ClaimContext) -> np.ndarray:
    """The dot centres of the traverse plane nearest Z = 0 (the sheet's mid-plane), m."""
    nearest = int(np.argmin([abs(pose.z_nominal) for pose in ctx.plate.poses]))
    return ctx.plate.dot_centres(nearest)


def _in_focus(claim: Claim, ctx: ClaimContext) -> ClaimResult:
    """Defocus blur of the sheet's dots over the diffraction spot, Scheimpflug cameras."""
    dots = _sheet_dots(ctx)
    worst, spots = 0.0, []
    for name in RIGS:
        rig = ctx.rig(name)
        for camera, spec in zip(rig.cameras, rig.spec["cameras"], strict=True):
            if not spec["scheimpflug"]:
                continue
            lens = camera.lens
            magnification = lens.image_distance / lens.focus_distance
            spot = 2.44 * WAVELENGTH * lens.f_number * (1 + magnification) / lens.pixel_pitch
            seen = np.isfinite(camera.project(dots)).all(axis=1)
            worst = max(worst, float(np.max(defocus_blur(camera, dots[seen]))) / spot)
            spots.append(spot)
    return result(
        claim,
        worst,
        f"blur / diffraction spot ≤ 1 on every Scheimpflug camera of {', '.join(RIGS)} "
        f"(spot 2.44λN(1 + M) = {min(spots):.2f}–{max(spots):.2f} px at λ = "
        f"{WAVELENGTH * 1e9:g} nm: a sharper focus would not show)",
        worst <= 1,
    )


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
    Claim(
        "optics.sheet_in_focus",
        "§2 (Scheimpflug mounts)",
        "on Scheimpflug mounts the whole oblique sheet is in focus",
        _in_focus,
    ),
)
