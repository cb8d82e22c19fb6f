"""Wall and CPU time of a run's stages: what a build took, kept beside its output.

The CPU time is that of this process and of every process it started that still runs or
that it waited for (the local Dask workers and their nannies), so that on two workers a
stage that keeps both busy shows about twice its wall time. Workers on another machine
(``--scheduler``) are not seen: their CPU time is missing from the sum.
"""

import time
from dataclasses import dataclass

import psutil

__all__ = ["StageTime", "Stopwatch", "cpu_seconds", "this_run_seconds"]


@dataclass(frozen=True)
class StageTime:
    """What building a stage took.

    Attributes
    ----------
    wall_s : float
        Wall-clock time of the build, s.
    cpu_s : float
        CPU time of the build, user and system, of this process and its local workers, s.
    reused : bool
        This run reused the stage, built earlier: the times are those of that build.
    """

    wall_s: float
    cpu_s: float
    reused: bool = False

    def as_dict(self) -> dict:
        """JSON-able: ``wall_s``, ``cpu_s`` (rounded to 0.01 s) and ``reused``."""
        wall, cpu = round(self.wall_s, 2), round(self.cpu_s, 2)
        return {"wall_s": wall, "cpu_s": cpu, "reused": self.reused}


def cpu_seconds() -> float:
    """User and system CPU time of this process, of the children it waited for and of
    its live descendants, s."""
    me = psutil.Process()
    own = me.cpu_times()
    total = own.user + own.system + own.children_user + own.children_system
    for child in me.children(recursive=True):
        try:
            times = child.cpu_times()
        except (psutil.NoSuchProcess, psutil.AccessDenied):
            continue  # it ended between the listing and the reading
        total += times.user + times.system
    return total


class Stopwatch:
    """Wall and CPU time of a ``with`` block: ``watch.time`` once it is left.

    Examples
    --------
    >>> from validation.workflow.clock import Stopwatch
    >>> with Stopwatch() as watch:
    ...     total = sum(i * i for i in range(10_000))
    >>> watch.time.wall_s >= 0 and watch.time.cpu_s >= 0
    True
    """

    def __enter__(self) -> "Stopwatch":
        self._wall, self._cpu = time.perf_counter(), cpu_seconds()
        self.time: StageTime | None = None
        return self

    def __exit__(self, *exc) -> None:
        # A worker that ended unwaited inside the block takes its CPU time with it.
        cpu = max(0.0, cpu_seconds() - self._cpu)
        self.time = StageTime(time.perf_counter() - self._wall, cpu)


def this_run_seconds(times: dict[str, StageTime]) -> dict[str, float]:
    """Wall seconds each stage of ``times`` took in this run: 0 for a reused one."""
    return {name: 0.0 if t.reused else t.wall_s for name, t in times.items()}
