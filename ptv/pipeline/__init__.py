"""The double-frame pipeline, from detections to links and statistics.

- :mod:`ptv.pipeline.frames`: the detections of a dataset, frame by frame (detected
  from its images or read from a detection store);
- :mod:`ptv.pipeline.double_frame`: detections → matches → links → S2(r), ε, u′;
- :mod:`ptv.pipeline.settings`: every option of ``synptv ptv`` in one TOML file;
- :mod:`ptv.pipeline.results`: the results on disk (``results.h5``, and the JSON summary
  that :mod:`ptv.pipeline.summary` makes).
"""
