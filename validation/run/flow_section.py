"""A scenario's ``[flow]``: kinematic simulation (a preset or custom), a Navier–Stokes
simulation, or a periodic field file (docs/run.md §7, docs/dns.md).

``kind = "ks"`` (the default) is kinematic simulation: a preset of the paper's Table 3,
or a custom flow of ``u_rms``, ``epsilon``, ``nu`` and a Δt set, with the KS options
``spectrum``, ``modes`` and ``unsteadiness``. ``kind = "dns"`` is a forced DNS in a
periodic box: ``epsilon`` (the injected power), ``nu``, ``grid`` (N), ``kmax_eta``
(default 1.5), ``spacing`` (snapshots apart, in eddy times T_L = L_int/u′; default 1)
and the Δt set; u′, R_λ and the box side follow from them (the box from ν, ε, N and
k_max η; u′ and R_λ measured when the flow has run). ``kind = "grid"`` reads the
periodic field time series of a file (``file``, docs/dns.md §10) and a Δt set. A field
of another kind is refused by name.
"""

from dataclasses import dataclass, fields, replace
from itertools import pairwise
from pathlib import Path

from simulator.dns.grid import dns_setup
from simulator.ks_field import DEFAULT_UNSTEADINESS
from simulator.presets import FLOW_PRESETS, FlowPreset, flow_preset
from simulator.spectra import SPECTRA
from simulator.turbulence import NU_WATER, TurbulenceParameters
from validation.run.scenario_fields import ScenarioError, section, typed

#: The kinds of flow a scenario can have.
FLOW_KINDS = ("ks", "dns", "grid")

#: The fields of a custom flow, given instead of a preset.
CUSTOM_FLOW_FIELDS = ("u_rms", "epsilon", "nu", "dt", "dt_tau_eta")

#: Fields that only kinematic simulation reads.
KS_FIELDS = ("preset", "spectrum", "modes", "unsteadiness", "u_rms")

#: The optional fields each kind may give (beside its Δt set), with their types.
KIND_FIELDS = {
    "ks": {"u_rms": float, "epsilon": float, "nu": float},
    "dns": {"epsilon": float, "nu": float, "grid": int, "kmax_eta": float, "spacing": float},
    "grid": {"file": str},
}

#: A kind's own options, written beside its scales (:meth:`FlowSection.scales`).
_OWN_OPTIONS = {
    "ks": ("spectrum", "modes", "unsteadiness"),
    "dns": ("kind", "grid", "kmax_eta", "spacing"),
    "grid": ("kind", "file"),
}

#: (fewest, most) Δt of a custom flow: the multi-Δt fit needs two, each is a run.
DT_COUNT = (2, 20)

#: (lowest, highest, unit) of the numbers of a flow: water, air, oils and liquid metals
#: stirred in a lab.
FLOW_LIMITS = {
    "u_rms": (1e-4, 10.0, "m/s"),
    "epsilon": (1e-8, 1e3, "m²/s³"),
    "nu": (1e-7, 1e-2, "m²/s"),
    "dt": (1e-7, 10.0, "s"),
    "dt_tau_eta": (1e-3, 1e3, "Kolmogorov times"),
    "unsteadiness": (0.0, 10.0, "(λ in ω_n = λ √(k³E))"),
    "kmax_eta": (1.0, 8.0, "(k_max η below 1 under-resolves the gradients)"),
    "spacing": (1.0, 100.0, "eddy times (snapshots at least one T_L apart are independent)"),
}

#: Default k_max η and snapshot spacing (eddy times) of a DNS flow.
DEFAULT_KMAX_ETA = 1.5
DEFAULT_SPACING = 1.0


