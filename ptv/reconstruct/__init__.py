"""Iterative particle reconstruction (IPR) on dense multi-camera images.

Modules (one job each): :mod:`~ptv.reconstruct.otf` (the particle-image model per camera
and image region), :mod:`~ptv.reconstruct.otf_measure` (its measurement on particle
images), :mod:`~ptv.reconstruct.dense_background` (background level of dense images),
:mod:`~ptv.reconstruct.projection` (projected and residual images),
:mod:`~ptv.reconstruct.peaks` (peaks of residual images),
:mod:`~ptv.reconstruct.triangulation` (candidates from the peaks of all cameras),
:mod:`~ptv.reconstruct.shake` (shaking particles against the residual),
:mod:`~ptv.reconstruct.mapping` (batched, timed camera calls and their derivatives),
and :mod:`~ptv.reconstruct.ipr` (the outer loop; its options,
:class:`ptv.settings.IPRSettings`, live with the stack's other settings).
Only the camera protocol of :mod:`ptv.camera_model` is used.
"""

from ptv.reconstruct.dense_background import BackgroundLevel, background_level
from ptv.reconstruct.ipr import IPRDiagnostics, Reconstruction, reconstruct
from ptv.reconstruct.mapping import grid_mappings
from ptv.reconstruct.otf import OpticalTransferFunction
from ptv.reconstruct.otf_measure import (
    TooFewIsolatedImages,
    defocus_law,
    measure_camera_otf,
    measure_otf,
    refine_otf,
    refine_otf_pooled,
)
from ptv.reconstruct.peaks import find_peaks
from ptv.reconstruct.projection import draw_spots, projected_image, residual_image
from ptv.settings import IPRSettings

__all__ = [
    "BackgroundLevel",
    "IPRDiagnostics",
    "IPRSettings",
    "OpticalTransferFunction",
    "Reconstruction",
    "TooFewIsolatedImages",
    "background_level",
    "defocus_law",
    "draw_spots",
    "find_peaks",
    "grid_mappings",
    "measure_camera_otf",
    "measure_otf",
    "projected_image",
    "reconstruct",
    "refine_otf",
    "refine_otf_pooled",
    "residual_image",
]
