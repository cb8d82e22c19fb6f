"""The pipelines, from a dataset's detections (:mod:`ptv.detect.frames`) to links, tracks
and statistics.

- :mod:`ptv.pipeline.double_frame`: detections → matches → links → S2(r), ε, u′;
- :mod:`ptv.pipeline.time_resolved`: every frame of a time-resolved recording matched
  and linked into tracks;
- :mod:`ptv.pipeline.track_fit`: a recording's tracks fitted as ``synptv ptv --tracks``
  fits them, and their Lagrangian statistics;
- :mod:`ptv.pipeline.settings_file`: the settings of ``synptv ptv`` (:mod:`ptv.settings`)
  in one TOML file;
- :mod:`ptv.pipeline.results`: the results on disk (``results.h5``, and the JSON summary
  that :mod:`ptv.pipeline.summary` makes).
"""
