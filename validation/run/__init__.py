"""``synptv run``: the scenario, the flow of a run, its dataset rendered (``synptv
render``), the stages of the virtual experiment, the reference rungs of the error budget,
the checks against truth and the report."""
