"""How well each plate image calibrated: the dots' reprojection error under a fitted
camera model, and the model-free plane fits whose residual is too large to trust."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ptv.calibration.grid_errors import TraverseDots
from ptv.calibration.model_free import ModelFreeCalibration
from ptv.camera_model import CameraModel

#: Largest plane-fit residual |T_j⁻¹(X, Y) − pixel| a plate image may leave, px: the
#: paper's own check of its cubic plane maps.
PLANE_RESIDUAL_LIMIT_PX = 2.0


def reprojection_rms(model: CameraModel, dots: TraverseDots) -> float:
    """RMS distance between the dots' pixels and their plate positions projected by
    ``model``, px (NaN when none projects).

    Parameters
    ----------
    model : CameraModel
        A fitted camera.
    dots : TraverseDots
        One plate image's dots: indices, pixels (N, 2) px, traverse reading Z_j m, and
        the plate's offsets when it was self-calibrated.
    """
    observation = dots.observation()
    world = np.column_stack(
        [observation.world_xy, np.full(len(observation.world_xy), observation.z)]
    )
    miss = np.linalg.norm(model.project(world) - observation.pixels, axis=1)
    miss = miss[np.isfinite(miss)]
    return float(np.sqrt(np.mean(miss**2))) if len(miss) else float("nan")


def large_plane_residual(
    camera: str,
    model: ModelFreeCalibration,
    fitted: Sequence[TraverseDots],
    images: Sequence[str],
) -> str | None:
    """A warning when a cubic plane fit T_j⁻¹ of ``camera`` misses a dot by more than
    :data:`PLANE_RESIDUAL_LIMIT_PX`, naming the worst dot and image and counting the
    other images above the limit; None when none is.

    Parameters
    ----------
    camera : str
        The camera's name, for the message.
    model : ModelFreeCalibration
        Its model-free calibration, one plane fit per entry of ``fitted``.
    fitted : sequence of TraverseDots
        The dots each plane was fitted on, in order.
    images : sequence of str
        The name of each fitted plate image, in order.
    """
    worst = [float(plane.residual_px.max()) for plane in model.planes]
    above = [k for k, residual in enumerate(worst) if residual > PLANE_RESIDUAL_LIMIT_PX]
    if not above:
        return None
    k = max(above, key=worst.__getitem__)
    i, j = (int(v) for v in fitted[k].indices[int(np.argmax(model.planes[k].residual_px))])
    others = f"; {len(above) - 1} other image(s) above it" if len(above) > 1 else ""
    return (
        f"{camera}: the cubic plane fit of {images[k]} misses dot ({i}, {j}) by "
        f"{worst[k]:.1f} px, more than {PLANE_RESIDUAL_LIMIT_PX:g} px{others} (a dot "
        "indexed wrongly, two dots blended, a plate that is not flat, or a distortion a "
        "cubic cannot follow: see the images' reprojection RMS)"
    )
