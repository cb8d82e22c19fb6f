"""The report of a run and the figures of runs, PTV results and calibrations."""
