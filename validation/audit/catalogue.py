"""Every named setting and constant of the chain, and how the sensitivity audit perturbs it.

The audited objects (docs/claims.md §6):

- every field of the settings the PTV stack reads (:mod:`ptv.settings`):
  :class:`~ptv.settings.PipelineSettings` (matching, linking, the median test),
  :class:`~ptv.settings.DetectorSettings` and :class:`~ptv.settings.StatisticsSettings`;
- the public module constants of the chain's code (``ptv.settings``, ``ptv.bins``,
  ``ptv.detect``, ``ptv.matching``, ``ptv.tracking``, ``ptv.stats``, ``ptv.pipeline``)
  and of the renderer's image formation (``simulator.render``).

Each entry says how it is perturbed: a tolerance or threshold ×0.5 and ×2, a physical
constant or size ±10 %, a count ×0.5 and ×2, a choice of algorithm swapped for the
nearest alternative. An entry no claim can reach, or that a perturbation cannot reach
(a constant compiled into a kernel, a keyword default the chain always sets, a file
format's name), is listed with the reason and not run. ``tests/validation/test_audit.py``
fails when a field or public constant of those classes and modules is missing here.
"""

import dataclasses
import importlib
from dataclasses import dataclass

from validation.mutations.base import Mutation
from validation.mutations.patching import Patch

__all__ = ["AUDITED", "Audited", "perturbation", "perturbations"]

#: Perturbations of each kind: (label, factor) for numbers, the alternative for choices.
FACTORS = {
    "tolerance": (("×0.5", 0.5), ("×2", 2.0)),
    "physical": (("−10 %", 0.9), ("+10 %", 1.1)),
    "count": (("×0.5", 0.5), ("×2", 2.0)),
}


@dataclass(frozen=True)
class Audited:
    """One setting or constant and how the audit treats it.

    Attributes
    ----------
    target : str
        ``"module:Class.field"`` for a settings field, ``"module:NAME"`` for a constant.
    kind : str
        ``tolerance``, ``physical``, ``count``, ``choice`` (perturbed), or ``not run``.
    groups : tuple of str
        Claim groups that can see it (``image``: the rendered cases run the stack with
        the default settings).
    alternative : object
        For a choice, the value it is swapped for.
    reason : str
        Why an entry is not run, or who reads it.
    """

    target: str
    kind: str
    groups: tuple[str, ...] = ("image",)
    alternative: object = None
    reason: str = ""

    @property
    def is_field(self) -> bool:
        """Whether the target is a field of a settings class."""
        return "." in self.target.partition(":")[2]


_PIPE = "ptv.settings:PipelineSettings."
_DET = "ptv.settings:DetectorSettings."
_STAT = "ptv.settings:StatisticsSettings."
#: The claim of synptv run's default statistics (#49).
_RUN = ("run",)
_SHARED = "read with a shared first frame only; the claims' runs are one experiment per Δt"
_U_PRIME = (
    "read by the Eulerian u′ and σ_b only, which no claim regresses: their sampling error "
    "is set by the snapshots, which the estimator's error (particles taken as "
    "independent) does not see"
)
_CASES_UNSET = "the rendered cases detect with the threshold and saturation only"
_DERIVED = "left out (None) it is derived; its rule's constants are audited"
_INDEPENDENT = (
    "sets how correlated snapshots are resampled; the claims' snapshots are independent "
    "realizations, drawn one at a time whatever it is"
)
_RATE = (
    "a false-alarm rate: how often an honest run fails a test, not a size the claims "
    "measure (benchmarks/bench_false_alarms.py counts it)"
)
_RECORDING = "read by time-resolved recordings only"
_CLAIMED = (
    "read by the recorded case's claims (#51–#53, which came after the last audit): not "
    "perturbed yet"
)
_WARNING = "sets when a warning is printed; no result depends on it"
_COMPILED = "compiled into a detection kernel: a perturbation needs the kernel recompiled"
_FORMAT = "a file format's name or version"
_FLAGS = "a flag's bit or an index into a table, not a quantity"
_WORK = "how work is split into chunks; results do not depend on it"
_ALIAS = "the default of a settings field audited above"
_UNUSED_DEFAULT = "the default of a keyword the pipeline always sets"
_CHOICES = "the list of allowed values of a choice audited above"

