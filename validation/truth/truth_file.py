"""``truth.h5``: the simulator's ground truth of a rendered dataset (ptv never reads it).

Layout (format version 3, whose rig has named distortion coefficients and a tank kind;
lengths in m, times in s, pixels as OpenCV)::

    /                       attrs: format_version, rig (the rig's JSON)
    /flow                   attrs: u', ε, ν and the derived scales, preset, dt,
                            dt_over_tau_eta, spectrum, n_modes, unsteadiness
    /cameras/<camera>       attrs: pupil centre, rotation, lens, tilt, window
    /plate                  z_nominal (N_Z,), z_actual (N_Z,), dots_world (N_Z, D, 3),
                            dot_indices (D, 2); per camera <camera>/dots_xy (N_Z, D, 2)
                            image of each dot centre, <camera>/dots_centroid (N_Z, D, 2)
                            centroid of its light, <camera>/dots_on_sensor (N_Z, D)
    /particles              attrs: shared_first_frame, frames (M, snapshots per Δt)
    /particles/dt<k>        attrs: dt
        positions_a, positions_b (M, P, 3)   X(t) and X(t + Δt_k), float64
        velocity (M, P, 3)                   u(X(t), t), m/s, float64
        <camera>/xy_a, <camera>/xy_b (M, P, 2)     exact image of each particle centre,
                                                   px, float32 (1e-4 px resolution); NaN
                                                   where not imaged
        <camera>/visible_a, <camera>/visible_b (M, P)   lit and on the sensor

With a shared first frame, ``positions_a``, ``velocity``, ``xy_a`` and ``visible_a`` of
every ``dt<k>`` are HDF5 hard links to those of ``dt0``: stored once. Without one, each
Δt is an independent experiment with its own P. The particle arrays are stored one
snapshot per HDF5 chunk, compressed without loss (gzip level 1, with the byte shuffle
for the floats): any HDF5 reader opens them.

:class:`TruthWriter` fills the file part by part (plate images, particle chunks, in any
order) and records each part as done only once its data are written, so a run
interrupted half-way resumes from the parts recorded. :class:`TruthFile` reads it back
one range of snapshots at a time.
"""

import json
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

from simulator.particles import DoubleFrameSample
from simulator.rigs import Rig, rig_from_dict
from simulator.spectra import SPECTRA
from simulator.turbulence import TurbulenceParameters
from validation.truth.exact import ExactStructure, ModalStructure, SpectrumStructure

FORMAT_VERSION = 3

#: Internal record of the parts written (deleted when the file is complete).
_PROGRESS = "progress"


@dataclass(frozen=True)
class TruthRun:
    """The truth of the run at one Δt over a range of snapshots.

    Attributes
    ----------
    dt : float
        s.
    positions : ndarray, shape (n, 2, P, 3)
        Particle positions at t and t + Δt, m.
    velocity : ndarray, shape (n, P, 3)
        Velocities at t, m/s.
    xy : dict of str to ndarray, shape (n, 2, P, 2)
        Exact image of every particle per camera, px (float32 as rendered and stored:
        1e-4 px resolution).
    visible : dict of str to ndarray of bool, shape (n, 2, P)
        Particle lit and its spot on the sensor.
    first : int
        Snapshot number of row 0 (rows are snapshots first, first + 1, …).
    """

    dt: float
    positions: np.ndarray
    velocity: np.ndarray
    xy: dict
    visible: dict
    first: int = 0

    @property
    def snapshots(self) -> range:
        """The snapshot numbers held."""
        return range(self.first, self.first + len(self.positions))


