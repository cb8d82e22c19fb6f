"""The virtual laboratory's ground truth: flows, tracers, rigs, cameras and their images.

``simulator`` imports neither ``ptv`` nor ``validation``: it is the world the PTV stack
measures, and only ``validation`` puts the two side by side.

The names below are the public API, importable as ``simulator.<name>``; each is loaded
on first use, so ``import simulator`` stays cheap. Units are SI (m, s, m/s, angles in
rad; a rig file's ``*_deg`` fields in degrees), pixels (px, x = column, y = row, (0, 0)
the centre of the top-left pixel), photo-electrons (e⁻) and grey levels (DN). The world
frame has its origin at the sheet's centre, Z normal to the sheet and Y up
(docs/conventions.md §3).

Kinematic-simulation flow (docs/flow.md)
    TurbulenceParameters  u′, ε, ν and the scales they give: η, τ_η, R_λ, L_int
    FlowPreset            a named flow condition: its parameters and its Δt set
    flow_preset           the paper's conditions by name: lem-8hz, lem-10hz, lem-12hz
    PopeSpectrum          Pope's model spectrum fitted to u′, ε, ν (the default)
    KolmogorovBandSpectrum  E ∝ k^(−5/3) on a band fitted to u′, ε, ν
    draw_ks_field         one random realization of a spectrum
    KSField               its exact velocity, gradient and Lagrangian acceleration
    exact_dll             the exact D_LL(r) of a spectrum (simulator.truth)

Tracers (docs/flow.md §6)
    Box                   an axis-aligned box: the sheet, a seeding volume (m)
    KSFlow                kinematic simulation as a tracer flow, a realization per snapshot
    follow_snapshots      tracers of independent snapshots followed over given times
    double_frame          frame pairs, one independent experiment per Δt
    shared_start          frame pairs at every Δt from a shared first frame
    follow_recording      tracers carried through the sheet over a recording's frames

Navier–Stokes DNS (docs/dns.md)
    dns_setup             the grid and box of a DNS from ν, ε, N and k_max η
    NavierStokesSolver    forced pseudo-spectral Navier–Stokes on a periodic grid
    ConstantPowerForcing  the forcing that injects a prescribed power ε
    initial_state         a random divergence-free start of a given spectrum shape
    spin_up               steps at the CFL limit for a number of eddy times
    stationary_flow       a flow spun up from noise and independent snapshots of it
    follow_dns_tracers    tracers advanced together with the flow
                          (simulator.dns.tracers.follow_tracers)

Field files and the grid flow (docs/dns.md §9, §12)
    PeriodicFieldSeries   velocity fields of a periodic box at several times
    write_field_file      a series written to an HDF5 field file
    read_field_file       a field file read and checked
    field_file_scales     u′, L_int, T_L and the time step of a field file
                          (simulator.dns.series_flow.series_scales)
    SeriesTracerFlow      tracers in a field file's flow (a scenario's ``kind = "grid"``)

Rigs (docs/rigs.md)
    rig_presets           the names of the rigs shipped with synptv
    load_rig              a rig by preset name or TOML file, checked field by field
    rig_from_dict         a rig from a parsed rig table
    Rig                   cameras and their names, the laser sheet and the tank

Cameras (docs/optics.md)
    Lens                  pinhole, Brown–Conrady distortion and a tilted sensor
    Camera                pose, lens and windows: project (point → px), pixel_to_ray
    look_at_camera        a camera placed by its distance and direction to a point
    WindowSpec            a flat window placed relative to a camera's line of sight
    flat_window           an air | glass | water window fixed in the world
    focus_on_plane        a camera refocused on a plane, with a Scheimpflug tilt

Rendering (docs/imaging.md, docs/render.md)
    render_particles      Gaussian spots integrated over the pixels: expected e⁻ per px
    Sensor                shot noise, read noise, full well and ADC: e⁻ to DN
    ParticleLighting      tracer diameter, laser-sheet profile and brightness
    rig_lighting          the lighting of a rig's sheet (Gaussian or top-hat)
    record_particles      the frame a camera records of particles at given positions

The first frame of a rig's cameras, for KS tracers (what ``synptv render`` does for
every camera, frame and Δt)::

    import simulator

    rig = simulator.load_rig("paper-stereo")
    preset = simulator.flow_preset("lem-10hz")
    flow = simulator.KSFlow(simulator.PopeSpectrum(preset.parameters))
    sample = simulator.shared_start(flow, preset.dt, particles=1000, snapshots=2,
                                    region=rig.sheet, rng=0)
    positions = sample.runs[0].positions[0, 0]  # Δt_0, snapshot 0, frame a: (P, 3), m
    lighting = simulator.rig_lighting(simulator.ParticleLighting(), rig)
    for name, camera in zip(rig.camera_names, rig.cameras):
        frame = simulator.record_particles(camera, positions, lighting=lighting,
                                           sensor=simulator.Sensor(), rng=0)
        print(name, frame.image.shape, frame.visible.sum())  # (H, W) DN, particles seen

Every name's docstring has examples on small inputs; the modules hold the rest of the
laboratory (``simulator.target`` and ``simulator.render.plate``: the calibration plate
and its images; ``simulator.scene``: the picture of a rig).
"""

