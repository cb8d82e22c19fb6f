"""Every rung of a run compared with the truth: the input of its checks and report.

For each rung of the error budget (:mod:`validation.run.experiment`), from the files its
stage wrote: c1 against the sample truth of the pairs it used, ε and u′ against the
exact trajectories of the same snapshots (paired), c2 against the noise its particles
had (:func:`validation.run.checks.compare_variant`).
"""

import json
from dataclasses import dataclass
from pathlib import Path

from validation.run.checks import compare_variant
from validation.run.scenario import Scenario, pipeline_settings
from validation.score.noise_prediction import predicted_noise
from validation.score.tolerances import float_array


def _read(path: Path) -> dict:
    return json.loads(path.read_text())


@dataclass(frozen=True, eq=False)
class RungComparisons:
    """Every rung of a run compared with the truth (:func:`compare_rungs`).

    Attributes
    ----------
    summaries, populations, matching : dict of str to dict
        Per rung, its ``summary.json``, ``population.json`` (None where the rung has
        none) and ``matching.json`` (only the rungs that match).
    comparisons : dict of str to dict
        Per rung, :func:`validation.run.checks.compare_variant`.
    noise : dict of str to NoisePrediction
        The noise terms each rung's c2 is compared with (``detection``: the detection
        rung's).
    noise_source : dict of str to str
        Whose particles' noise each prediction is.
    check_range : (float, float)
        r range of the c1 and c2 checks, m.
    noise_free : (ndarray (B,), ndarray (B,))
        c2 of the exact trajectories and its standard error, m².
    """

    summaries: dict
    populations: dict
    matching: dict
    comparisons: dict
    noise: dict
    noise_source: dict
    check_range: tuple[float, float]
    noise_free: tuple


def compare_rungs(
    scenario: Scenario, truth: dict, detection: dict, folders: dict[str, Path]
) -> RungComparisons:
    """Compare each rung's statistics with the truth: its c1 with the sample truth of
    its pairs, its ε and u′ with the exact trajectories' (paired), its c2 with the noise
    its particles had.

    Parameters
    ----------
    scenario : Scenario
        The run's scenario (its checks' r range, analysis volume and bins).
    truth : dict
        ``truth.json``.
    detection : dict
        The detection rung's ``detection.json``.
    folders : dict of str to Path
        Every rung's folder, ``exact`` and ``detection`` among them.

    Returns
    -------
    RungComparisons
        Per rung: its summary, its comparison with the truth
        (:func:`validation.run.checks.compare_variant`), its matching against the
        truth-paired matches and its population.json where it has one.
    """
    settings = pipeline_settings(scenario).statistics
    p = truth["parameters"]
    check_range = (
        scenario.checks.c1_r_min_eta * p["eta"],
        scenario.checks.c1_r_max_l_int * p["L_int"],
    )
    box = scenario.ptv.analysis_size
    noise = {"detection": predicted_noise(detection, settings.bins, box)}
    noise_source = {"detection": "detection"}  # whose particles' noise each prediction is
    summaries, comparisons, matching, populations = {}, {}, {}, {}
    # The fit's c2 on the exact positions: the flow's terms beyond Δt², in every rung's c2.
    exact = _read(folders["exact"] / "summary.json")
    exact_fit = exact["structure_function"]
    noise_free = (float_array(exact_fit["noise"]), float_array(exact_fit["se_noise"]))
    for variant, folder in folders.items():
        summary = _read(folder / "summary.json")
        summary.pop("dataset", None)
        summary["calibration"] = variant
        summaries[variant] = summary
        population = folder / "population.json"
        populations[variant] = _read(population) if population.is_file() else None
        # c2 is predicted from the noise of the very particles this S2 used (the
        # trajectory test drops the noisiest), else from the detection rung's.
        measured = populations[variant] is not None and all(
            v is not None for row in populations[variant]["displacement_noise_m"] for v in row
        )
        noise[variant] = (
            predicted_noise(populations[variant], settings.bins, box)
            if measured
            else noise["detection"]
        )
        noise_source[variant] = variant if measured else "detection"
        comparisons[variant] = compare_variant(
            summary,
            truth,
            check_range=check_range,
            noise=noise[variant],
            population=populations[variant],
            noise_free_c2=None if variant == "exact" else noise_free,
            exact=None if variant == "exact" else exact,
        )
        if (folder / "matching.json").is_file():
            matching[variant] = _read(folder / "matching.json")
    return RungComparisons(
        summaries,
        populations,
        matching,
        comparisons,
        noise,
        noise_source,
        check_range,
        noise_free,
    )