class TruthWriter:
    """Fills a truth.h5 part by part; every call opens, writes and closes the file.

    Parameters
    ----------
    path : Path
        The file; created with the header if it does not exist, else continued.
    header : callable(h5py.File), optional
        Writes the flow, cameras and rig when the file is created.
    cameras : sequence of str
        Camera names.
    planes : int
        Traverse positions of the plate.
    chunks : sequence of (int, int)
        The particle chunks (snapshot ranges) that will be written.
    frames : int
        Snapshots M per Δt.
    shared_first_frame : bool
        Frame a of snapshot m shared by every Δt.
    """

    def __init__(
        self,
        path: Path,
        *,
        header,
        cameras: Sequence[str],
        planes: int,
        chunks: Sequence[tuple[int, int]],
        frames: int,
        shared_first_frame: bool,
    ) -> None:
        self.path = Path(path)
        self.cameras = list(cameras)
        self.chunks = list(chunks)
        self.frames = frames
        self.shared = shared_first_frame
        if self.path.exists():
            try:
                with h5py.File(self.path, "r") as f:
                    ok = f.attrs.get("format_version") == FORMAT_VERSION and _PROGRESS in f
            except OSError:
                ok = False
            if ok:
                return
            self.path.unlink()  # unreadable (killed while writing): start again
        with h5py.File(self.path, "w") as f:
            f.attrs["format_version"] = FORMAT_VERSION
            header(f)
            progress = f.create_group(_PROGRESS)
            progress.create_dataset("plates", data=np.zeros((len(cameras), planes), bool))
            progress.create_dataset("chunks", data=np.zeros(len(self.chunks), bool))
            if self.chunks:  # a recording's plates only: its particles are in sequence<s>/
                group = f.create_group("particles")
                group.attrs["shared_first_frame"] = shared_first_frame
                group.attrs["frames"] = frames

    def done(self) -> tuple[np.ndarray, np.ndarray]:
        """Which plate images (C, N_Z) and particle chunks (n_chunks,) are written."""
        with h5py.File(self.path, "r") as f:
            return f[_PROGRESS]["plates"][:], f[_PROGRESS]["chunks"][:]

    def write_plate(self, c: int, j: int, projected, centroid, on_sensor, dots) -> None:
        """The truth of plate image j of camera c: dot images (D, 2), centroids (D, 2),
        on-sensor flags (D,); ``dots`` holds z_nominal, z_actual, dots_world and
        dot_indices (written with the first plate)."""
        with h5py.File(self.path, "a") as f:
            plate = f.require_group("plate")
            for key, value in dots.items():
                if key not in plate:
                    plate.create_dataset(key, data=value)
            planes = len(dots["z_nominal"])
            g = plate.require_group(self.cameras[c])
            for key, value, dtype in (
                ("dots_xy", projected, np.float64),
                ("dots_centroid", centroid, np.float64),
                ("dots_on_sensor", on_sensor, bool),
            ):
                value = np.asarray(value, dtype=dtype)
                ds = g.require_dataset(key, shape=(planes, *value.shape), dtype=dtype)
                ds[j] = value
            f[_PROGRESS]["plates"][c, j] = True

    def write_chunk(self, i: int, runs: Sequence[TruthRun]) -> None:
        """The particles of chunk i (one TruthRun per Δt)."""
        with h5py.File(self.path, "a") as f:
            for k, run in enumerate(runs):
                self._write_run(f, k, run)
            f[_PROGRESS]["chunks"][i] = True

    def _write_run(self, f: h5py.File, k: int, run: TruthRun) -> None:
        group = f.require_group(f"particles/dt{k}")
        group.attrs["dt"] = run.dt
        rows = slice(run.first, run.first + len(run.positions))
        arrays = {
            "positions_a": (run.positions[:, 0], np.float64),
            "positions_b": (run.positions[:, 1], np.float64),
            "velocity": (run.velocity, np.float64),
        }
        for camera in self.cameras:
            for f_index, frame in enumerate("ab"):
                arrays[f"{camera}/xy_{frame}"] = (run.xy[camera][:, f_index], np.float32)
                arrays[f"{camera}/visible_{frame}"] = (run.visible[camera][:, f_index], bool)
        for key, (value, dtype) in arrays.items():
            at_t = key.endswith("_a") or key == "velocity"
            if self.shared and k > 0 and at_t:  # frame a is dt0's: link it, once
                if key not in group:
                    group[key] = f[f"particles/dt0/{key}"]
                continue
            ds = group.require_dataset(
                key,
                shape=(self.frames, *value.shape[1:]),
                dtype=dtype,
                chunks=(1, *value.shape[1:]),
                compression="gzip",
                compression_opts=1,
                shuffle=dtype is not bool,
            )
            ds[rows] = np.asarray(value, dtype=dtype)

    def finish(self) -> None:
        """Check every part is written and drop the record of parts."""
        plates, chunks = self.done()
        if not (plates.all() and chunks.all()):
            raise RuntimeError(
                f"{self.path}: parts missing ({(~plates).sum()} plates, "
                f"{(~chunks).sum()} particle chunks)"
            )
        with h5py.File(self.path, "a") as f:
            del f[_PROGRESS]


