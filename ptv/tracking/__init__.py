"""Tracking: double-frame links at Δt and tracks through consecutive frames
(:mod:`ptv.tracking.linking`), and every frame of a time-resolved recording matched and
linked into tracks (:mod:`ptv.tracking.recording`); docs/ptv.md §4, §6."""