@dataclass(frozen=True)
class FlowSection:
    """The turbulence (module docstring).

    The fields a kind does not use are None (``preset`` too, for a custom, DNS or file
    flow).

    Raises
    ------
    ValueError
        A field of another kind, a preset with custom fields, a custom flow without
        u_rms or epsilon, a DNS without epsilon or grid, a file flow without its file,
        not exactly one of dt and dt_tau_eta, a Δt set not increasing or not positive;
        the message names the field (``flow.<field>``).
    """

    preset: str | None = "lem-10hz"
    spectrum: str = "pope"
    modes: int = 200
    unsteadiness: float = DEFAULT_UNSTEADINESS
    u_rms: float | None = None
    epsilon: float | None = None
    nu: float | None = None
    dt: tuple[float, ...] | None = None
    dt_tau_eta: tuple[float, ...] | None = None
    kind: str = "ks"
    grid: int | None = None
    kmax_eta: float | None = None
    spacing: float | None = None
    file: str | None = None

    def __post_init__(self) -> None:
        if self.kind not in FLOW_KINDS:
            raise ValueError(f"flow.kind must be one of {', '.join(FLOW_KINDS)}, got {self.kind!r}")
        optional = {n for names in KIND_FIELDS.values() for n in names}
        stray = sorted(n for n in optional - set(KIND_FIELDS[self.kind]) if getattr(self, n))
        if stray:
            raise ValueError(
                f"flow.{stray[0]} is not a field of a {self.kind!r} flow (flow.kind = "
                f"{self.kind!r}; docs/run.md §7)"
            )
        if self.kind == "ks":
            self._check_ks()
            return
        if self.preset is not None or self.u_rms is not None:
            name = "preset" if self.preset is not None else "u_rms"
            raise ValueError(
                f"flow.{name} is a field of kinematic simulation, not of a {self.kind!r} flow"
                + (" (its u' is measured)" if self.kind == "dns" else "")
            )
        if self.kind == "dns":
            for name in ("epsilon", "grid"):
                if getattr(self, name) is None:
                    raise ValueError(f"flow.{name}: a DNS flow needs epsilon (m²/s³) and grid (N)")
            object.__setattr__(self, "nu", NU_WATER if self.nu is None else self.nu)
            object.__setattr__(
                self, "kmax_eta", DEFAULT_KMAX_ETA if self.kmax_eta is None else self.kmax_eta
            )
            object.__setattr__(
                self, "spacing", DEFAULT_SPACING if self.spacing is None else self.spacing
            )
        elif self.file is None:
            raise ValueError("flow.file: a 'grid' flow needs the periodic field file it reads")
        self._check_dt()

    def _check_ks(self) -> None:
        custom = [name for name in CUSTOM_FLOW_FIELDS if getattr(self, name) is not None]
        if self.preset is not None:
            if custom:
                raise ValueError(
                    f"flow.preset {self.preset!r} and the custom flow's {', '.join(custom)} "
                    "exclude each other: give a preset or u_rms, epsilon, nu and a Δt set"
                )
            return
        missing = [name for name in ("u_rms", "epsilon") if getattr(self, name) is None]
        if missing:
            raise ValueError(
                f"flow.{missing[0]}: a custom flow needs u_rms (m/s) and epsilon (m²/s³), "
                f"missing {', '.join(missing)} (or give a preset)"
            )
        if self.nu is None:
            object.__setattr__(self, "nu", NU_WATER)
        self._check_dt()

    def _check_dt(self) -> None:
        given = [name for name in ("dt", "dt_tau_eta") if getattr(self, name) is not None]
        if len(given) != 1:
            raise ValueError(
                f"flow.dt: a {'custom' if self.kind == 'ks' else self.kind} flow needs "
                f"exactly one of dt (s) and dt_tau_eta (Kolmogorov times), got "
                f"{' and '.join(given) if given else 'neither'}"
            )
        name = given[0]
        values = getattr(self, name)
        if not DT_COUNT[0] <= len(values) <= DT_COUNT[1]:
            raise ValueError(
                f"flow.{name} must hold {DT_COUNT[0]} to {DT_COUNT[1]} values (the multi-Δt "
                f"fit needs two), got {list(values)}"
            )
        if not (values[0] > 0 and all(a < b for a, b in pairwise(values))):
            raise ValueError(f"flow.{name} must be > 0 and strictly increasing, got {list(values)}")

    def as_preset(self, parameters: TurbulenceParameters | None = None) -> FlowPreset:
        """The flow as a :class:`simulator.presets.FlowPreset`: the preset, or a custom
        flow named ``"custom"`` whose Δt set is given in units of its τ_η. A DNS or file
        flow needs its ``parameters`` (u′ measured, ε, ν: the flow stage's) and is named
        by its kind.

        Raises
        ------
        ValueError
            An unknown preset name; a DNS or file flow without its parameters.
        """
        if self.preset is not None:
            return flow_preset(self.preset)
        if self.kind != "ks":
            if parameters is None:
                raise ValueError(
                    f"a {self.kind!r} flow's u' is measured: its parameters come from its "
                    "flow stage"
                )
        else:
            parameters = TurbulenceParameters(u_rms=self.u_rms, epsilon=self.epsilon, nu=self.nu)
        ratios = self.dt_tau_eta
        if ratios is None:
            ratios = tuple(d / parameters.tau_eta for d in self.dt)
        name = "custom" if self.kind == "ks" else self.kind
        return FlowPreset(name, parameters, ratios, "scenario [flow]")

    @property
    def label(self) -> str:
        """The preset name, ``custom`` with u' and ε, or the DNS or file, for titles."""
        if self.preset is not None:
            return self.preset
        if self.kind == "dns":
            return f"DNS {self.grid}^3 (epsilon = {self.epsilon:g} m^2/s^3, nu = {self.nu:g})"
        if self.kind == "grid":
            return f"field file {Path(self.file).name}"
        return f"custom (u' = {self.u_rms:g} m/s, epsilon = {self.epsilon:g} m^2/s^3)"

    def scales(self, parameters: TurbulenceParameters | None = None) -> dict:
        """The flow and its derived scales, SI units, for logs and JSON files.

        Parameters
        ----------
        parameters : TurbulenceParameters, optional
            A DNS or file flow's (from its flow stage).

        Returns
        -------
        dict
            ``preset`` (``"custom"``, ``"dns"`` or ``"grid"`` when there is none); u_rms
            (m/s), epsilon (m²/s³), nu (m²/s) and the derived eta (m), tau_eta (s),
            R_lambda, L_int (m), taylor_microscale (m) of
            :meth:`simulator.turbulence.TurbulenceParameters.as_dict`; the Δt set as
            ``dt`` (s) and ``dt_over_tau_eta``; the kind's own options (spectrum, modes,
            unsteadiness for KS; kind, grid, kmax_eta, spacing for a DNS; kind and file).
        """
        flow = self.as_preset(parameters)
        own = {name: getattr(self, name) for name in _OWN_OPTIONS[self.kind]}
        return {
            "preset": flow.name,
            **flow.parameters.as_dict(),
            "dt": [float(d) for d in flow.dt],
            "dt_over_tau_eta": [float(r) for r in flow.dt_over_tau_eta],
            **own,
        }

    def describe(self, parameters: TurbulenceParameters | None = None) -> str:
        """One line: the flow, its Kolmogorov and integral scales, R_λ and the Δt set
        (a DNS before it has run: what its inputs prescribe; a field file before it is
        read: its name and the Δt set)."""
        if self.kind == "dns" and parameters is None:
            setup = dns_setup(self.nu, self.epsilon, self.grid, kmax_eta=self.kmax_eta)
            ratios = self.dt_tau_eta or tuple(d / setup.tau_eta for d in self.dt)
            dt = ", ".join(f"{r * setup.tau_eta * 1e3:.4g}" for r in ratios)
            return (
                f"flow DNS {self.grid}^3: epsilon = {self.epsilon:.4g} m^2/s^3, nu = "
                f"{self.nu:.3g} m^2/s, k_max eta = {self.kmax_eta:g}; eta = "
                f"{setup.eta * 1e6:.1f} um, tau_eta = {setup.tau_eta * 1e3:.3f} ms, box side "
                f"{setup.grid.box_side * 1e3:.4g} mm; u', R_lambda and T_L are measured; "
                f"dt = {dt} ms"
            )
        if self.kind == "grid" and parameters is None:
            dt = (
                f"{', '.join(f'{r:g}' for r in self.dt_tau_eta)} tau_eta"
                if self.dt_tau_eta
                else f"{', '.join(f'{d * 1e3:.4g}' for d in self.dt)} ms"
            )
            return (
                f"flow field file {self.file}: nu, epsilon and the box from the file, u' and "
                f"R_lambda measured on it; dt = {dt}"
            )
        s = self.scales(parameters)
        dt = ", ".join(f"{d * 1e3:.4g}" for d in s["dt"])
        return (
            f"flow {s['preset']}: u' = {s['u_rms']:.4g} m/s, epsilon = {s['epsilon']:.4g} "
            f"m^2/s^3, nu = {s['nu']:.3g} m^2/s; "
            f"eta = {s['eta'] * 1e6:.1f} um, tau_eta = {s['tau_eta'] * 1e3:.3f} ms, "
            f"R_lambda = {s['R_lambda']:.1f}, L_int = u'^3/eps = {s['L_int'] * 100:.2f} cm; "
            f"dt = {dt} ms"
        )

    def as_dict(self) -> dict:
        """JSON-able form: the fields this kind uses (``kind`` written only for a flow
        that is not KS, so that the files of KS runs stay as they were)."""
        out = {}
        for f in fields(self):
            value = getattr(self, f.name)
            if value is None or (f.name == "kind" and value == "ks"):
                continue
            if self.kind != "ks" and f.name in KS_FIELDS:
                continue
            out[f.name] = list(value) if isinstance(value, tuple) else value
        return out


