"""Virtual experiments described by TOML files: presets ``default``, ``ci``, ``box-3cam``
and ``paper-8hz/10hz/12hz``.

A scenario composes a flow (a preset or custom), a rig, the calibration target and
traverse, the tracer seeding and lighting, the sensor, the sizes and the PTV analysis.
Every length is in m, every time in s. A scenario file has ``name``, ``description``,
``seed`` and the tables (fields and defaults in :class:`Scenario`)::

    [flow]         kind ("ks", "dns", "grid"; :mod:`validation.run.flow_section`);
                   KS: preset, or u_rms, epsilon, nu and dt (s) or dt_tau_eta
                   (Kolmogorov times); spectrum, modes, unsteadiness
    [rig]          name (a rig preset or a .toml path, relative to the scenario file)
    [calibration]  planes, plate ("realistic" or "ideal"), brightness, methods
    [particles]    count, frames, electrons, diameter, shared_first_frame
    [sensor]       gain, read_noise, offset, full_well, bit_depth, background
    [ptv]          methods, analysis_size, r_min, r_max, n_bins, plateau, kolmogorov_c2,
                   max_speed, tolerance, min_cameras, n_boot (but for methods and
                   analysis_size, the names of :mod:`ptv.settings`; the old r_range, bins
                   and analysis_volume are read, with a warning)
    [checks]       c1_r_min_eta, c1_r_max_l_int
    [output]       images, links
    [recording]    frames, sequences, frame_rate or tau_tau_eta, steps, fit_window: a
                   time-resolved recording instead of frame pairs
                   (:mod:`validation.run.recording_section`, docs/run.md §11)
    [ipr]          methods, otf_regions, mapping_grid, outer_iterations: iterative
                   particle reconstruction rungs (:mod:`validation.run.ipr_section`)

Missing tables take their defaults; unknown tables or fields are errors that name the
file and the field. A custom flow (:class:`FlowSection`), for example::

    [flow]
    u_rms = 0.12              # u', one component, m/s
    epsilon = 0.05            # m²/s³
    nu = 1.0e-6               # m²/s (default: water)
    dt_tau_eta = [0.05, 0.1, 0.2]

is refused when it also names a preset, lacks u_rms or epsilon, gives both or neither
of dt and dt_tau_eta, a Δt set not strictly increasing from > 0, or numbers outside
:data:`validation.run.flow_section.FLOW_LIMITS`. :meth:`FlowSection.as_preset` gives the
flow, preset or custom, to everything that simulates it.
"""

import tomllib
from dataclasses import asdict, dataclass, field, replace
from importlib import resources
from pathlib import Path

import numpy as np

from ptv.calibration.methods import CALIBRATION_METHODS
from ptv.names import FILE_NAME_RULE, is_file_name
from ptv.settings import PipelineSettings, StatisticsSettings
from simulator.render.sensor import Sensor
from simulator.rigs import RigFileError, load_rig, rig_presets
from validation.run.derived_ptv import (
    DERIVED_FIELDS,
    derive_ptv_ranges,
    independent_pair_ambiguity,
)
from validation.run.flow_section import (
    FlowSection,
    check_flow,
    dns_box_side,
    dns_eta,
    flow_section,
)
from validation.run.ipr_section import IprSection, check_ipr, check_ipr_memory, sensor_pixels
from validation.run.recording_section import RecordingSection, check_recording
from validation.run.scenario_fields import ScenarioError, renamed_keys, section


@dataclass(frozen=True)
class RigSection:
    """The cameras: a rig preset name or a rig TOML file."""

    name: str = "paper-stereo"


@dataclass(frozen=True)
class CalibrationSection:
    """The dotted plate, its traverse and the calibration methods fitted.

    ``plate`` is ``"realistic"`` (dot scatter, traverse error, tilt, bow, uneven light:
    :data:`simulator.target.REALISTIC`) or ``"ideal"``; ``brightness`` is the
    photo-electrons of a fully lit plate pixel.
    """

    planes: int = 13
    plate: str = "realistic"
    brightness: float = 4000.0
    methods: tuple[str, ...] = ("model-free", "tsai", "pinhole", "soloff")


