"""The shared, lazily computed runs and references of a claims run."""

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ptv.stats.structure import StructureFunction, structure_function
from simulator.particles import ANALYSIS_VOLUME, DoubleFrameSample
from simulator.presets import flow_preset
from simulator.rigs import load_rig, rig_from_dict
from simulator.spectra import KolmogorovBandSpectrum, PopeSpectrum
from simulator.target import Imperfections, PlateDesign, build_plate, traverse_positions
from validation.claims.crowded_scores import CrowdedScores, crowded_scores
from validation.claims.formation_scores import FormationScores, formation_scores
from validation.claims.ipr_scores import IprScores, ipr_scores
from validation.claims.recorded_case import RecordedCase, record_case
from validation.claims.recorded_scores import (
    LagrangianScores,
    TrackFitScores,
    lagrangian_scores,
    track_fit_scores,
)
from validation.claims.rendered_case import CROWDED_CASE, SLOW_CASE, RenderedCase, render_case
from validation.studies.calibration_methods import (
    calibrate_cameras,
    compare_methods,
    plane_count_study,
)
from validation.studies.multi_dt_experiment import (
    Measurement,
    MultiDtResult,
    add_dt3_term,
    analyse,
    band_limited_spectrum,
    simulate,
)
from validation.truth.calibration_errors import synthetic_plane_dots
from validation.truth.independent import (
    BruteForceS2,
    brute_force_s2,
    exact_dll,
    log_edges,
    plateau_epsilon_reference,
)
from validation.truth.noise_floor import NoiseFloor, noise_floor

#: Correlation length of the spatially correlated noise of claim #9, m.
CORRELATION_LENGTH = 3e-3
#: Separation bins of the statistics claims (10η to L_int/2) and the plateau range, m.
BINS = 16
PLATEAU_RANGE = (2e-3, 20e-3)
#: The rigs of the calibration claims.
RIGS = ("paper-stereo", "conventional")


@dataclass(frozen=True)
class Sizes:
    """Sample sizes of a claims run.

    Attributes
    ----------
    particles : int
        Particles per snapshot of the KS runs.
    snapshots : int
        Snapshots per Δt.
    reference_particles : int
        Particles per group of the brute-force reference (two groups per snapshot).
    dot_noise_px : float
        Dot-centre noise of the synthetic calibration dots, px.
    image_snapshots : int
        Frame pairs of the rendered case of the image-stack claims.
    recording_particles : int
        Tracers in the sheet of the recorded case of the track claims (#51–#53).
    recording_frames : int
        Its frames, τ_η/10 apart.
    ipr_snapshots : int
        Snapshots of the dense case of the reconstruction claims (#55, #56).
    """

    particles: int
    snapshots: int
    reference_particles: int = 300
    dot_noise_px: float = 0.05
    image_snapshots: int = 3
    recording_particles: int = 500
    recording_frames: int = 60
    ipr_snapshots: int = 1


SIZES = {
    "quick": Sizes(particles=1000, snapshots=100),
    "full": Sizes(
        particles=2000,
        snapshots=600,
        reference_particles=500,
        image_snapshots=12,
        recording_particles=1000,
        recording_frames=120,
        ipr_snapshots=3,
    ),
}