def flow_section(table: object, source: str) -> FlowSection:
    """The [flow] table of ``source`` (:class:`FlowSection`)."""
    if not isinstance(table, dict):
        raise ScenarioError(f"{source}: [flow] must be a table")
    where = f"{source}: flow"
    kind = typed(table.get("kind", "ks"), str, f"{where}.kind")
    special = {n: t for names in KIND_FIELDS.values() for n, t in names.items()}
    given = {name: table[name] for name in (*special, "dt", "dt_tau_eta") if name in table}
    common = section(
        FlowSection,
        {k: v for k, v in table.items() if k not in given and k != "kind"},
        source,
        "flow",
    )
    if kind != "ks":
        given_ks = [n for n in KS_FIELDS if n in table]
        if given_ks:
            raise ScenarioError(
                f"{where}.{given_ks[0]}: a field of kinematic simulation, not of a {kind!r} "
                "flow (flow.kind)"
            )
    if not given and kind == "ks":
        return common
    values = {}
    for name, value in given.items():
        if name in ("dt", "dt_tau_eta"):
            if not isinstance(value, list | tuple):
                raise ScenarioError(f"{where}.{name} must be a list, got {value!r}")
            values[name] = tuple(typed(v, float, f"{where}.{name}") for v in value)
        else:
            values[name] = typed(value, special[name], f"{where}.{name}")
    try:
        return replace(
            common, kind=kind, preset=common.preset if "preset" in table else None, **values
        )
    except ValueError as err:
        raise ScenarioError(f"{source}: {err}") from None


