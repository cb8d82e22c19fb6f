"""Stereo matching: which detections of several cameras image the same particle
(:mod:`ptv.matching.stereo`), and the tolerance they are matched with
(:mod:`ptv.matching.tolerance`); docs/ptv.md §3."""
