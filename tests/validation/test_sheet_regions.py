"""The whole sheet's yield by region, against counts made by hand."""

import json

import numpy as np
import pytest

from ptv.settings import PipelineSettings
from simulator.rigs import load_rig
from validation.report.sheet_region_table import sheet_region_table
from validation.truth.matching import score_matching
from validation.truth.sheet_regions import SheetRegions, region_counts, region_table
from validation.truth.truth_file import TruthFile, TruthRun, TruthWriter

#: A 100 × 100 × 10 mm sheet, a plate as wide over a traverse of ±6 mm, three cameras.
REGIONS = SheetRegions(
    sheet=((-0.05, -0.05, -0.005), (0.05, 0.05, 0.005)),
    calibrated=((-0.05, -0.05, -0.006), (0.05, 0.05, 0.006)),
    n_cameras=3,
)
#: Particles (m), how many cameras image each, and which were found.
POSITIONS = np.array(
    [
        [0.0, 0.0, 0.0],  # the core: found
        [0.01, 0.0, 0.0047],  # the dim wing, 4.7 mm deep: lost
        [0.0505, 0.0, -0.001],  # beyond the X edge, off the plate: lost
        [0.049, 0.02, -0.0052],  # beyond the sheet's face, 1 mm inside its X edge: found
        [0.0, 0.01, 0.003],  # imaged by two cameras only: found
        [0.0, -0.01, 0.001],  # imaged by one camera
    ]
)
IMAGING = np.array([3, 3, 3, 3, 2, 1])
FOUND = np.array([True, False, False, True, True, False])


def test_the_table_counts_each_region_as_by_hand():
    rows = region_table(REGIONS, region_counts(REGIONS, POSITIONS, IMAGING, FOUND))
    table = {(r["group"], r["region"]): (r["particles"], r["found"], r["loss"]) for r in rows}
    # Particles 0-3 are imaged by all three cameras (the sheet yield's), 1 and 2 are lost.
    assert table == {
        ("sheet", "whole sheet"): (4, 2, 0.5),
        ("depth |Z − Z₀|", "0 to 2 mm"): (2, 1, 0.25),
        ("depth |Z − Z₀|", "2 to 4 mm"): (0, 0, 0.0),
        ("depth |Z − Z₀|", "4 to 4.5 mm"): (0, 0, 0.0),
        ("depth |Z − Z₀|", "4.5 to 5 mm"): (1, 0, 0.25),
        ("depth |Z − Z₀|", "beyond 5 mm (outside the sheet)"): (1, 1, 0.0),
        ("X, Y outline", "more than 2 mm inside the edges"): (2, 1, 0.25),
        ("X, Y outline", "within 2 mm inside the edges"): (1, 1, 0.0),
        ("X, Y outline", "beyond the edges"): (1, 0, 0.25),
        ("calibrated volume", "inside the plate's dots × traverse"): (3, 2, 0.25),
        ("calibrated volume", "outside"): (1, 0, 0.25),
        ("cameras imaging it", "2 of 3 (not in the sheet yield)"): (1, 1, None),
    }
    yields = {r["region"]: r["yield"] for r in rows}
    assert yields["whole sheet"] == 0.5 and yields["2 to 4 mm"] is None


def test_two_cameras_have_no_rows_outside_the_sheet_yield():
    two = SheetRegions(REGIONS.sheet, REGIONS.calibrated, n_cameras=2)
    rows = region_table(two, region_counts(two, POSITIONS, np.minimum(IMAGING, 2), FOUND))
    assert [r["group"] for r in rows].count("cameras imaging it") == 0
    assert rows[0]["particles"] == 5  # every particle imaged by both


def test_run_scores_the_regions_of_the_frames_it_scores():
    """Two frames of the particles above (the second shifted 1 mm in Y), each measured
    where its particles are found, 20 µm off (within the 0.1 mm voxel): the whole-sheet
    row is the sheet yield, and every partition loses what the sheet loses."""
    shift = np.array([0.0, 1e-3, 0.0])
    particles = np.stack([POSITIONS, POSITIONS + shift])
    visible = {
        name: np.stack([IMAGING > c, IMAGING > c])[:, None].repeat(2, axis=1)
        for c, name in enumerate(("c0", "c1", "c2"))
    }
    truth = TruthRun(
        dt=1e-3,
        positions=particles[:, None].repeat(2, axis=1),
        velocity=np.zeros((2, len(POSITIONS), 3)),
        xy={name: np.zeros((2, 2, len(POSITIONS), 2)) for name in visible},
        visible=visible,
    )
    points = [p[FOUND] + 2e-5 for p in particles]
    quality = score_matching(
        points, truth, list(visible), PipelineSettings(), voxel=1e-4, regions=REGIONS
    ).as_dict()
    rows = quality["sheet_regions"]
    assert (rows[0]["particles"], rows[0]["found"]) == (8, 4)
    assert rows[0]["yield"] == quality["sheet_yield"] == 0.5
    for group in ("depth |Z − Z₀|", "X, Y outline", "calibrated volume"):
        losses = [r["loss"] for r in rows if r["group"] == group]
        assert sum(losses) == pytest.approx(1 - quality["sheet_yield"], abs=1e-12)


def test_the_report_shows_every_scored_measurement_beside_the_regions():
    rows = region_table(REGIONS, region_counts(REGIONS, POSITIONS, IMAGING, FOUND))
    results = {"matching": {"model-free": {"sheet_regions": rows}, "old": {"yield": 1.0}}}
    page = "".join(sheet_region_table(results))
    assert "<th>model-free: yield (loss)</th>" in page and "old" not in page
    assert "<td>whole sheet</td><td>4</td><td>0.5 (50 %)</td>" in page
    assert "<td>2 of 3 (not in the sheet yield)</td><td>1</td><td>1</td>" in page
    assert sheet_region_table({"matching": {"old": {"yield": 1.0}}}) == []


def test_the_regions_of_a_dataset_are_its_rigs_sheet_and_its_plates_true_dots(tmp_path):
    rig = load_rig("box-3cam")  # a 100 × 100 × 10 mm sheet, three cameras
    writer = TruthWriter(
        tmp_path / "truth.h5",
        header=lambda f: f.attrs.__setitem__("rig", json.dumps(rig.spec)),
        cameras=rig.camera_names,
        planes=2,
        chunks=[(0, 1)],
        frames=1,
        shared_first_frame=True,
    )
    dots = np.array(  # two dots at each of two traverse positions, m
        [
            [[-0.05, -0.05, -0.001], [0.05, 0.049, -0.001]],
            [[-0.0501, -0.05, 0.001], [0.05, 0.05, 0.0012]],
        ]
    )
    plate = {
        "z_nominal": [-0.001, 0.001],
        "z_actual": [-0.001, 0.0011],
        "dots_world": dots,
        "dot_indices": [[0, 0], [1, 1]],
    }
    writer.write_plate(0, 0, np.zeros((2, 2)), np.zeros((2, 2)), np.ones(2, bool), plate)
    assert SheetRegions.of_dataset(TruthFile(tmp_path)) == SheetRegions(
        sheet=((-0.05, -0.05, -0.005), (0.05, 0.05, 0.005)),
        calibrated=((-0.0501, -0.05, -0.001), (0.05, 0.05, 0.0012)),
        n_cameras=3,
    )
