"""``synptv run``: the scenario, the stages of the virtual experiment, the reference
rungs of the error budget and the checks against truth."""