AUDITED: tuple[Audited, ...] = (
    Audited(
        _PIPE + "volume",
        "not run",
        (),
        reason="a region, not one number: the sheet and a 1 mm margin, which the cases fill",
    ),
    Audited(_PIPE + "tolerance", "not run", (), reason=_DERIVED),
    Audited(_PIPE + "min_cameras", "not run", (), reason=_DERIVED),
    Audited(_PIPE + "max_speed", "not run", (), reason=_DERIVED),
    Audited(_PIPE + "position_noise", "tolerance"),
    Audited(_PIPE + "predicted_radii", "not run", (), reason=f"{_DERIVED}; {_SHARED}"),
    Audited(_PIPE + "max_acceleration", "not run", (), reason=_RECORDING),
    Audited(_PIPE + "track_gap", "not run", (), reason=_RECORDING),
    Audited(_PIPE + "outlier_threshold", "tolerance"),
    Audited(_PIPE + "outlier_neighbours", "count"),
    Audited(_PIPE + "snapshots", "not run", (), reason="None: every snapshot"),
    Audited(_PIPE + "statistics", "not run", (), reason="its fields are audited below"),
    Audited(_DET + "threshold_sigmas", "tolerance"),
    Audited(_DET + "saturation", "not run", (), reason="None: the sensor's largest reading"),
    Audited(_DET + "particles", "not run", (), reason=_CASES_UNSET),
    Audited(_DET + "background", "not run", (), reason=_CASES_UNSET),
    Audited(_DET + "tophat_radius", "not run", (), reason=_CASES_UNSET),
    Audited(_DET + "median_frames", "not run", (), reason=_CASES_UNSET),
    Audited(_DET + "min_peak", "not run", (), reason=_CASES_UNSET),
    Audited(_DET + "min_size", "not run", (), reason=_CASES_UNSET),
    Audited(_DET + "diameter", "not run", (), reason=_CASES_UNSET),
    Audited(
        _STAT + "analysis_volume",
        "not run",
        (),
        reason="a region, not a size: it selects the links (a smaller box is a smaller "
        "sample, not a bias); the claims' links lie in the documented box",
    ),
    Audited(_STAT + "r_min", "physical", _RUN),
    Audited(_STAT + "r_max", "physical", _RUN),
    Audited(_STAT + "n_bins", "count", _RUN),
    Audited(_STAT + "binning", "not run", (), reason=_SHARED),
    Audited(_STAT + "plateau", "physical", _RUN),
    Audited(_STAT + "plateau_method", "choice", _RUN, alternative="max"),
    Audited(_STAT + "kolmogorov_c2", "physical", _RUN),
    Audited(_STAT + "n_boot", "count", _RUN),
    Audited(_STAT + "eulerian_cells", "not run", (), reason=_U_PRIME),
    Audited(_STAT + "min_cell_count", "not run", (), reason=_U_PRIME),
    Audited(_STAT + "trajectory_threshold", "not run", (), reason=_SHARED),
    Audited(_STAT + "snapshot_block", "not run", (), reason=_INDEPENDENT),
    Audited(_STAT + "seed", "not run", (), reason="the bootstrap's seed: another draw, not a size"),
    Audited("ptv.matching.tolerance:PIXEL_FLOOR", "tolerance"),
    Audited("ptv.matching.tolerance:SPREAD_PER_MEDIAN", "tolerance"),
    Audited("ptv.matching.tolerance:CONVERGED", "tolerance"),
    Audited("ptv.matching.tolerance:MAX_ITERATIONS", "count"),
    Audited("ptv.matching.stereo:DEFAULT_TOLERANCE", "not run", (), reason=_UNUSED_DEFAULT),
    Audited("ptv.tracking.link_speed:SPEED_SIGMAS", "tolerance"),
    Audited("ptv.tracking.link_speed:MAD_TO_SIGMA", "physical"),
    Audited("ptv.tracking.link_speed:CONVERGED", "tolerance"),
    Audited("ptv.tracking.link_speed:MAX_ITERATIONS", "count"),
    Audited("ptv.tracking.stitching:DROP_COST", "not run", (), reason=_RECORDING),
    Audited("ptv.pipeline.time_resolved:MISS_NOISE_FACTOR", "not run", (), reason=_RECORDING),
    Audited("ptv.pipeline.time_resolved:MIN_MISSES", "not run", (), reason=_RECORDING),
    Audited("ptv.tracking.fitting:SIGNIFICANCE", "not run", (), reason=_CLAIMED),
    Audited("ptv.tracking.fitting:FOURTH_DERIVATIVE_DEGREE", "not run", (), reason=_CLAIMED),
    Audited("ptv.tracking.fitting:OUTLIER_CHI2", "not run", (), reason=_CLAIMED),
    Audited("ptv.tracking.fitting:OUTLIER_ROUNDS", "not run", (), reason=_CLAIMED),
    Audited("ptv.tracking.fitting:MIN_FIT_POINTS", "not run", (), reason=_CLAIMED),
    Audited("ptv.stats.lagrangian:STEPS", "not run", (), reason=_CLAIMED),
    Audited("ptv.stats.lagrangian:LAGS", "not run", (), reason=_CLAIMED),
    Audited("ptv.pipeline.resolve:LINK_SPEED_SNAPSHOTS", "count"),
    Audited(
        "ptv.pipeline.reconstructed:FLAT_OTF_ITERATIONS",
        "not run",
        (),
        reason="read by IPR's OTF only (claim #55, after the last audit): not perturbed yet",
    ),
    Audited(
        "ptv.pipeline.reconstructed:OTF_MAX_EXPOSURES",
        "not run",
        (),
        reason="a cap on the exposures the OTF pools: the claims' dense case needs one",
    ),
    Audited("ptv.tracking.link_prediction:MISS_SIGMAS", "not run", (), reason=_SHARED),
    Audited("ptv.tracking.link_prediction:MIN_MISSES", "not run", (), reason=_SHARED),
    Audited("ptv.stats.resampling:RESOLVED_RHO1", "not run", (), reason=_INDEPENDENT),
    Audited("ptv.stats.mean_displacement:OFFSET_FALSE_ALARM", "not run", (), reason=_RATE),
    Audited("simulator.render.spot:SHEET_PROFILES", "not run", (), reason=_CHOICES),
    Audited("ptv.pipeline.double_frame:AMBIGUITY_WARNING", "not run", (), reason=_WARNING),
    Audited("ptv.detect.frames:STILL_FRACTION", "not run", (), reason=_WARNING),
    Audited("ptv.detect.frames:MIN_STILL_CHECK", "not run", (), reason=_WARNING),
    Audited("ptv.pipeline.summary:THIN_MATCH_FRACTION", "not run", (), reason=_WARNING),
    Audited("ptv.pipeline.summary:FORMAT_NAME", "not run", (), reason=_FORMAT),
    Audited("ptv.pipeline.summary:FORMAT_VERSION", "not run", (), reason=_FORMAT),
    Audited("ptv.settings:MEASUREMENT_VOLUME", "not run", (), reason=_ALIAS),
    Audited("ptv.pipeline.settings_file:SECTIONS", "not run", (), reason=_FORMAT),
    Audited("ptv.detect._groups:GROUP_DISTANCE_PX", "tolerance"),
    Audited("ptv.detect._groups:MAX_GROUP", "count"),
    Audited("ptv.detect._groups:PIECE_DISTANCES", "not run", (), reason="a schedule of distances"),
    Audited("ptv.detect._blocks:NATIVE_DIAMETER", "not run", (), reason=_CASES_UNSET),
    Audited("ptv.detect.background:MAD_TO_SIGMA", "physical"),
    Audited("ptv.detect._split:MIN_SEPARATION", "not run", (), reason=_COMPILED),
    Audited("ptv.detect._split:MAX_ADDED", "not run", (), reason=_COMPILED),
    Audited("ptv.detect._split:SPLIT_CHI2", "not run", (), reason=_COMPILED),
    Audited("ptv.detect._split:SCREEN_CHI2", "not run", (), reason=_COMPILED),
    Audited("ptv.detect._kernels:MAX_SPLIT", "not run", (), reason=_COMPILED),
    *(
        Audited(f"ptv.detect._kernels:{name}", "not run", (), reason=_FLAGS)
        for name in (
            "OVERLAP",
            "ELONGATED",
            "SATURATED",
            "EDGE",
            "FALLBACK",
            "CENTROID",
            "GAUSS",
            "GAUSS3",
        )
    ),
    Audited("ptv.detect._refine:HALF", "not run", (), reason=_COMPILED),
    Audited("ptv.detect._image:KERNEL_DTYPES", "not run", (), reason=_FLAGS),
    Audited("ptv.settings:BACKGROUND_REMOVALS", "not run", (), reason=_CHOICES),
    *(
        Audited(f"ptv.detect.store:{name}", "not run", (), reason=_FORMAT)
        for name in ("FORMAT_NAME", "FORMAT_VERSION", "INDEX")
    ),
    Audited("ptv.stats.pairs:N_CHUNKS", "not run", (), reason=_WORK),
    Audited("ptv.bins:BINNINGS", "not run", (), reason=_CHOICES),
    Audited("ptv.settings:ANALYSIS_VOLUME", "not run", (), reason=_ALIAS),
    Audited("ptv.stats.dissipation:NU_WATER", "not run", (), reason=_UNUSED_DEFAULT),
    Audited(
        "ptv.settings:DEFAULT_C2",
        "not run",
        (),
        reason="taken as keyword defaults when the modules load; claim #12 pins C₂ = 2",
    ),
    Audited("simulator.render.spot:AIRY_BETA2", "not run", (), reason="the Airy convention only"),
    Audited("simulator.render.spot:DIAMETER_PER_SIGMA", "physical"),
    Audited("simulator.render.spot:WAVELENGTH_532", "not run", (), reason=_UNUSED_DEFAULT),
    Audited("simulator.render.plate:MARGIN_SAFETY", "not run", (), reason="plate images only"),
    Audited("simulator.render.plate:CENTRE_CHUNK", "not run", (), reason=_WORK),
    Audited("simulator.render.plate:SUBSAMPLE_CHUNK", "not run", (), reason=_WORK),
    Audited("simulator.render.plate:RIM_POINTS", "not run", (), reason="plate images only"),
    Audited("simulator.render.plate:ON_SENSOR_MARGIN", "not run", (), reason="plate images only"),
    Audited("simulator.render.plate:MIN_BLUR_SIGMA", "not run", (), reason="plate images only"),
)