@dataclass(frozen=True)
class ParticlesSection:
    """Tracers: mean number in the illuminated sheet, frame pairs per Δt, light, size.

    ``electrons`` is the photo-electron count from a tracer on the sheet's centre
    plane; it sets the detection noise (0.05 px rms at 2000 e⁻ on paper-stereo).
    ``shared_first_frame``: every Δt from the same snapshots (the paper's time-resolved
    acquisition, default) or one independent experiment per Δt.
    """

    count: int = 2000
    frames: int = 40
    electrons: float = 2000.0
    diameter: float = 225e-6
    shared_first_frame: bool = True


#: The stack's defaults (:mod:`ptv.settings`), which a scenario's [ptv] table shares.
_PIPELINE = PipelineSettings()
_STATISTICS = _PIPELINE.statistics


@dataclass(frozen=True)
class PtvSection:
    """The PTV analysis.

    ``methods`` are the calibrations the PTV runs with (the true cameras always run
    too, for the error budget); ``analysis_size`` is the size of the centred box the
    statistics use, m; ``r_min`` and ``r_max`` the outer edges of the ``n_bins`` log-spaced
    separation bins, m; ``plateau`` the r range of the plateau ε, m; ``min_cameras``
    the fewest cameras a match must use (2 to the rig's camera count; left out, all but
    one of four or more, else 2); ``tolerance`` the matching tolerance on the ray
    distances, m, and ``max_speed`` the largest particle speed, m/s (left out, both
    measured on the rig and the data). Left out, ``analysis_size``, ``r_min``, ``r_max`` and
    ``plateau`` follow the rig and the flow (:mod:`validation.run.derived_ptv`). The
    other fields' defaults are the stack's (:class:`ptv.settings.StatisticsSettings`,
    :class:`ptv.settings.PipelineSettings`); ``analysis_size`` is the size of a box
    centred on the origin, which ``StatisticsSettings.analysis_volume`` gives by its
    corners.
    """

    methods: tuple[str, ...] = ("model-free", "tsai")
    analysis_size: tuple[float, float, float] = (0.07, 0.07, 0.008)
    r_min: float = _STATISTICS.r_min
    r_max: float = _STATISTICS.r_max
    n_bins: int = _STATISTICS.n_bins
    plateau: tuple[float, float] = _STATISTICS.plateau
    kolmogorov_c2: float = _STATISTICS.kolmogorov_c2
    max_speed: float | None = _PIPELINE.max_speed
    tolerance: float | None = _PIPELINE.tolerance
    min_cameras: int | None = _PIPELINE.min_cameras
    n_boot: int = _STATISTICS.n_boot


@dataclass(frozen=True)
class ChecksSection:
    """Where c1 is compared with the sample truth: c1_r_min_eta·η ≤ r ≤ c1_r_max_l_int·L_int."""

    c1_r_min_eta: float = 40.0
    c1_r_max_l_int: float = 0.5


@dataclass(frozen=True)
class OutputSection:
    """What a run keeps beyond its statistics: ``images`` writes the particle images into
    the dataset (16-bit TIFF, about 4 MB each) instead of detecting them in memory only;
    ``links`` writes every rung's links in the analysis volume into its results.h5
    (about 0.3 GB per rung at the paper's size). The plate images and truth.h5 are
    always written."""

    images: bool = False
    links: bool = True


