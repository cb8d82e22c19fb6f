"""The error a dataset that cannot be processed raises (its message names file and field)."""


class DatasetError(ValueError):
    """A dataset folder that cannot be processed (the message names file and value)."""
