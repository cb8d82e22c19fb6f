"""The figures of runs, PTV results and calibrations, and the reports of a recording
and of a score (the report of a run: :mod:`validation.run.run_report`)."""