@dataclass(frozen=True)
class Scenario:
    """One virtual experiment (module docstring for the file format).

    Examples
    --------
    The CI scenario: the paper-stereo rig in the 10 Hz flow, 2000 tracers, 40 frame
    pairs per Δt, 7 calibration planes:

    >>> import validation
    >>> scenario = validation.load_scenario("ci")
    >>> scenario.rig.name, scenario.flow.label, scenario.seed
    ('paper-stereo', 'lem-10hz', 0)
    >>> scenario.particles.count, scenario.particles.frames, scenario.calibration.planes
    (2000, 40, 7)
    >>> scenario.ptv.methods, scenario.ptv.analysis_size  # calibrations the PTV uses; m
    (('model-free',), (0.07, 0.07, 0.008))
    >>> scenario.with_seed(3).seed  # the same experiment, other random draws
    3
    >>> sorted(scenario.as_dict())  # its tables, as a scenario file holds them
    ['calibration', 'checks', 'description', 'flow', 'name', 'output', 'particles', 'ptv',
     'rig', 'seed', 'sensor']
    """

    name: str
    description: str = ""
    seed: int = 0
    flow: FlowSection = field(default_factory=FlowSection)
    rig: RigSection = field(default_factory=RigSection)
    calibration: CalibrationSection = field(default_factory=CalibrationSection)
    particles: ParticlesSection = field(default_factory=ParticlesSection)
    sensor: Sensor = field(default_factory=Sensor)
    ptv: PtvSection = field(default_factory=PtvSection)
    checks: ChecksSection = field(default_factory=ChecksSection)
    output: OutputSection = field(default_factory=OutputSection)
    recording: RecordingSection | None = None
    ipr: IprSection | None = None

    def as_dict(self) -> dict:
        """JSON-able form, the inverse of :func:`scenario_from_dict` (the fields its flow
        does not use left out, and ``recording`` and ``ipr`` where there are none)."""
        spec = asdict(self)
        spec["flow"] = self.flow.as_dict()
        for optional in ("recording", "ipr"):
            if getattr(self, optional) is None:
                del spec[optional]
        return spec

    def with_seed(self, seed: int) -> "Scenario":
        """The same scenario with another seed."""
        return replace(self, seed=int(seed))


_SECTIONS = {
    "flow": FlowSection,
    "rig": RigSection,
    "calibration": CalibrationSection,
    "particles": ParticlesSection,
    "sensor": Sensor,
    "ptv": PtvSection,
    "checks": ChecksSection,
    "output": OutputSection,
}


#: (lowest, highest, why) of every size a scenario or a command line may ask for.
SIZE_LIMITS = {
    "modes": (1, 10_000, " (a KS field of 10⁴ modes already resolves 4 decades)"),
    "planes": (3, 200, ""),
    "count": (1, 100_000, " (10⁵ tracers are 0.045 particles per pixel on 2048 × 1088)"),
    "frames": (2, 100_000, " (10⁵ frame pairs per Δt would take days)"),
    "n_bins": (1, 1_000, ""),
}


def _check(scenario: Scenario, source: str, given: set[str]) -> None:
    def fail(message: str):
        raise ScenarioError(f"{source}: {message}")

    check_flow(scenario.flow, fail)
    for where, methods in (
        ("calibration.methods", scenario.calibration.methods),
        ("ptv.methods", scenario.ptv.methods),
    ):
        unknown = [m for m in methods if m not in CALIBRATION_METHODS]
        if unknown:
            fail(f"{where}: unknown method(s) {unknown}; known: {', '.join(CALIBRATION_METHODS)}")
    if not scenario.ptv.methods:
        fail("ptv.methods must name at least one calibration method")
    missing = [m for m in scenario.ptv.methods if m not in scenario.calibration.methods]
    if missing:
        fail(f"ptv.methods {missing} are not in calibration.methods")
    if scenario.calibration.plate not in ("realistic", "ideal"):
        fail(
            f"calibration.plate must be 'realistic' or 'ideal', got {scenario.calibration.plate!r}"
        )
    for where, value, (minimum, maximum, why) in (
        ("flow.modes", scenario.flow.modes, SIZE_LIMITS["modes"]),
        ("calibration.planes", scenario.calibration.planes, SIZE_LIMITS["planes"]),
        ("particles.count", scenario.particles.count, SIZE_LIMITS["count"]),
        ("particles.frames", scenario.particles.frames, SIZE_LIMITS["frames"]),
        ("ptv.n_bins", scenario.ptv.n_bins, SIZE_LIMITS["n_bins"]),
    ):
        if not minimum <= value <= maximum:
            fail(f"{where} must be from {minimum} to {maximum}{why}, got {value}")
    for where, value in (
        ("particles.electrons", scenario.particles.electrons),
        ("particles.diameter", scenario.particles.diameter),
        ("calibration.brightness", scenario.calibration.brightness),
    ):
        if not value > 0:
            fail(f"{where} must be > 0, got {value}")
    if scenario.ptv.min_cameras is not None and scenario.ptv.min_cameras < 2:
        fail(f"ptv.min_cameras must be at least 2, got {scenario.ptv.min_cameras}")
    if len(scenario.ptv.analysis_size) != 3 or min(scenario.ptv.analysis_size) <= 0:
        fail(f"ptv.analysis_size must be 3 sizes > 0, m, got {scenario.ptv.analysis_size}")
    for where, value in (
        ("checks.c1_r_min_eta", scenario.checks.c1_r_min_eta),
        ("checks.c1_r_max_l_int", scenario.checks.c1_r_max_l_int),
    ):
        if not value > 0:
            fail(f"{where} must be > 0, got {value}")
    for where, (lo, hi) in (
        ("ptv.r_min and ptv.r_max", (scenario.ptv.r_min, scenario.ptv.r_max)),
        ("ptv.plateau", scenario.ptv.plateau),
    ):
        if not 0 < lo < hi:
            fail(f"{where} must be [low, high] with 0 < low < high, m, got {[lo, hi]}")
    if {"r_min", "r_max", "plateau", "analysis_size"} & given:  # else derived, checked later
        _check_separations(scenario, source)
    if scenario.flow.kind == "dns":
        half = dns_box_side(scenario.flow) / 2
        missing = [name for name in ("r_min", "r_max", "plateau") if name not in given]
        if missing:
            fail(
                f"ptv.{' and ptv.'.join(missing)}: a DNS must give them: its integral length "
                f"is measured only once it runs, and half its box ({half * 1e3:.4g} mm, "
                f"{half / dns_eta(scenario.flow):.0f}η) leaves no 40η … L_int/2 range to derive "
                "them from (the dns-ci scenario gives r_min 1 mm, r_max 25 mm, plateau 2–20 mm)"
            )
        if scenario.ptv.r_max > half:
            fail(
                f"ptv.r_max reaches {scenario.ptv.r_max * 1e3:g} mm, beyond half the DNS "
                f"box ({half * 1e3:.4g} mm), where the box's periodic images correlate the "
                "pairs (docs/dns.md §8)"
            )
    try:
        pipeline_settings(scenario)
    except ValueError as err:
        fail(f"ptv: {err}")