def _target(audited: Audited):
    """(owner, attribute) of a constant, or (class, field name) of a settings field."""
    module, _, path = audited.target.partition(":")
    owner = importlib.import_module(module)
    *parents, name = path.split(".")
    for parent in parents:
        owner = getattr(owner, parent)
    return owner, name


def _with_default(cls, name: str, value):
    """A subclass of the dataclass ``cls`` whose field ``name`` defaults to ``value``."""
    namespace = {
        "__annotations__": {name: cls.__annotations__[name]},
        name: value,
        "__module__": cls.__module__,
        "__qualname__": cls.__qualname__,
    }
    params = cls.__dataclass_params__
    return dataclass(frozen=params.frozen, eq=params.eq)(type(cls.__name__, (cls,), namespace))


def _scaled(value, factor: float, kind: str):
    if isinstance(value, tuple):  # a range, a box or cells: every entry
        return tuple(_scaled(v, factor, kind) for v in value)
    if isinstance(value, dict):  # a table of numbers: its default entry
        first = next(iter(value))
        return {**value, first: value[first] * factor}
    if kind == "count":
        return max(1, round(value * factor))
    return type(value)(value * factor)


def perturbations(audited: Audited) -> list[Mutation]:
    """The audit's perturbations of one entry (none for an entry not run)."""
    if audited.kind == "not run":
        return []
    owner, name = _target(audited)
    if audited.is_field:
        original = {f.name: f.default for f in dataclasses.fields(owner)}[name]
        values = (
            [(f"→ {audited.alternative!r}", audited.alternative)]
            if audited.kind == "choice"
            else [(label, _scaled(original, f, audited.kind)) for label, f in FACTORS[audited.kind]]
        )
        class_target = audited.target.rpartition(".")[0]
        patches = [
            (label, Patch(class_target, lambda cls, v=value: _with_default(cls, name, v)))
            for label, value in values
        ]
    else:
        patches = [
            (label, Patch(audited.target, lambda v, f=f: _scaled(v, f, audited.kind)))
            for label, f in FACTORS[audited.kind]
        ]
    return [
        Mutation(
            f"{audited.target} {label}",
            f"{audited.target.partition(':')[2]} {label}",
            (patch,),
            (),
            audited.groups,
            lambda: None,
        )
        for label, patch in patches
    ]


def perturbation(name: str) -> Mutation:
    """The perturbation called ``name`` (picklable lookup for the runner's processes)."""
    for audited in AUDITED:
        for candidate in perturbations(audited):
            if candidate.name == name:
                return candidate
    raise ValueError(f"unknown perturbation {name!r}")
