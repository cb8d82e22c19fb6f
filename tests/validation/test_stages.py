"""Stages: built once per inputs, rebuilt when they change, never left half-written."""

import json

import pytest

from validation.workflow.stages import STAGE_FILE, run_stage, stage_key


class Builder:
    """A stage builder that writes ``value.txt`` and counts its calls."""

    def __init__(self, value: str, *, fail: bool = False):
        self.value = value
        self.fail = fail
        self.calls = 0

    def __call__(self, target):
        self.calls += 1
        target.mkdir()
        (target / "value.txt").write_text(self.value)
        if self.fail:
            raise RuntimeError("builder interrupted")
        (target / "done.txt").write_text("complete")


def leftovers(folder):
    """Hidden temporary folders beside a stage folder."""
    return sorted(p.name for p in folder.parent.glob(f".{folder.name}.partial-*"))


def test_identical_inputs_build_once_and_reuse(tmp_path):
    folder, build = tmp_path / "stage", Builder("a")
    first = run_stage(folder, {"n": 1, "dt": [1e-4, 2e-4]}, build, name="detect")
    again = run_stage(folder, {"dt": [1e-4, 2e-4], "n": 1}, build, name="detect")
    assert build.calls == 1
    assert not first.reused and again.reused
    assert first.folder == again.folder == folder and first.key == again.key
    assert (folder / "value.txt").read_text() == "a"
    record = json.loads((folder / STAGE_FILE).read_text())
    assert record["stage"] == "detect" and record["key"] == first.key
    assert leftovers(folder) == []


def test_different_inputs_rebuild(tmp_path):
    folder = tmp_path / "stage"
    old, new = Builder("old"), Builder("new")
    run_stage(folder, {"n": 1}, old, name="s")
    outcome = run_stage(folder, {"n": 2}, new, name="s")
    assert new.calls == 1 and not outcome.reused
    assert (folder / "value.txt").read_text() == "new"
    assert json.loads((folder / STAGE_FILE).read_text())["key"] == stage_key({"n": 2})
    assert run_stage(folder, {"n": 2}, new, name="s").reused and new.calls == 1


def test_a_failed_first_build_leaves_nothing_behind(tmp_path):
    folder = tmp_path / "out" / "stage"
    with pytest.raises(RuntimeError, match="interrupted"):
        run_stage(folder, {"n": 1}, Builder("x", fail=True), name="s")
    assert not folder.exists()
    assert leftovers(folder) == []
    build = Builder("x")
    assert not run_stage(folder, {"n": 1}, build, name="s").reused and build.calls == 1
    assert (folder / "done.txt").exists()


def test_a_failed_rebuild_leaves_the_earlier_folder_intact_and_reusable(tmp_path):
    folder, good = tmp_path / "stage", Builder("good")
    built = run_stage(folder, {"n": 1}, good, name="s")
    with pytest.raises(RuntimeError):
        run_stage(folder, {"n": 2}, Builder("bad", fail=True), name="s")
    assert (folder / "value.txt").read_text() == "good"
    assert (folder / "done.txt").exists()
    assert json.loads((folder / STAGE_FILE).read_text())["key"] == built.key
    assert leftovers(folder) == []
    assert run_stage(folder, {"n": 1}, good, name="s").reused and good.calls == 1


def test_a_temporary_folder_from_an_interrupted_process_is_removed_by_the_next_run(tmp_path):
    folder = tmp_path / "stage"
    stale = tmp_path / f".{folder.name}.partial-killed"
    (stale / folder.name).mkdir(parents=True)
    (stale / folder.name / "value.txt").write_text("half")
    run_stage(folder, {"n": 1}, Builder("a"), name="s")
    assert leftovers(folder) == []
    assert (folder / "value.txt").read_text() == "a"


@pytest.mark.parametrize("record", [None, "not json", '{"stage": "s"}'])
def test_a_folder_without_a_valid_record_is_rebuilt(tmp_path, record):
    folder = tmp_path / "stage"
    folder.mkdir()
    (folder / "stale.txt").write_text("from an interrupted run")
    if record is not None:
        (folder / STAGE_FILE).write_text(record)
    build = Builder("fresh")
    outcome = run_stage(folder, {"n": 1}, build, name="s")
    assert build.calls == 1 and not outcome.reused
    assert sorted(p.name for p in folder.iterdir()) == ["done.txt", STAGE_FILE, "value.txt"]


def test_stage_key_ignores_key_order_and_sees_every_value():
    inputs = {"seed": 3, "flow": {"preset": "lem-10hz", "modes": 200}, "dt": [1e-4, 2e-4]}
    reordered = {"dt": [1e-4, 2e-4], "flow": {"modes": 200, "preset": "lem-10hz"}, "seed": 3}
    assert stage_key(inputs) == stage_key(reordered)
    assert len(stage_key(inputs)) == 64 and int(stage_key(inputs), 16) >= 0
    for changed in (
        {**inputs, "seed": 4},
        {**inputs, "flow": {"preset": "lem-10hz", "modes": 201}},
        {**inputs, "dt": [2e-4, 1e-4]},
        {**inputs, "extra": None},
    ):
        assert stage_key(changed) != stage_key(inputs)


def test_stage_key_refuses_nan():
    with pytest.raises(ValueError):
        stage_key({"x": float("nan")})


class ChunkedBuilder:
    """A resumable builder: one file per chunk, skipping the chunks already there, that
    can be stopped after a given number of new chunks."""

    def __init__(self, chunks: int, *, stop_after: int | None = None):
        self.chunks = chunks
        self.stop_after = stop_after
        self.computed: list[int] = []

    def __call__(self, target):
        target.mkdir(exist_ok=True)
        for i in range(self.chunks):
            part = target / f"chunk-{i}.txt"
            if part.exists():
                continue
            if self.stop_after is not None and len(self.computed) == self.stop_after:
                raise KeyboardInterrupt
            part.write_text(str(i * i))
            self.computed.append(i)


def test_a_resumable_stage_goes_on_from_the_chunks_an_interruption_left(tmp_path):
    folder, inputs = tmp_path / "stage", {"n": 5}
    first = ChunkedBuilder(5, stop_after=2)
    with pytest.raises(KeyboardInterrupt):
        run_stage(folder, inputs, first, name="render", resume=True)
    kept = f".stage.partial-{stage_key(inputs)[:16]}"
    assert not folder.exists() and leftovers(folder) == [kept]
    second = ChunkedBuilder(5)
    outcome = run_stage(folder, inputs, second, name="render", resume=True)
    assert first.computed == [0, 1] and second.computed == [2, 3, 4]
    assert not outcome.reused and leftovers(folder) == []
    assert [(folder / f"chunk-{i}.txt").read_text() for i in range(5)] == ["0", "1", "4", "9", "16"]


def test_other_inputs_discard_what_an_interrupted_build_left(tmp_path):
    folder = tmp_path / "stage"
    with pytest.raises(KeyboardInterrupt):
        run_stage(folder, {"n": 5}, ChunkedBuilder(5, stop_after=2), name="render", resume=True)
    other = ChunkedBuilder(5)
    run_stage(folder, {"n": 6}, other, name="render", resume=True)
    assert other.computed == [0, 1, 2, 3, 4] and leftovers(folder) == []