def scenario_from_dict(spec: dict, *, source: str = "scenario") -> Scenario:
    """A validated scenario from a parsed TOML (or :meth:`Scenario.as_dict`) table.

    Raises
    ------
    ScenarioError
        Unknown or ill-typed fields, unknown presets or methods, impossible sizes.
    """
    if "name" not in spec or not isinstance(spec["name"], str):
        raise ScenarioError(f"{source}: a scenario needs a 'name' string")
    if not is_file_name(spec["name"]):
        raise ScenarioError(f"{source}: name must be {FILE_NAME_RULE}, got {spec['name']!r}")
    spec = renamed_keys(spec, source)
    optional = {"recording", "ipr"}
    unknown = sorted(set(spec) - {"name", "description", "seed", *optional, *_SECTIONS})
    if unknown:
        raise ScenarioError(
            f"{source}: unknown table(s) or field(s) {', '.join(map(repr, unknown))}"
        )
    seed = spec.get("seed", 0)
    if not isinstance(seed, int) or isinstance(seed, bool) or seed < 0:
        raise ScenarioError(f"{source}: seed must be an integer >= 0, got {seed!r}")
    sections = {
        key: flow_section(spec.get(key, {}), source)
        if cls is FlowSection
        else section(cls, spec.get(key, {}), source, key)
        for key, cls in _SECTIONS.items()
    }
    description = spec.get("description", "")
    if not isinstance(description, str):
        raise ScenarioError(f"{source}: description must be a string, got {description!r}")
    if "recording" in spec:
        sections["recording"] = section(RecordingSection, spec["recording"], source, "recording")
    if "ipr" in spec:
        sections["ipr"] = section(IprSection, spec["ipr"], source, "ipr")
    scenario = Scenario(name=spec["name"], description=description, seed=seed, **sections)
    _check(scenario, source, set(spec.get("ptv", {})))
    if scenario.recording is not None:
        check_recording(scenario, source)
    return scenario


