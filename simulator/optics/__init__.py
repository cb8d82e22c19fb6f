"""The physical camera: lens, tilted sensor, flat refractive windows, Scheimpflug focus.

Modules (one job each): ``rays`` (ray bundles), ``lens`` (pinhole + Brown–Conrady +
tilted sensor), ``interfaces`` (flat stacks, vector Snell, back-projection),
``forward`` (Newton forward refraction), ``camera`` (pose + lens + stack: the
``pixel_to_ray`` / ``project`` protocol), ``placement`` (look-at constructor with a
window), ``scheimpflug`` (thin-lens focus, sensor tilt, defocus blur).
"""

from simulator.optics.camera import Camera
from simulator.optics.interfaces import FlatInterfaces, flat_window
from simulator.optics.lens import Lens
from simulator.optics.placement import WindowSpec, look_at_camera
from simulator.optics.rays import Rays
from simulator.optics.scheimpflug import (
    SheetFocus,
    defocus_blur,
    focus_on_plane,
    scheimpflug_focus,
)

__all__ = [
    "Camera",
    "FlatInterfaces",
    "Lens",
    "Rays",
    "SheetFocus",
    "WindowSpec",
    "defocus_blur",
    "flat_window",
    "focus_on_plane",
    "look_at_camera",
    "scheimpflug_focus",
]
