"""Names that become folder and file names: cameras, scenarios, calibration methods.

A name is 1 to 64 letters, digits, '.', '_' and '-', starting with a letter or digit, so
that no name can point elsewhere ("../x", "/tmp/x") or hide (".x"). The simulator, which
may not import ``ptv``, applies the same rule to the camera names of its rigs
(``simulator.rigs.is_file_name``); a test holds the two to the same answers.
"""

import re

_FILE_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,63}")

#: The rule, as error messages state it.
FILE_NAME_RULE = (
    "1 to 64 letters, digits, '.', '_' or '-', starting with a letter or digit (it names "
    "folders and files)"
)


def is_file_name(name: object) -> bool:
    """Whether ``name`` may be used as a folder or file name (:data:`FILE_NAME_RULE`)."""
    return isinstance(name, str) and _FILE_NAME.fullmatch(name) is not None


def check_file_name(name: object, where: str) -> str:
    """``name`` if it is a plain file name, else a ValueError naming ``where``."""
    if not is_file_name(name):
        raise ValueError(f"{where}: expected {FILE_NAME_RULE}, got {name!r}")
    return name
