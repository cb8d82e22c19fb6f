"""The radius a link of Δt_k is searched within, from the linking settings
(:class:`ptv.settings.PipelineSettings`): around X(t), or around the link's prediction
from the next smaller Δt."""

import math

from ptv.settings import PipelineSettings
from ptv.tracking.linking import search_radius

__all__ = ["link_radius", "predicted_radius", "radius_at"]


def link_radius(dt: float, settings: PipelineSettings) -> float:
    """Link search radius max_speed·Δt + 5·position_noise, m.

    Raises
    ------
    ValueError
        ``settings.max_speed`` is None (not yet measured:
        :func:`ptv.pipeline.resolve.resolve_settings`).
    """
    if settings.max_speed is None:
        raise ValueError("max_speed is not known yet: measure it with resolve_settings")
    return search_radius(
        dt, u_rms=settings.max_speed, sigma_b=settings.position_noise, k_v=1.0, k_b=5.0
    )


def predicted_radius(k: int, settings: PipelineSettings) -> float | None:
    """The radius around the predicted links at Δt_k.

    Parameters
    ----------
    k : int
        Index of Δt_k in the dataset's Δt order.
    settings : PipelineSettings
        Their ``predicted_radii``.

    Returns
    -------
    float or None
        The radius, m; None where Δt_k is linked around X(t) (the smallest Δt, or
        settings without predicted radii).
    """
    radii = settings.predicted_radii
    if radii is None or k >= len(radii) or math.isnan(radii[k]):
        return None
    return radii[k]


def radius_at(k: int, dt: float, settings: PipelineSettings) -> float:
    """The radius the links of Δt_k are searched within.

    Parameters
    ----------
    k : int
        Index of Δt_k in the dataset's Δt order.
    dt : float
        Δt_k, s.
    settings : PipelineSettings
        Their ``predicted_radii``, ``max_speed`` and ``position_noise``.

    Returns
    -------
    float
        Around the link's prediction (:func:`predicted_radius`) where the settings have
        one, else around X(t) (:func:`link_radius`), m.
    """
    predicted = predicted_radius(k, settings)
    return link_radius(dt, settings) if predicted is None else predicted