def scenario_presets() -> list[str]:
    """Names of the scenario presets shipped with synptv.

    Returns
    -------
    list of str
        Sorted; each loads with :func:`load_scenario` (docs/run.md §2).

    Examples
    --------
    >>> import validation
    >>> validation.scenario_presets()
    ['box-3cam', 'ci', 'default', 'dense', 'dense-ci', 'dns', 'dns-ci', 'paper-10hz',
     'paper-12hz', 'paper-8hz', 'slow-4cam', 'slow-dense', 'slow-unequal', 'tr', 'tr-ci',
     'tr-dns']
    """
    folder = resources.files("validation") / "scenarios"
    return sorted(
        p.name.removesuffix(".toml") for p in folder.iterdir() if p.name.endswith(".toml")
    )


def load_scenario(name_or_path: str | Path) -> Scenario:
    """A preset scenario by name, or a scenario file by path.

    A rig given as a relative ``.toml`` path in a scenario file is taken relative to
    that file. The PTV ranges a file leaves out (``[ptv]`` analysis_size, r_min, r_max,
    plateau) follow its rig and flow (:mod:`validation.run.derived_ptv`).

    Parameters
    ----------
    name_or_path : str or Path
        A name of :func:`scenario_presets`, or a scenario TOML file.

    Returns
    -------
    Scenario

    Raises
    ------
    ScenarioError
        Unknown preset, missing or invalid file.

    Examples
    --------
    A scenario file of one's own: the box-3cam rig, 500 tracers, 4 frame pairs per Δt;
    the rest takes its defaults and the ranges of the analysis follow the flow:

    >>> import pathlib, tempfile
    >>> import validation
    >>> tmp = tempfile.TemporaryDirectory()
    >>> path = pathlib.Path(tmp.name) / "small.toml"
    >>> _ = path.write_text('''
    ... name = "small"
    ... [rig]
    ... name = "box-3cam"
    ... [particles]
    ... count = 500
    ... frames = 4
    ... ''')
    >>> scenario = validation.load_scenario(path)
    >>> scenario.rig.name, scenario.particles.count, scenario.flow.label
    ('box-3cam', 500, 'lem-10hz')
    >>> [round(r * 1e3, 2) for r in (scenario.ptv.r_min, scenario.ptv.r_max)]  # bins' edges, mm
    [0.49, 35.0]
    >>> validation.load_scenario("fast")
    Traceback (most recent call last):
    ...
    validation.run.scenario_fields.ScenarioError: unknown scenario 'fast'; presets: ...
    >>> tmp.cleanup()
    """
    path = Path(name_or_path)
    if path.suffix == ".toml" or path.exists():
        if not path.is_file():
            what = "is a folder, not a file" if path.is_dir() else "does not exist"
            raise ScenarioError(f"scenario file {str(path)!r} {what}")
        source = str(path)
        try:
            text = path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as err:
            raise ScenarioError(f"{source}: not readable as a UTF-8 text file ({err})") from None
    else:
        presets = scenario_presets()
        if str(name_or_path) not in presets:
            raise ScenarioError(
                f"unknown scenario {str(name_or_path)!r}; presets: {', '.join(presets)} "
                "(or a .toml path)"
            )
        text = (resources.files("validation") / "scenarios" / f"{name_or_path}.toml").read_text()
        source, path = f"{name_or_path}.toml", None
    try:
        spec = tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise ScenarioError(f"{source}: not valid TOML: {err}") from None
    spec = renamed_keys(spec, source)
    scenario = scenario_from_dict(spec, source=source)
    rig = Path(scenario.rig.name)
    if path is not None and rig.suffix == ".toml" and not rig.is_absolute():
        rig = path.parent / rig
        scenario = replace(scenario, rig=RigSection(str(rig)))
    if scenario.rig.name not in rig_presets() and not rig.is_file():
        raise ScenarioError(
            f"{source}: rig.name: unknown rig {scenario.rig.name!r}, neither a rig preset "
            f"({', '.join(rig_presets())}) nor a rig file"
        )
    try:
        loaded = load_rig(scenario.rig.name)  # a bad rig is refused now, not in the run
    except RigFileError as err:
        raise ScenarioError(f"{source}: rig.name: {err}") from None
    cameras = loaded.cameras
    if scenario.ipr is not None:
        check_ipr(scenario, source, len(cameras))
        check_ipr_memory(scenario, source, sensor_pixels(cameras))
    given = set(spec.get("ptv", {}))
    if not given.issuperset(DERIVED_FIELDS):
        scales = None
        if scenario.flow.kind == "ks":
            parameters = scenario.flow.as_preset().parameters
            scales = {"eta": parameters.eta, "L_int": parameters.L_int}
        scenario = derive_ptv_ranges(scenario, given, loaded.sheet.size, scales, source)
        _check_separations(scenario, source)
    if scenario.flow.kind == "ks" and not scenario.particles.shared_first_frame:
        u_rms = scenario.flow.as_preset().parameters.u_rms
        independent_pair_ambiguity(scenario, loaded.sheet.size, u_rms, source)
    if scenario.flow.kind == "grid":
        scenario = _checked_field_file(scenario, path, source)
    if scenario.ptv.min_cameras is not None and scenario.ptv.min_cameras > len(cameras):
        raise ScenarioError(
            f"{source}: ptv.min_cameras is {scenario.ptv.min_cameras} but rig "
            f"{scenario.rig.name!r} has {len(cameras)} cameras"
        )
    return scenario


