"""A short time-resolved recording without images, for the claims on track fitting and
the Lagrangian statistics (docs/claims.md #51–#53).

The tracers of the default flow (``lem-10hz``, kinematic simulation of Pope's spectrum)
in the paper-stereo rig's light sheet are followed over a few dozen frames τ_η/10 apart,
as the ``tr`` scenarios record them (:func:`simulator.recording.follow_recording`, which
gives every particle's exact position, velocity and Lagrangian acceleration at each
frame), and their positions are measured with white Gaussian noise of a known σ per
component. No image is rendered and nothing is linked: the tracks are the particles'
own runs of consecutive frames in the sheet (a particle that leaves and comes back
starts another), so that what the claims judge is the fitting and the statistics alone.
"""

from dataclasses import dataclass

import numpy as np

from simulator.particles import KSFlow
from simulator.presets import flow_preset
from simulator.recording import follow_recording
from simulator.rigs import load_rig
from simulator.spectra import PopeSpectrum

#: The flow and the rig whose sheet the tracers cross.
PRESET = "lem-10hz"
RIG = "paper-stereo"
#: Frame interval in Kolmogorov times: the tr scenarios' τ₀ = τ_η/10.
FRAME_INTERVAL_TAU_ETA = 0.1
#: Position noise σ per component, m: within the 2–8 µm that the rendered tr run measures
#: across the sheet's depth (docs/lagrangian.md §6), small enough that the fitted
#: acceleration's error (its floor ≈ 2/3 of the acceleration's rms at the chosen
#: window) can tell a fit from half of it.
NOISE = 5e-6


@dataclass(frozen=True, eq=False)
class RecordedCase:
    """Tracks of exact trajectories and their noisy measurement.

    Attributes
    ----------
    track, frame : ndarray of int, shape (M,)
        Track (a particle's run of consecutive frames in the sheet) and frame; rows
        sorted by track, then frame.
    position, velocity, acceleration : ndarray, shape (M, 3)
        Exact X(t_f), u and Lagrangian acceleration, m, m/s, m/s².
    measured : ndarray, shape (M, 3)
        ``position`` plus white Gaussian noise of σ = ``noise`` per component, m.
    noise : float
        σ, m.
    frame_rate : float
        Hz.
    tau_eta : float
        The flow's Kolmogorov time, s.
    """

    track: np.ndarray
    frame: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    measured: np.ndarray
    noise: float
    frame_rate: float
    tau_eta: float

    @property
    def tracks(self) -> int:
        """Number of tracks."""
        return int(self.track.max()) + 1 if len(self.track) else 0


def record_case(particles: int, frames: int, *, seed: int, noise: float = NOISE) -> RecordedCase:
    """Follow ``particles`` tracers (mean number in the sheet) over ``frames`` frames.

    Parameters
    ----------
    particles : int
        Mean number of tracers in the sheet at any frame.
    frames : int
        Frames F ≥ 2, τ_η/10 apart.
    seed : int
        Seeds the flow's realization and the tracers (``seed``) and the noise
        (``seed + 1``).
    noise : float
        σ per component, m.

    Returns
    -------
    RecordedCase
    """
    parameters = flow_preset(PRESET).parameters
    frame_rate = 1.0 / (FRAME_INTERVAL_TAU_ETA * parameters.tau_eta)
    recording = follow_recording(
        KSFlow(PopeSpectrum(parameters)),
        frame_rate,
        frames,
        particles=particles,
        region=load_rig(RIG).sheet,
        rng=seed,
    )
    particle, frame = recording.particle, recording.frame
    starts = np.r_[True, (particle[1:] != particle[:-1]) | (frame[1:] != frame[:-1] + 1)]
    position = recording.position
    measured = position + np.random.default_rng(seed + 1).normal(0.0, noise, position.shape)
    return RecordedCase(
        track=np.cumsum(starts) - 1,
        frame=frame,
        position=position,
        velocity=recording.velocity,
        acceleration=recording.acceleration,
        measured=measured,
        noise=float(noise),
        frame_rate=frame_rate,
        tau_eta=parameters.tau_eta,
    )
