"""Tracking: double-frame links at Δt and tracks through consecutive frames
(:mod:`ptv.tracking.linking`), tracks joined across a false point
(:mod:`ptv.tracking.stitching`), every frame of a time-resolved recording matched and
linked into tracks (:mod:`ptv.tracking.recording`), and tracks fitted for velocity and
acceleration (:mod:`ptv.tracking.fitting`); docs/ptv.md §4, §6, docs/lagrangian.md."""
