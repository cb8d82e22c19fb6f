"""Figures and pictures written as PNG files: whole or not at all."""

import os
import tempfile
from collections.abc import Callable
from pathlib import Path

import cv2
import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from matplotlib.figure import Figure


def _write_atomically(path: Path, write: Callable[[str], None]) -> Path:
    """Call ``write`` on a temporary name beside ``path``, make the file readable by
    everyone (mkstemp makes it private; a figure is for sharing) and rename it."""
    handle, temporary = tempfile.mkstemp(suffix=".png", dir=path.parent, prefix=f".{path.name}.")
    os.close(handle)
    try:
        write(temporary)
        os.chmod(temporary, 0o644)
        os.replace(temporary, path)
    finally:
        if os.path.exists(temporary):
            os.remove(temporary)
    return path


def save_figure(figure: Figure, path: str | os.PathLike, *, dpi: int = 110) -> Path:
    """Write a figure as PNG atomically and close it."""
    try:
        return _write_atomically(
            Path(path), lambda name: figure.savefig(name, dpi=dpi, bbox_inches="tight")
        )
    finally:
        plt.close(figure)


def check_png_path(path: str | os.PathLike) -> Path:
    """``path`` as a Path, refused (ValueError, one line) unless it ends in ``.png`` and its
    folder exists: checked before the work that draws the picture."""
    path = Path(path)
    if path.suffix.lower() != ".png":
        raise ValueError(f"{str(path)!r}: a picture is written as PNG; the name must end in .png")
    if not path.parent.is_dir():
        raise ValueError(f"folder {str(path.parent)!r} for {path.name} does not exist")
    return path


def save_picture(rgb: np.ndarray, path: str | os.PathLike) -> Path:
    """Write an RGB picture, shape (H, W, 3), uint8, as PNG atomically.

    Raises
    ------
    ValueError
        A path refused by :func:`check_png_path`.
    """
    path = check_png_path(path)
    ok, encoded = cv2.imencode(".png", np.ascontiguousarray(rgb[:, :, ::-1]))
    if not ok:  # pragma: no cover (OpenCV failure)
        raise RuntimeError(f"OpenCV could not encode {path.name} as PNG")
    return _write_atomically(path, lambda name: Path(name).write_bytes(encoded.tobytes()))