class TruthFile:
    """Reads a truth.h5 (:data:`FORMAT_VERSION`) a range of snapshots at a time.

    Parameters
    ----------
    path : path-like
        The file, or the dataset folder holding it.

    Attributes
    ----------
    path : Path
        The file.
    rig : Rig
        The cameras and sheet the dataset was rendered with.
    frames : int
        Snapshots M per Δt.
    shared_first_frame : bool
        Frame a of snapshot m shared by every Δt.
    dt : ndarray, shape (K,)
        The Δt, s.

    Raises
    ------
    ValueError
        No truth.h5, or one of another format version.

    Examples
    --------
    The particles' truth of a dataset, written here as ``synptv render`` writes it (which
    adds the plate's and the images): 4 snapshots of KS tracers in the paper-stereo
    rig's sheet at the 10 Hz condition's three shortest Δt.

    >>> import json, pathlib, tempfile
    >>> import numpy as np
    >>> import simulator, validation
    >>> rig, preset = simulator.load_rig("paper-stereo"), simulator.flow_preset("lem-10hz")
    >>> flow = simulator.KSFlow(simulator.PopeSpectrum(preset.parameters), n_modes=50)
    >>> sample = simulator.shared_start(flow, preset.dt[:3], particles=300, snapshots=4,
    ...                                 region=rig.sheet, rng=0)
    >>> tmp = tempfile.TemporaryDirectory()
    >>> folder = pathlib.Path(tmp.name)
    >>> _ = validation.write_sample_truth(folder, rig, sample, preset.parameters)
    >>> truth = validation.TruthFile(folder)
    >>> truth.rig.camera_names, truth.frames, (truth.dt * 1e3).round(3)  # Δt in ms
    (('cam1', 'cam2'), 4, array([0.097, 0.194, 0.291]))
    >>> first = truth.runs(0, 2)[0]  # snapshots 0 and 1 at Δt_0
    >>> first.positions.shape, first.xy["cam1"].shape  # (n, 2, P, 3) m, (n, 2, P, 2) px
    ((2, 2, 324, 3), (2, 2, 324, 2))
    >>> tmp.cleanup()
    """

    def __init__(self, path) -> None:
        path = Path(path)
        if path.is_dir():
            path = path / "truth.h5"
        if not path.is_file():
            raise ValueError(
                f"{path.parent} has no truth.h5: reference runs need a synthetic dataset"
            )
        self.path = path
        with h5py.File(path, "r") as f:
            version = f.attrs.get("format_version")
            if version != FORMAT_VERSION:
                raise ValueError(
                    f"{path}: truth format version {version}, this synptv reads {FORMAT_VERSION}"
                    " (render the dataset again)"
                )
            self.rig: Rig = rig_from_dict(json.loads(f.attrs["rig"]), source=str(path))
            particles = f["particles"]
            self.frames = int(particles.attrs["frames"])
            self.shared_first_frame = bool(particles.attrs["shared_first_frame"])
            self.dt = np.array([particles[f"dt{k}"].attrs["dt"] for k in range(len(particles))])

    def flow(self) -> tuple[TurbulenceParameters, ExactStructure]:
        """The flow the dataset was simulated with: u', ε, ν, and its exact D_LL (of its
        KS spectrum, or of a DNS's modes, ``/flow/shell_k`` and ``/flow/shell_energy``)."""
        with h5py.File(self.path, "r") as f:
            group = f["flow"]
            attrs = group.attrs
            parameters = TurbulenceParameters(
                u_rms=float(attrs["u_rms"]), epsilon=float(attrs["epsilon"]), nu=float(attrs["nu"])
            )
            if "shell_k" in group:
                return parameters, ModalStructure(group["shell_k"][()], group["shell_energy"][()])
            return parameters, SpectrumStructure(SPECTRA[str(attrs["spectrum"])](parameters))

    def plate_dots(self) -> np.ndarray:
        """True centres of the plate's dots at every traverse position, (N_Z, D, 3), m."""
        with h5py.File(self.path, "r") as f:
            return f["plate/dots_world"][:]

    def runs(self, m0: int = 0, m1: int | None = None) -> list[TruthRun]:
        """The truth of snapshots m0 … m1 − 1 (default: all), one TruthRun per Δt."""
        m1 = self.frames if m1 is None else m1
        rows = slice(m0, m1)
        out = []
        with h5py.File(self.path, "r") as f:
            for k, dt in enumerate(self.dt):
                g = f[f"particles/dt{k}"]

                def pair(key, group=g):
                    return np.stack([group[f"{key}_a"][rows], group[f"{key}_b"][rows]], axis=1)

                out.append(
                    TruthRun(
                        dt=float(dt),
                        positions=pair("positions"),
                        velocity=g["velocity"][rows],
                        xy={c: pair(f"{c}/xy") for c in self.rig.camera_names},
                        visible={c: pair(f"{c}/visible") for c in self.rig.camera_names},
                        first=m0,
                    )
                )
        return out

    def snapshots_at_t(
        self, chunks: Sequence[tuple[int, int]], *, progress=None
    ) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        """Positions (P, 3) and velocities (P, 3) at t of every independent snapshot:
        those of Δt_0 with a shared first frame, of every Δt otherwise; read a chunk of
        snapshots (ranges m0, m1) at a time, ``progress(done, total)`` called after
        each."""
        groups = range(1 if self.shared_first_frame else len(self.dt))
        total = len(groups) * len(chunks)
        for k in groups:
            for i, (m0, m1) in enumerate(chunks):
                with h5py.File(self.path, "r") as f:
                    g = f[f"particles/dt{k}"]
                    x, u = g["positions_a"][m0:m1], g["velocity"][m0:m1]
                if progress is not None:
                    progress(k * len(chunks) + i + 1, total)
                yield from zip(x, u, strict=True)


