"""Particle detection on camera images (no knowledge of any simulator).

- :mod:`ptv.detect.background`: robust background level and noise (median, MAD),
  globally or per tile; threshold = level + k · noise.
- :mod:`ptv.detect.locate`: local maxima above threshold, connected regions split
  between resolved maxima, sub-pixel centres (least-squares Gaussian refined by joint
  fits of pixel-integrated spots, 3-point Gaussian or threshold-subtracted centroid),
  blends of unresolved particles split by a model test, intensity, peak, size and
  flags; particle images larger than about 6 px, given their diameter, on sums of
  pixel blocks at their scale (:mod:`ptv.detect._blocks`).
- :mod:`ptv.detect.detections`: the :class:`Detections` result and its flags.
- :mod:`ptv.detect.peaklocking`: histogram of the fractional positions and a test of
  its uniformity (peak-locking diagnostic).
"""

from ptv.detect._image import check_image
from ptv.detect.background import BackgroundEstimate, estimate_background
from ptv.detect.detections import DetectionFlag, Detections
from ptv.detect.locate import detect_particles
from ptv.detect.peaklocking import FractionSums, PeakLocking, peak_locking

__all__ = [
    "BackgroundEstimate",
    "DetectionFlag",
    "Detections",
    "FractionSums",
    "PeakLocking",
    "check_image",
    "detect_particles",
    "estimate_background",
    "peak_locking",
]
