"""A time-resolved recording cut into the frame pairs of the multi-Δt method.

A high-speed camera records frames n = 0, 1, 2, … at a constant frame rate f, stored
under a pattern with the frame number (``seq/{camera}/{n:06d}.tif``). The multi-Δt
method wants frame pairs at several separations: with steps s_k (in frames),
Δt_k = s_k / f, and snapshot m pairs frame a = first + m·stride with frame b = a + s_k.
Every Δt starts snapshot m from the same frame a (a shared first frame), so the
statistics follow the same particles over every Δt (docs/statistics.md). Snapshots are
the frame pairs that fit in first … last for the largest step; the stride defaults to
the largest step, so that consecutive snapshots share at most one frame.

Tracking (``synptv ptv --tracks``) uses every frame of the recording instead, first …
last in steps of one frame (:meth:`TimeResolved.frame_numbers`).
"""

from dataclasses import dataclass

import numpy as np

__all__ = ["TimeResolved"]


@dataclass(frozen=True)
class TimeResolved:
    """How a frame-numbered recording maps to (Δt index k, snapshot m, frame a|b).

    Attributes
    ----------
    frame_rate : float
        Frames per second, Hz, > 0.
    images : str
        File pattern with ``{camera}`` and ``{n}`` (the frame number), relative to the
        dataset folder.
    steps : tuple of int
        Frame separation of each Δt, frames, distinct, >= 1.
    first, last : int
        First frame used and last frame recorded.
    stride : int
        Frames between the first frames of consecutive snapshots, >= 1.
    """

    frame_rate: float
    images: str
    steps: tuple[int, ...]
    first: int
    last: int
    stride: int

    @classmethod
    def from_dict(cls, spec: dict) -> "TimeResolved":
        """The ``time_resolved`` object of experiment.json (already schema-checked);
        ``first`` defaults to 0 and ``stride`` to the largest step.

        Raises
        ------
        ValueError
            Too few frames for one snapshot at the largest step.
        """
        steps = tuple(int(s) for s in spec["steps"])
        first, last = int(spec.get("first", 0)), int(spec["last"])
        if last - first < max(steps):
            raise ValueError(
                f"time_resolved: frames {first} … {last} hold no pair {max(steps)} frames apart"
            )
        return cls(
            frame_rate=float(spec["frame_rate"]),
            images=str(spec["images"]),
            steps=steps,
            first=first,
            last=last,
            stride=int(spec.get("stride", max(steps))),
        )

    @property
    def dt(self) -> np.ndarray:
        """Δt_k = steps[k] / frame_rate, s, shape (K,)."""
        return np.asarray(self.steps, dtype=float) / self.frame_rate

    @property
    def snapshots(self) -> int:
        """Frame pairs per Δt: those whose largest-step frame b is recorded."""
        return (self.last - self.first - max(self.steps)) // self.stride + 1

    def frame_number(self, k: int, m: int, frame: str) -> int:
        """The recorded frame that is frame ``frame`` of snapshot m at Δt_k."""
        start = self.first + m * self.stride
        return start if frame == "a" else start + self.steps[k]

    def frame_numbers(self, snapshots: int | None = None) -> range:
        """The consecutive frames first … last, or only those the first ``snapshots``
        frame pairs span (first … frame b of snapshot ``snapshots`` − 1 at the largest
        step) when they are fewer than all."""
        if snapshots is None or snapshots >= self.snapshots:
            return range(self.first, self.last + 1)
        return range(self.first, self.first + (snapshots - 1) * self.stride + max(self.steps) + 1)
