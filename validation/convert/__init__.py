"""``synptv convert``: another PTV code's output as the files ``synptv score`` reads.

A code run on an exported dataset (``synptv export``, docs/export.md) writes its 3-D
particles in its own units and frame numbers; this package turns them back into the
positions file of docs/score.md §1 (``dt,snapshot,frame,x,y,z`` and a ``track`` column
where the code linked frame a to frame b) or, for a time-resolved recording, the tracks
file of docs/score.md §11 (``track,frame,x,y,z``), in metres. Modules, one job each:

- :mod:`~validation.convert.points`: a code's points in its own frame numbers, and the
  dataset's frames they map to (the inverse of what the export wrote), the track ids
  and the CSV text;
- :mod:`~validation.convert.openptv`: OpenPTV's ``rt_is.<number>`` (and ``ptv_is``)
  files;
- :mod:`~validation.convert.myptv`: MyPTV's particles and trajectory files.

Every error is one line naming the file, the line and the field (``ValueError``).
"""
