"""Stereo matching: which detections of several cameras image the same particle
(:mod:`ptv.matching.stereo`, docs/ptv.md §3)."""