class ClaimContext:
    """Shared, lazily computed runs and references for the claims of one size.

    Parameters
    ----------
    size : {"quick", "full"}
        Sample sizes.
    seed : int
        Seed of every run.
    kolmogorov_c2 : float or None
        C₂ used by the ε estimator (None: the stack's default; a wrong value must make
        claims fail).
    refraction : bool
        False evaluates the calibration claims on rigs whose windows are removed (a
        broken rig the Scheimpflug claim must fail on).
    band_cutoff : float
        k_Nη of the band-limited K41 spectrum of claims #10 and #23 (2π; 0.544, the
        dissipation-matched "k41-band", has no 2/3 range and must fail #10).
    dt3_coefficient : float
        β/ε of the Δt³ term injected for claim #23 (docs/statistics.md §4: β ≈ −(2/3)ε).

    Examples
    --------
    Nothing runs until a claim asks for it: making the context is free, and the two
    arithmetic claims below need none of its runs.

    >>> import validation
    >>> ctx = validation.ClaimContext("quick", seed=0)
    >>> ctx.sizes.particles, ctx.sizes.snapshots  # of the KS multi-Δt experiments
    (1000, 100)
    >>> [r.passed for r in validation.run_claims(ctx, ids=["table3.arithmetic",
    ...                                                    "flow.pope_spectrum"])]
    [True, True]
    >>> validation.ClaimContext("medium")
    Traceback (most recent call last):
    ...
    ValueError: unknown claims size 'medium'; known: quick, full
    """

    def __init__(
        self,
        size: str = "quick",
        *,
        seed: int = 0,
        kolmogorov_c2: float | None = None,
        refraction: bool = True,
        band_cutoff: float = 2 * np.pi,
        dt3_coefficient: float = -2.0 / 3.0,
    ) -> None:
        if size not in SIZES:
            raise ValueError(f"unknown claims size {size!r}; known: {', '.join(SIZES)}")
        self.sizes = SIZES[size]
        self.seed = seed
        self.kolmogorov_c2 = kolmogorov_c2
        self.refraction = refraction
        self.band_cutoff = band_cutoff
        self.dt3_coefficient = dt3_coefficient
        self.preset = flow_preset("lem-10hz")
        self.plate = build_plate(
            PlateDesign(), traverse_positions(), imperfections=Imperfections(), rng=seed
        )

    # ------------------------------------------------------------------ calibration

    def rig(self, name: str):
        """The rig ``name``, without its windows when ``refraction`` is False."""
        rig = load_rig(name)
        if self.refraction:
            return rig
        spec = {
            **rig.spec,
            "cameras": [{k: v for k, v in c.items() if k != "window"} for c in rig.spec["cameras"]],
        }
        return rig_from_dict(spec, source=f"{name} without windows")

    def _dots(self, rig):
        return synthetic_plane_dots(
            rig.cameras, self.plate, noise_px=self.sizes.dot_noise_px, rng=self.seed + 1
        )

    def _compare(self, name: str) -> dict:
        rig = self.rig(name)
        return compare_methods(
            rig, self.plate, self._dots(rig), methods=("model-free", "tsai"), rng=self.seed + 2
        )

    @cached_property
    def paper_stereo(self) -> dict:
        """Table 1 and model errors of model-free and Tsai on paper-stereo."""
        return self._compare("paper-stereo")

    @cached_property
    def conventional(self) -> dict:
        """Table 1 and model errors of model-free and Tsai on the conventional rig."""
        return self._compare("conventional")

    @cached_property
    def noise_floors(self) -> dict[str, NoiseFloor]:
        """Per rig of :data:`RIGS`, what the dot-centre noise alone allows
        (:func:`validation.truth.noise_floor.noise_floor`, from the true cameras)."""
        points = np.concatenate([self.plate.dot_centres(j) for j in range(len(self.plate.poses))])
        return {
            name: noise_floor(self.rig(name).cameras, points, self.sizes.dot_noise_px)
            for name in RIGS
        }

    @cached_property
    def planes(self) -> dict[int, dict]:
        """Plane-count rows (3, 7, 13 planes) on paper-stereo, model-free."""
        rig = self.rig("paper-stereo")
        rows = plane_count_study(
            rig, self.plate, self._dots(rig), counts=(3, 7, 13), rng=self.seed + 3
        )
        return {row["planes"]: row for row in rows}

    @cached_property
    def plane_residuals_px(self) -> list[np.ndarray]:
        """T_j⁻¹ residuals of the model-free fits on paper-stereo, px, per camera and plane."""
        rig = self.rig("paper-stereo")
        calibrations = calibrate_cameras("model-free", rig, self._dots(rig))
        return [p.residual_px for c in calibrations for p in c.planes]

    # ------------------------------------------------------------------- statistics

    @cached_property
    def sample(self) -> DoubleFrameSample:
        """The exact double-frame runs of the Pope-spectrum statistics claims."""
        return simulate(
            self.preset,
            particles=self.sizes.particles,
            snapshots=self.sizes.snapshots,
            rng=self.seed + 4,
        )

    @cached_property
    def band_spectrum(self) -> KolmogorovBandSpectrum:
        """The band-limited K41 spectrum of claims #10 and #23 (cut at k_Nη = band_cutoff)."""
        return band_limited_spectrum(self.preset.parameters, cutoff=self.band_cutoff)

    @cached_property
    def _band_sample(self) -> DoubleFrameSample:
        return simulate(
            self.preset,
            particles=self.sizes.particles,
            snapshots=self.sizes.snapshots,
            spectrum=self.band_spectrum,
            rng=self.seed + 6,
        )

    @cached_property
    def rendered_case(self) -> RenderedCase:
        """The small rendered case of the image-stack claims, measured by the stack."""
        return render_case(self.sizes.image_snapshots, seed=self.seed + 10)

    @cached_property
    def slow_case(self) -> RenderedCase:
        """The slow lab flow on four cameras (claims #35, #36), measured by the stack."""
        return render_case(self.sizes.image_snapshots, seed=self.seed + 11, spec=SLOW_CASE)

    @cached_property
    def crowded_case(self) -> RenderedCase:
        """The default's rig and flow crowded (claims #42–#45), measured by the stack."""
        return render_case(self.sizes.image_snapshots, seed=self.seed + 14, spec=CROWDED_CASE)

    @cached_property
    def crowded(self) -> CrowdedScores:
        """The crowded case's yield, ghosts, links and outlier flags against references."""
        return crowded_scores(self.crowded_case)

    @cached_property
    def formation(self) -> FormationScores:
        """The rendered case's images against their specification (claims #37–#41)."""
        return formation_scores(self.rendered_case, seed=self.seed + 12)

    @cached_property
    def slow_formation(self) -> FormationScores:
        """The slow case's images against their specification (claims #37–#41)."""
        return formation_scores(self.slow_case, seed=self.seed + 13)

    @cached_property
    def recorded_case(self) -> RecordedCase:
        """The short recording of exact trajectories and their noisy measurement
        (claims #51–#53)."""
        return record_case(
            self.sizes.recording_particles, self.sizes.recording_frames, seed=self.seed + 16
        )

    @cached_property
    def track_fits(self) -> TrackFitScores:
        """The recorded case's tracks fitted by the stack, against their floors."""
        return track_fit_scores(self.recorded_case, seed=self.seed + 18)

    @cached_property
    def lagrangian(self) -> LagrangianScores:
        """The recorded case's Lagrangian statistics, noisy and noise-free."""
        return lagrangian_scores(self.recorded_case, seed=self.seed + 18)

    @cached_property
    def ipr(self) -> IprScores:
        """The dense case's measured OTF and reconstruction against the truth (claims
        #55, #56)."""
        return ipr_scores(self.sizes.ipr_snapshots, seed=self.seed + 20)

    @cached_property
    def reference(self) -> BruteForceS2:
        """S2 of the exact velocities of the Pope-spectrum runs at t, by brute force over
        two groups of ``reference_particles`` per snapshot in the claims' bins
        (:func:`validation.truth.independent.brute_force_s2`)."""
        p = self.preset.parameters

        def snapshots():
            for run in self.sample.runs:
                for x, u in zip(run.positions[:, 0], run.velocity[:, 0], strict=True):
                    inside = ANALYSIS_VOLUME.contains(x)
                    yield x[inside], u[inside]

        return brute_force_s2(
            snapshots(),
            log_edges(10 * p.eta, p.L_int / 2, BINS),
            per_group=self.sizes.reference_particles,
            rng=self.seed + 8,
        )

    @cached_property
    def epsilon_reference(self) -> float:
        """ε_input × the estimator's plateau deficit on the Pope spectrum, m²/s³: the
        maximum of (D_LL/C₂)^{3/2}/r at the reference's bins in the plateau range, from
        an independent quadrature of the spectrum and C₂ = 2
        (:func:`validation.truth.independent.plateau_epsilon_reference`)."""
        spectrum = PopeSpectrum(self.preset.parameters)
        return plateau_epsilon_reference(
            lambda r: exact_dll(spectrum, r), self.reference.r, r_range=PLATEAU_RANGE
        )

    def _analyse(self, measurement: Measurement, *, band: bool = False) -> MultiDtResult:
        c2 = {} if self.kolmogorov_c2 is None else {"kolmogorov_c2": self.kolmogorov_c2}
        return analyse(
            self._band_sample if band else self.sample,
            self.preset,
            measurement,
            bins=BINS,
            inertial_range=PLATEAU_RANGE,
            spectrum=self.band_spectrum if band else None,
            sample_truth=False,
            rng=self.seed + 5,
            **c2,
        )

    @cached_property
    def multi_dt(self) -> MultiDtResult:
        """The multi-Δt experiment with 15 µm white noise."""
        return self._analyse(Measurement())

    @cached_property
    def multi_dt_exact(self) -> MultiDtResult:
        """The same sample's exact positions (no noise): the reference of the run
        statistics' u′ on the same snapshots (#54)."""
        return self._analyse(Measurement(noise=(0.0, 0.0, 0.0)))

    @cached_property
    def multi_dt_correlated(self) -> MultiDtResult:
        """The same with spatially correlated noise (ℓ = 3 mm, white in time)."""
        return self._analyse(Measurement(correlation_length=CORRELATION_LENGTH))

    @cached_property
    def multi_dt_scaled(self) -> MultiDtResult:
        """The same with a 1 % calibration scale error."""
        return self._analyse(Measurement(scale_error=0.01))

    @cached_property
    def multi_dt_band(self) -> MultiDtResult:
        """The multi-Δt experiment with 15 µm white noise on the band-limited spectrum."""
        return self._analyse(Measurement(), band=True)

    @cached_property
    def dt3_fits(self) -> tuple[StructureFunction, StructureFunction]:
        """Fits of the band-limited run without and with βΔt³ (β = dt3_coefficient·ε).

        Both from the same pair sums with the same bootstrap draws, so they differ only
        by the injected term.
        """
        sums, dt = self.multi_dt_band.sums, self._band_sample.dt
        beta = self.dt3_coefficient * self.preset.parameters.epsilon
        base = structure_function(sums, dt, rng=self.seed + 7)
        return base, structure_function(add_dt3_term(sums, dt, beta), dt, rng=self.seed + 7)
