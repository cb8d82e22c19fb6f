"""Tracking: double-frame links at Δt and tracks through consecutive frames
(:mod:`ptv.tracking.linking`), tracks joined across a false point
(:mod:`ptv.tracking.stitching`) and tracks fitted for velocity and acceleration
(:mod:`ptv.tracking.fitting`); docs/ptv.md §4, §6, docs/lagrangian.md. A whole recording
is matched and tracked by :mod:`ptv.pipeline.time_resolved`."""
