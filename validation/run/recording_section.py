"""A scenario's ``[recording]``: a time-resolved acquisition instead of frame pairs.

A recording is ``frames`` consecutive frames at a constant frame rate, given in Hz
(``frame_rate``) or as the frame interval in Kolmogorov times (``tau_tau_eta``), and a
scenario may ask for several independent ``sequences``. The multi-Δt method takes its
frame pairs from the recording at the frame ``steps`` (Δt_k = steps[k] / frame_rate), and
the tracks are fitted over ``fit_window`` points (chosen from the data when left out).

Everything is checked when the scenario is read, before any work: the frame rate, the
counts, the steps against the frames, and the memory the recording's truth and tracks
will take against the machine's (:func:`recording_memory`).
"""

import math
import os
from dataclasses import dataclass

from simulator.recording import BATCH
from validation.run.scenario_fields import ScenarioError

#: (lowest, highest) frame interval in Kolmogorov times: below, thousands of frames per
#: τ_η; above, a particle's acceleration changes between frames and no track holds.
TAU_TAU_ETA_LIMITS = (0.005, 2.0)
#: (lowest, highest) frame rate, Hz.
FRAME_RATE_LIMITS = (1.0, 1e6)
#: (fewest, most) frames per sequence and sequences.
FRAME_LIMITS = (10, 100_000)
SEQUENCE_LIMITS = (1, 1_000)
#: Fewest points of a track fit (a cubic and one degree of freedom).
MIN_FIT_WINDOW = 5
#: Bytes a particle-frame takes in a recording's run: its truth, points, tracks, fits and
#: the statistics' samples, with the images and buffers of the work besides (the tr run
#: peaked at 1.44 GB resident for its 0.4 M particle-frames).
BYTES_PER_PARTICLE_FRAME = 3600
#: Share of the machine's memory a recording may plan to take.
MEMORY_SHARE = 0.5


@dataclass(frozen=True)
class RecordingSection:
    """A time-resolved acquisition (module docstring). ``[particles] count`` is the mean
    number of tracers in the sheet at every frame; its ``frames`` and the flow's Δt set
    are not used (a DNS keeps ``frames`` snapshots, one per recording at least).
    ``max_acceleration``, m/s², is the largest acceleration the tracker allows for
    (left out, the PTV stack's default, which suits the fast flows of the paper)."""

    frames: int = 200
    sequences: int = 1
    frame_rate: float | None = None
    tau_tau_eta: float | None = None
    steps: tuple[int, ...] = (1, 2, 4, 8)
    fit_window: int | None = None
    max_acceleration: float | None = None

    def rate(self, tau_eta: float) -> float:
        """Frames per second, Hz, for a flow of Kolmogorov time ``tau_eta`` (s)."""
        if self.frame_rate is not None:
            return self.frame_rate
        return 1.0 / (self.tau_tau_eta * tau_eta)


def recording_memory(particles: int, frames: int) -> float:
    """Bytes a sequence of ``frames`` frames with ``particles`` tracers in the sheet
    plans to take at its peak: its particle-frames, and the batch of seeds followed at
    once (:data:`simulator.recording.BATCH`, 72 bytes per seed and frame)."""
    rows = particles * frames
    return rows * BYTES_PER_PARTICLE_FRAME + 72 * BATCH * frames


def machine_memory() -> float:
    """Physical memory of this machine, bytes."""
    return float(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))


def check_recording(scenario, source: str, *, memory: float | None = None) -> None:
    """Refuse a recording that cannot run, naming the file and the field.

    Parameters
    ----------
    scenario : Scenario
        With ``recording``.
    source : str
        The scenario file, for the message.
    memory : float, optional
        The machine's memory, bytes (default :func:`machine_memory`).

    Raises
    ------
    ScenarioError
    """
    r = scenario.recording

    def fail(message: str):
        raise ScenarioError(f"{source}: recording.{message}")

    if scenario.flow.kind not in ("ks", "dns"):
        raise ScenarioError(
            f"{source}: [recording] follows a kinematic simulation or a DNS, not kind "
            f"{scenario.flow.kind!r}"
        )
    if scenario.flow.kind == "dns" and scenario.particles.frames < r.sequences:
        raise ScenarioError(
            f"{source}: particles.frames ({scenario.particles.frames}) is the DNS's number "
            f"of snapshots and each recording starts at one: give at least "
            f"recording.sequences ({r.sequences})"
        )
    if (r.frame_rate is None) == (r.tau_tau_eta is None):
        fail("frame_rate: give the frame rate (Hz) or tau_tau_eta (Kolmogorov times), one")
    if r.frame_rate is not None and not (
        FRAME_RATE_LIMITS[0] <= r.frame_rate <= FRAME_RATE_LIMITS[1]
    ):
        fail(
            f"frame_rate must be from {FRAME_RATE_LIMITS[0]:g} to {FRAME_RATE_LIMITS[1]:g} Hz, "
            f"got {r.frame_rate!r}"
        )
    tau_eta = _tau_eta(scenario)
    ratio = 1.0 / (r.rate(tau_eta) * tau_eta)
    lo, hi = TAU_TAU_ETA_LIMITS
    if not lo <= ratio <= hi:
        field = "tau_tau_eta" if r.tau_tau_eta is not None else "frame_rate"
        fail(
            f"{field}: a frame every {ratio:.3g} Kolmogorov times is outside {lo:g} … {hi:g} "
            f"(τ_η = {tau_eta * 1e3:.3g} ms)"
        )
    if len(r.steps) < 2 or len(set(r.steps)) != len(r.steps) or min(r.steps) < 1:
        fail(f"steps must be at least two distinct frame steps >= 1, got {list(r.steps)}")
    if not FRAME_LIMITS[0] <= r.frames <= FRAME_LIMITS[1]:
        fail(f"frames must be from {FRAME_LIMITS[0]} to {FRAME_LIMITS[1]}, got {r.frames}")
    if r.frames <= 2 * max(r.steps):
        fail(f"frames ({r.frames}) must exceed twice the largest step ({max(r.steps)})")
    if not SEQUENCE_LIMITS[0] <= r.sequences <= SEQUENCE_LIMITS[1]:
        fail(
            f"sequences must be from {SEQUENCE_LIMITS[0]} to {SEQUENCE_LIMITS[1]}, "
            f"got {r.sequences}"
        )
    if r.fit_window is not None and not (
        r.fit_window >= MIN_FIT_WINDOW and r.fit_window % 2 == 1 and r.fit_window <= r.frames
    ):
        fail(f"fit_window must be odd, >= {MIN_FIT_WINDOW} and <= frames, got {r.fit_window}")
    if r.max_acceleration is not None and not (
        math.isfinite(r.max_acceleration) and r.max_acceleration > 0
    ):
        fail(f"max_acceleration must be a finite number > 0 (m/s²), got {r.max_acceleration!r}")
    memory = machine_memory() if memory is None else memory
    need = recording_memory(scenario.particles.count, r.frames)
    if need > MEMORY_SHARE * memory:
        fail(
            f"frames: {scenario.particles.count} tracers over {r.frames} frames take about "
            f"{need / 2**30:.3g} GiB, more than half this machine's {memory / 2**30:.3g} GiB: "
            "record fewer frames per sequence and more sequences"
        )


def _tau_eta(scenario) -> float:
    """The flow's Kolmogorov time, s: (ν/ε)^½ (a DNS's u′ is measured later, its τ_η is
    known from the start)."""
    if scenario.flow.kind == "dns":
        return math.sqrt(scenario.flow.nu / scenario.flow.epsilon)
    return scenario.flow.as_preset().parameters.tau_eta