def dns_eta(flow: FlowSection) -> float:
    """A DNS flow's Kolmogorov length from its inputs, η = (ν³/ε)^{1/4}, m."""
    return dns_setup(flow.nu, flow.epsilon, flow.grid, kmax_eta=flow.kmax_eta).eta


def dns_box_side(flow: FlowSection) -> float:
    """Side of a DNS flow's periodic box, L = 2πNη/(3 k_max η), m."""
    return dns_setup(flow.nu, flow.epsilon, flow.grid, kmax_eta=flow.kmax_eta).grid.box_side


def check_flow(flow: FlowSection, fail) -> None:
    """Refuse (through ``fail``) an unknown preset or spectrum, a flow out of
    :data:`FLOW_LIMITS`, a KS flow its spectrum cannot be fitted to, or a DNS whose grid
    or memory the machine cannot hold (checked before anything is allocated). A field
    file is checked once its path is resolved (:func:`check_field_file`)."""
    if flow.preset is not None and flow.preset not in FLOW_PRESETS:
        fail(f"flow.preset {flow.preset!r} unknown; known: {', '.join(FLOW_PRESETS)}")
    if flow.spectrum not in SPECTRA:
        fail(f"flow.spectrum {flow.spectrum!r} unknown; known: {', '.join(SPECTRA)}")
    for name, (lowest, highest, unit) in FLOW_LIMITS.items():
        value = getattr(flow, name)
        if value is None:
            continue
        for v in value if isinstance(value, tuple) else (value,):
            if not lowest <= v <= highest:
                fail(f"flow.{name} must be from {lowest:g} to {highest:g} {unit}, got {v:g}")
    if flow.kind == "ks" and flow.preset is None:
        try:
            SPECTRA[flow.spectrum](flow.as_preset().parameters)
        except ValueError as err:  # the solver's message may span lines: one line here
            why = " ".join(str(err).split())
            fail(f"flow: u_rms, epsilon and nu give no {flow.spectrum} spectrum: {why}")
    if flow.kind == "dns":
        try:
            dns_setup(flow.nu, flow.epsilon, flow.grid, kmax_eta=flow.kmax_eta)
        except ValueError as err:
            text = str(err)
            field = next((n for n in ("kmax_eta", "n", "nu", "epsilon") if n in text), "grid")
            fail(f"flow.{'grid' if field == 'n' else field}: {text}")