from importlib import import_module

#: Public name → (module, name there). Kept out of the namespace until first use: the
#: flows and the renderer import numba, SciPy and h5py, about a second together.
_EXPORTS = {
    # kinematic-simulation flow
    "TurbulenceParameters": ("simulator.turbulence", "TurbulenceParameters"),
    "FlowPreset": ("simulator.presets", "FlowPreset"),
    "flow_preset": ("simulator.presets", "flow_preset"),
    "PopeSpectrum": ("simulator.spectra", "PopeSpectrum"),
    "KolmogorovBandSpectrum": ("simulator.spectra", "KolmogorovBandSpectrum"),
    "draw_ks_field": ("simulator.ks_field", "draw_ks_field"),
    "KSField": ("simulator.ks_field", "KSField"),
    "exact_dll": ("simulator.truth", "longitudinal_structure_function"),
    # tracers
    "Box": ("simulator.particles", "Box"),
    "KSFlow": ("simulator.particles", "KSFlow"),
    "follow_snapshots": ("simulator.particles", "follow_snapshots"),
    "double_frame": ("simulator.particles", "double_frame"),
    "shared_start": ("simulator.particles", "shared_start"),
    "follow_recording": ("simulator.recording", "follow_recording"),
    # Navier–Stokes DNS
    "dns_setup": ("simulator.dns.grid", "dns_setup"),
    "NavierStokesSolver": ("simulator.dns.solver", "NavierStokesSolver"),
    "ConstantPowerForcing": ("simulator.dns.forcing", "ConstantPowerForcing"),
    "initial_state": ("simulator.dns.spinup", "initial_state"),
    "spin_up": ("simulator.dns.spinup", "spin_up"),
    "stationary_flow": ("simulator.dns.spinup", "stationary_flow"),
    "follow_dns_tracers": ("simulator.dns.tracers", "follow_tracers"),
    # field files and the grid flow
    "PeriodicFieldSeries": ("simulator.dns.fieldfile", "PeriodicFieldSeries"),
    "write_field_file": ("simulator.dns.fieldfile", "write_field_file"),
    "read_field_file": ("simulator.dns.fieldfile", "read_field_file"),
    "field_file_scales": ("simulator.dns.series_flow", "series_scales"),
    "SeriesTracerFlow": ("simulator.dns.series_flow", "SeriesTracerFlow"),
    # rigs
    "rig_presets": ("simulator.rigs", "rig_presets"),
    "load_rig": ("simulator.rigs", "load_rig"),
    "rig_from_dict": ("simulator.rigs", "rig_from_dict"),
    "Rig": ("simulator.rigs", "Rig"),
    # cameras
    "Lens": ("simulator.optics.lens", "Lens"),
    "Camera": ("simulator.optics.camera", "Camera"),
    "look_at_camera": ("simulator.optics.placement", "look_at_camera"),
    "WindowSpec": ("simulator.optics.placement", "WindowSpec"),
    "flat_window": ("simulator.optics.interfaces", "flat_window"),
    "focus_on_plane": ("simulator.optics.scheimpflug", "focus_on_plane"),
    # rendering
    "render_particles": ("simulator.render.particle_images", "render_particles"),
    "Sensor": ("simulator.render.sensor", "Sensor"),
    "ParticleLighting": ("simulator.render.camera_frames", "ParticleLighting"),
    "rig_lighting": ("simulator.render.camera_frames", "rig_lighting"),
    "record_particles": ("simulator.render.camera_frames", "record_particles"),
}

__all__ = list(_EXPORTS)


def __getattr__(name: str) -> object:
    """The public object ``name``, imported from its module on first use (PEP 562)."""
    try:
        module, attribute = _EXPORTS[name]
    except KeyError:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}") from None
    value = getattr(import_module(module), attribute)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    """The module's names and the public ones not loaded yet (for ``dir`` and ``help``)."""
    return sorted(set(globals()) | set(__all__))