def _check_separations(scenario: Scenario, source: str, eta: float | None = None) -> None:
    """Refuse separations no pair of the analysis volume can have (beyond its diagonal)
    and a plateau or r range starting below η (the flow's, or ``eta``; a field file's η
    is known once it is read)."""

    def fail(message: str):
        raise ScenarioError(f"{source}: {message}")

    diagonal = float(np.linalg.norm(scenario.ptv.analysis_size))
    for where, (_, hi) in (
        ("ptv.r_max", (scenario.ptv.r_min, scenario.ptv.r_max)),
        ("ptv.plateau", scenario.ptv.plateau),
    ):
        if hi > diagonal:
            fail(
                f"{where} reaches {hi * 1e3:g} mm, beyond the {diagonal * 1e3:.4g} mm diagonal "
                "of ptv.analysis_size: no pair is that far apart"
            )
    if eta is None:
        if scenario.flow.kind == "grid":
            return
        eta = (
            dns_eta(scenario.flow)
            if scenario.flow.kind == "dns"
            else scenario.flow.as_preset().parameters.eta
        )
    for where, (lo, _) in (
        ("ptv.r_min", (scenario.ptv.r_min, scenario.ptv.r_max)),
        ("ptv.plateau", scenario.ptv.plateau),
    ):
        if lo < eta:
            fail(
                f"{where} starts at {lo * 1e3:g} mm, below the flow's Kolmogorov length "
                f"η = {eta * 1e3:.3g} mm"
            )


def _checked_field_file(scenario: Scenario, path: Path | None, source: str) -> Scenario:
    """A ``grid`` flow's file resolved (relative to the scenario file) and read as a run
    will read it, its separations checked against half its box."""
    from validation.run.grid_flow import grid_run_flow  # reads the file: only for a grid

    file = Path(scenario.flow.file)
    if path is not None and not file.is_absolute():
        scenario = replace(scenario, flow=replace(scenario.flow, file=str(path.parent / file)))
    try:
        run_flow = grid_run_flow(scenario.flow, scenario.particles.frames)
    except ValueError as err:
        raise ScenarioError(f"{source}: flow.file: {err}") from None
    _check_separations(scenario, source, eta=run_flow.preset.parameters.eta)
    half = run_flow.scales["box_side"] / 2
    if scenario.ptv.r_max > half:
        raise ScenarioError(
            f"{source}: ptv.r_max reaches {scenario.ptv.r_max * 1e3:g} mm, beyond half "
            f"the file's periodic box ({half * 1e3:.4g} mm), where its periodic images "
            "correlate the pairs (docs/dns.md §8)"
        )
    return scenario


def pipeline_settings(scenario: Scenario) -> PipelineSettings:
    """The PTV options of a scenario (analysis box centred on the origin)."""
    p = scenario.ptv
    half = np.asarray(p.analysis_size) / 2
    return PipelineSettings(
        max_speed=p.max_speed,
        tolerance=p.tolerance,
        min_cameras=p.min_cameras,
        statistics=StatisticsSettings(
            analysis_volume=(-half, half),
            r_min=p.r_min,
            r_max=p.r_max,
            n_bins=p.n_bins,
            plateau=p.plateau,
            kolmogorov_c2=p.kolmogorov_c2,
            n_boot=p.n_boot,
            seed=scenario.seed,
        ),
    )
