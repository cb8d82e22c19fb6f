"""The sweep runner: each point computed once, saved atomically, reused only when unchanged."""

import json
import uuid
from contextlib import contextmanager
from importlib.metadata import version
from pathlib import Path

import numpy as np
import pytest
from distributed import Client, LocalCluster

from validation.studies.runner import Sweep, SweepPoint, run_sweep, seed_sequence
from validation.workflow.parallel import dask_client


def square_task(settings: dict, options: dict, point: dict) -> dict:
    """Leaves one marker file per execution, so the test can count them."""
    (Path(options["marks"]) / f"{point['x']}-{uuid.uuid4().hex}").touch()
    return {"rows": [{"x": point["x"], "y": point["x"] ** 2 * options["scale"], "nan": np.nan}]}


@pytest.fixture(scope="module")
def cluster():
    with LocalCluster(
        n_workers=2, threads_per_worker=1, processes=False, dashboard_address=":0"
    ) as local:
        yield local


@pytest.fixture
def connect(cluster):
    calls = []

    @contextmanager
    def open_client(pending: int):
        calls.append(pending)
        with Client(cluster) as client:
            yield client

    open_client.calls = calls
    return open_client


def sweep(marks: Path, *, scale: float = 1.0, n: int = 5) -> Sweep:
    return Sweep(
        "square",
        square_task,
        {"name": "test", "seed": 0},
        {"marks": str(marks), "scale": scale},
        tuple(SweepPoint(f"x-{x}", {"x": x}) for x in range(n)),
    )


def executions(marks: Path) -> list[int]:
    return sorted(int(p.name.split("-")[0]) for p in marks.iterdir())


def test_an_interrupted_sweep_resumes_and_computes_each_point_once(tmp_path, connect):
    marks, points = tmp_path / "marks", tmp_path / "points"
    marks.mkdir()
    saved = []

    def stop(point_id):
        saved.append(point_id)
        if len(saved) == 2:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_sweep(sweep(marks), points, connect, on_saved=stop)
    assert sorted(p.stem for p in points.glob("*.json")) == sorted(saved)

    done = []
    outcome = run_sweep(sweep(marks), points, connect, progress=lambda d, t: done.append((d, t)))
    assert set(outcome.reused) == set(saved) and len(outcome.computed) == 3
    assert connect.calls == [5, 3]  # the client is asked for the missing points only
    assert done[0] == (2, 5) and done[-1] == (5, 5)
    run_count = {x: executions(marks).count(x) for x in range(5)}
    finished_first = {int(i.split("-")[1]) for i in saved}
    for x, count in run_count.items():
        # a point stopped in flight may have run once before the interrupt, never twice after
        assert count == 1 or (count == 2 and x not in finished_first)
    assert [r["rows"][0]["y"] for r in outcome.results.values()] == [0, 1, 4, 9, 16]
    assert outcome.results["x-3"]["rows"][0]["nan"] is None  # NaN saved as null

    before = len(executions(marks))
    again = run_sweep(sweep(marks), points, connect)
    assert again.computed == () and len(again.reused) == 5
    assert len(executions(marks)) == before and connect.calls == [5, 3]


def test_points_computed_from_other_inputs_or_unreadable_are_recomputed(tmp_path, connect):
    marks, points = tmp_path / "marks", tmp_path / "points"
    marks.mkdir()
    run_sweep(sweep(marks, n=3), points, connect)
    record = json.loads((points / "x-1.json").read_text())
    assert record["inputs"] == {
        "synptv": version("synptv"),
        "study": "square",
        "scenario": "test",
        "settings": {"name": "test", "seed": 0},
        "options": {"marks": str(marks), "scale": 1.0},
        "point": {"x": 1},
    }
    (points / "x-2.json").write_text("{truncated")
    outcome = run_sweep(sweep(marks, n=3), points, connect)
    assert outcome.computed == ("x-2",)
    outcome = run_sweep(sweep(marks, scale=2.0, n=3), points, connect)
    assert len(outcome.computed) == 3
    assert outcome.results["x-2"]["rows"][0]["y"] == 8.0
    assert executions(marks) == [0, 0, 1, 1, 2, 2, 2]


def test_seeds_depend_on_the_keys_only():
    a = seed_sequence(3, "noise", {"noise_um": 5.0, "k": 1})
    b = seed_sequence(3, "noise", {"k": 1, "noise_um": 5.0})
    assert a.generate_state(4).tolist() == b.generate_state(4).tolist()
    for other in (seed_sequence(4, "noise", {"noise_um": 5.0, "k": 1}), seed_sequence(3, "dt")):
        assert other.generate_state(4).tolist() != a.generate_state(4).tolist()


def test_workers_and_scheduler_exclude_each_other():
    with pytest.raises(ValueError, match="not both"), dask_client(workers=2, scheduler="x"):
        pass
