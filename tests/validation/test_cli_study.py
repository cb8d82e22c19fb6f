"""``synptv study``: rows and curves written; bad input in one line."""

import json

from validation.cli import main


def test_plane_study_writes_rows_and_curves(tmp_path, capsys):
    assert main(["study", "planes", "--out", str(tmp_path), "--quiet"]) == 0
    rows = json.loads((tmp_path / "planes.json").read_text())
    assert [r["planes"] for r in rows] == [2, 3, 5, 7, 9, 13]
    assert rows[-1]["table1_ratio"] == 1.0 and rows[-1]["model_ratio"] == 1.0
    assert (tmp_path / "planes.png").stat().st_size > 10_000
    assert "curves to" in capsys.readouterr().out


def test_study_on_an_unknown_rig(tmp_path, capsys):
    assert main(["study", "planes", "--rig", "nope", "--out", str(tmp_path), "--quiet"]) == 2
    assert "unknown rig" in capsys.readouterr().err