def write_sample_truth(
    folder: str | Path,
    rig: Rig,
    sample: DoubleFrameSample,
    parameters: TurbulenceParameters,
    *,
    spectrum: str = "pope",
) -> Path:
    """The truth.h5 of a simulated sample as a rig's cameras see it, without images: what
    ``synptv score`` reads of a dataset, for positions a code computed some other way.

    Parameters
    ----------
    folder : str or Path
        The dataset folder (created if needed); ``truth.h5`` is written into it.
    rig : Rig
        Its cameras image every particle (the exact pixel and whether it is seen); its
        specification is written for the scorer.
    sample : DoubleFrameSample
        K runs of M snapshots (:func:`simulator.shared_start` or
        :func:`simulator.double_frame`).
    parameters : TurbulenceParameters
        The flow the sample was drawn in (u′, ε, ν), for the statistics' truth.
    spectrum : str
        The flow's spectrum, a name of :data:`simulator.spectra.SPECTRA`.

    Returns
    -------
    Path
        The file written.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> import simulator, validation
    >>> rig, preset = simulator.load_rig("paper-stereo"), simulator.flow_preset("lem-10hz")
    >>> flow = simulator.KSFlow(simulator.PopeSpectrum(preset.parameters), n_modes=50)
    >>> sample = simulator.shared_start(flow, preset.dt[:3], particles=300, snapshots=4,
    ...                                 region=rig.sheet, rng=0)
    >>> tmp = tempfile.TemporaryDirectory()
    >>> path = validation.write_sample_truth(tmp.name, rig, sample, preset.parameters)
    >>> truth = validation.TruthFile(path)
    >>> truth.frames, truth.shared_first_frame, truth.runs()[0].positions.shape
    (4, True, (4, 2, 324, 3))
    >>> tmp.cleanup()
    """
    if spectrum not in SPECTRA:
        raise ValueError(f"spectrum must be one of {sorted(SPECTRA)}, got {spectrum!r}")
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    snapshots = len(sample.runs[0].positions)
    runs = []
    for dt, run in zip(sample.dt, sample.runs, strict=True):
        x = run.positions[:, :2]  # (M, 2, P, 3): X(t) and X(t + Δt), m
        xy, visible = {}, {}
        for name, camera in zip(rig.camera_names, rig.cameras, strict=True):
            pixels, seen = camera.project_visible(x.reshape(-1, 3))
            xy[name] = pixels.reshape(*x.shape[:3], 2)
            visible[name] = seen.reshape(x.shape[:3])
        runs.append(TruthRun(float(dt), x, run.velocity[:, 0], xy, visible))

    def header(f: h5py.File) -> None:
        f.attrs["rig"] = json.dumps(rig.spec)
        f.create_group("flow").attrs.update(parameters.as_dict(), spectrum=spectrum)

    writer = TruthWriter(
        folder / "truth.h5",
        header=header,
        cameras=rig.camera_names,
        planes=0,
        chunks=[(0, snapshots)],
        frames=snapshots,
        shared_first_frame=sample.shared_first_frame,
    )
    writer.write_chunk(0, runs)
    writer.finish()
    return writer.path
