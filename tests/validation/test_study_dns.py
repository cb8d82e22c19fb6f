"""The dt study on a Navier–Stokes flow: every range, both binnings, resumed; refusals."""

import json

import numpy as np
import pytest

from validation.run.scenario import load_scenario, scenario_from_dict
from validation.studies.study import StudySettings, run_study


def _tiny_dns():
    """dns-ci on 32³ with 3 snapshots: a field in seconds."""
    settings = load_scenario("dns-ci").as_dict()
    settings["name"] = "dns-tiny"
    settings["flow"]["grid"] = 32
    settings["particles"].update(count=400, frames=3)
    settings["ptv"].update(r_min=1e-3, r_max=12e-3, plateau=[2e-3, 10e-3], n_boot=20, n_bins=8)
    return scenario_from_dict(settings)


@pytest.mark.filterwarnings("ignore::DeprecationWarning")  # dask's LocalCluster
def test_the_dt_study_of_a_dns_measures_both_binnings_at_every_range_and_resumes(tmp_path):
    scenario = _tiny_dns()
    files = run_study(
        "dt", scenario, tmp_path / "out", seeds=2, settings=StudySettings(), workers=1, quiet=True
    )
    table = json.loads(files.table.read_text())
    assert table["chain"] == "ideal"
    rows = table["points"]
    # 4 scales × 2 binnings × 2 noise levels (0 and σ) × 2 seeds
    assert len(rows) == 32
    assert {r["binning"] for r in rows} == {"start", "midpoint"}
    assert {r["noise_um"] for r in rows} == {0.0, 15.0}
    assert (tmp_path / "out" / "flow" / "field.h5").is_file()
    ranges = sorted({r["dt_max_over_tau_eta"] for r in rows})
    assert ranges == pytest.approx(np.array([0.5, 1, 2, 4]) * 0.21)
    again = run_study(
        "dt", scenario, tmp_path / "out", seeds=2, settings=StudySettings(), workers=1, quiet=True
    )
    assert again.computed == () and len(again.reused) == 2
    assert files.figure.stat().st_size > 0


@pytest.mark.parametrize(
    ("study", "chain", "message"),
    [
        ("noise", None, "draws kinematic simulation"),
        ("seeding", "ideal", "draws kinematic simulation"),
        ("dt", "rendered", "exact trajectories"),
    ],
)
def test_studies_a_dns_cannot_run_are_refused_before_any_work(tmp_path, study, chain, message):
    scenario = _tiny_dns()
    with pytest.raises(ValueError, match=message):
        run_study(study, scenario, tmp_path / "out", chain=chain, quiet=True)
    assert not (tmp_path / "out").exists()
