"""The detection rung's record: ``detection.json`` (the truth-paired detections' errors,
yield, noise and peak locking) and the peak-locking figure."""

import json
from pathlib import Path

import numpy as np

from ptv.detect.peaklocking import peak_locking
from validation.report.png import save_figure
from validation.report.run_figures import peak_locking_figure


def save_detection(quality, folder: Path, label: str) -> None:
    """detection.json and the fractional-position histograms (peak-locking diagnostic),
    the figure titled ``label``."""
    locking = {name: peak_locking(sums) for name, sums in quality.fractions.items()}
    record = {
            "cameras": list(quality.cameras),
            "rms_error_px": quality.rms_error_px.tolist(),
            "found": quality.found.tolist(),
            "spurious": quality.spurious.tolist(),
            "position_noise_m": quality.position_noise.tolist(),
            "dt": quality.dt.tolist(),
            "displacement_noise_m": quality.displacement_noise.tolist(),
            "pair_noise_m2": [
                [None if not np.isfinite(v) else float(v) for v in row]
                for row in quality.pair_noise
            ],
            "peak_locking": {
                name: {
                    "amplitude_px": pl.amplitude.tolist(),
                    "p_chi2": pl.p_chi2.tolist(),
                    "locked": pl.locked(),
                    "counts": pl.counts.tolist(),
                    "edges": pl.edges.tolist(),
                }
                for name, pl in locking.items()
            },
        }
    text = json.dumps(record, indent=2, allow_nan=False) + "\n"
    (folder / "detection.json").write_text(text)
    save_figure(peak_locking_figure(locking, label=label), folder / "peak_locking.png")
