"""Executors: the same results in this process and on Dask workers, bounded work in
flight, bad options refused before any work."""

import time

import pytest

from validation.cli import main
from validation.workflow.parallel import (
    IN_FLIGHT,
    DaskExecutor,
    InProcess,
    check_parallel_options,
    dask_client,
    executor,
)

#: A task, scale·x + offset: a lambda, which Dask sends by value (worker processes cannot
#: import this test module).
affine = lambda x, *, scale, offset: scale * x + offset  # noqa: E731


def test_in_process_and_on_workers_give_the_same_results_by_index():
    items = list(range(12))
    shared = {"scale": 3, "offset": -1}
    here = dict(InProcess().map(affine, items, shared=shared))
    with dask_client(workers=2) as client:
        there = dict(DaskExecutor(client).map(affine, items, shared=shared))
    assert here == there == {i: 3 * i - 1 for i in items}


def test_items_are_drawn_a_few_per_worker_at_a_time():
    drawn = []

    def lazy():
        for i in range(20):
            drawn.append(i)
            yield i

    with dask_client(workers=2) as client:
        ex = DaskExecutor(client)
        results = ex.map(affine, lazy(), shared={"scale": 1, "offset": 0})
        first = next(results)
        assert len(drawn) <= IN_FLIGHT * ex.workers + 1
        assert sorted([first, *results]) == [(i, i) for i in range(20)]


@pytest.mark.parametrize(
    ("workers", "scheduler", "message"),
    [
        (0, None, "--workers must be an integer >= 1"),
        (2, "tcp://127.0.0.1:8786", "not both"),
        (None, "localhost", "host:port"),
    ],
)
def test_bad_options_are_refused(workers, scheduler, message):
    with pytest.raises(ValueError, match=message):
        check_parallel_options(workers, scheduler)


def test_one_worker_is_this_process():
    with executor(workers=1) as ex:
        assert isinstance(ex, InProcess)


def test_an_unreachable_scheduler_is_a_one_line_error_before_any_work(tmp_path, capsys):
    start = time.monotonic()
    argv = ["run", "--scheduler", "tcp://127.0.0.1:9", "--out", str(tmp_path / "x"), "--quiet"]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "cannot connect to a Dask scheduler" in err[0]
    assert not (tmp_path / "x").exists()
    assert time.monotonic() - start < 60


def test_zero_workers_is_refused_before_the_scenario_is_read(tmp_path, capsys):
    argv = ["run", "--workers", "0", "--scenario", "nope", "--out", str(tmp_path / "x")]
    assert main(argv) == 2
    assert "--workers must be an integer >= 1" in capsys.readouterr().err
    assert not (tmp_path / "x").exists()
