"""``synptv score``: any PTV code's 3-D positions and tracks scored against a rendered
dataset's truth.

Modules, one job each: :mod:`~validation.score.positions` reads and checks a positions
file; :mod:`~validation.score.reference` pairs the positions with the reference
particles one-to-one (:mod:`validation.truth.matching`, as ``synptv run`` scores its
matching); :mod:`~validation.score.scores` gives yield, ghosts, position errors and the
links of tracks. For time-resolved recordings, :mod:`~validation.score.track_file` reads
a tracks CSV file and :mod:`~validation.score.trajectories` scores the tracks against the
true trajectories. A check's tolerance from its false-alarm rate
(:mod:`~validation.score.tolerances`) and the noise that c2 should show
(:mod:`~validation.score.noise_prediction`) serve ``synptv score`` and ``synptv run``
alike.

Above this package: :mod:`validation.run.score_statistics` (S2 and ε through synptv's
multi-Δt statistics against the truth), :mod:`validation.report.score_report` (the
report) and :mod:`validation.commands.score` (the command line).
"""
