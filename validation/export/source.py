"""A rendered dataset, read and checked for export before anything is written.

Everything an export needs comes from three places of a ``synptv render`` folder:
``experiment.json`` (cameras, image sizes, Δt values, frame pairs, the plate design and
its traverse positions, the file layout), the images it names (plate images per camera
and plane, particle images per Δt, camera, snapshot and frame) and ``truth.h5``, whose
rig gives what a real experiment would have measured on its bench: where each camera
stands and looks, its lens, and the geometry of its window. A recorded dataset (the
``dataset`` folder of ``synptv run`` on a scenario with ``[recording]``) holds the
plates at its top and each recording in ``sequence<s>/``, a time-resolved dataset with
its own truth.h5. Errors name the file and the field, in one line (``ValueError``).
"""

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ptv.calibration.plate_images import nominal_grid, plate_setup
from ptv.io.dataset import Dataset, open_dataset
from ptv.io.experiment_file import read_experiment
from ptv.tracking.link_speed import SPEED_SIGMAS
from simulator.rigs import Rig
from validation.run.render_recording import sequence_folder
from validation.truth.recording_truth import read_recording_truth
from validation.truth.truth_file import TruthFile

#: Snapshots whose true velocities give the tracking bounds' speed.
SPEED_SNAPSHOTS = 5


@dataclass(frozen=True, eq=False)
class ExportSource:
    """A dataset folder as an exporter reads it.

    Attributes
    ----------
    folder : Path
        The dataset folder.
    dataset : ptv.io.dataset.Dataset
        Cameras, image shapes, Δt values, frame pairs and the particle image paths.
    rig : simulator.rigs.Rig
        The rig of truth.h5: the nominal camera poses, lenses and windows.
    dots : ndarray, shape (N_Z, D, 3)
        Nominal centre of every plate dot at every traverse position, m (the plate's
        grid times its pitch, at the nominal traverse Z_j): what a user would type
        into a target file.
    dot_diameters : (float, float)
        Diameters of the plate's ordinary and marked dots, m.
    plate_images : list of list of Path
        Plate image of camera c at traverse position j: ``plate_images[c][j]``.
    bit_depth : int or None
        Significant bits of the grey levels (experiment.json), None if not declared.
    max_speed : float
        Largest particle speed for the tracking bounds, m/s: |U| + 5 max_i σ_i of the true
        velocities of the first snapshots (:func:`true_max_speed`) or recorded frames,
        what a user who knows the flow would type.
    recordings : tuple of ptv.io.dataset.Dataset
        The time-resolved recordings of a recorded dataset, in order (``dataset`` is the
        first); empty for frame pairs.
    max_acceleration : float or None
        Of a recorded dataset: |A| + 5 max_i σ_i of the true accelerations of its first
        frames, m/s² (:func:`speed_bound`); None for frame pairs.
    """

    folder: Path
    dataset: Dataset
    rig: Rig
    dots: np.ndarray
    dot_diameters: tuple[float, float]
    plate_images: list
    bit_depth: int | None
    max_speed: float
    recordings: tuple = ()
    max_acceleration: float | None = None

    @property
    def cameras(self) -> tuple[str, ...]:
        """Camera names, in the order of experiment.json."""
        return self.dataset.cameras

    def frame_path(self, k: int, camera: str, m: int, frame: str) -> Path:
        """Particle image of frame ``frame`` (a or b) of snapshot m at Δt_k."""
        return self.dataset.frame_path(k, camera, m, frame)


def read_source(folder: str | Path) -> ExportSource:
    """Read and check a rendered dataset folder for export.

    Parameters
    ----------
    folder : path-like
        A folder written by ``synptv render`` (with particle images and truth.h5).

    Returns
    -------
    ExportSource

    Raises
    ------
    ValueError
        One line naming the file and the field: no such folder, no truth.h5, a
        malformed experiment.json, no particle images (a run without --keep-images), a
        missing image, dot lists instead of plate images,
        camera names that differ between experiment.json and truth.h5; a recording's
        ``sequence<s>`` folder given in place of the dataset that holds its plates.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise ValueError(f"--dataset {folder}: no such folder")
    if (folder / "sequence0").is_dir():
        return _recorded_source(folder)
    if not (folder / "truth.h5").is_file():
        raise ValueError(
            f"--dataset {folder}: no truth.h5 (export takes each camera's nominal pose and "
            "window from the rig a rendered dataset records there)"
        )
    try:
        spec = read_experiment(folder)
        if "time_resolved" in spec:
            raise ValueError(
                f"--dataset {folder}: one recording of a recorded dataset; export the "
                f"folder that holds it ({folder.parent}), whose plates calibrate it"
            )
        if spec.get("particle_images", "") is None:
            raise ValueError(
                f"{folder / 'experiment.json'}: particle_images is null: this dataset was "
                "written without its particle images (synptv run keeps them only with "
                "--keep-images): run it again with --keep-images, or render one with "
                "synptv render"
            )
        dataset = open_dataset(folder)
        setup = plate_setup(folder)
    except FileNotFoundError as err:
        raise ValueError(str(err)) from None
    truth = TruthFile(folder)
    return _source(folder, spec, dataset, setup, truth.rig, true_max_speed(truth))


def _spec(folder: Path) -> dict:
    try:
        return read_experiment(folder)
    except FileNotFoundError as err:
        raise ValueError(str(err)) from None


def _source(folder: Path, spec: dict, dataset: Dataset, setup, rig: Rig, speed: float, **more):
    """The ExportSource of a checked folder."""
    if setup.listed:
        raise ValueError(
            f"{folder / 'experiment.json'}: export copies the plate images; this folder gives "
            "dot lists (calibration_dots) instead"
        )
    if tuple(rig.camera_names) != dataset.cameras:
        raise ValueError(
            f"{folder / 'truth.h5'}: rig cameras {', '.join(rig.camera_names)} differ "
            f"from experiment.json's {', '.join(dataset.cameras)}"
        )
    _, nominal = nominal_grid(setup, {})
    bits = spec.get("bit_depth")
    if bits is not None and bits > 16:
        raise ValueError(
            f"{folder / 'experiment.json'}: 'bit_depth' must be an integer 1 … 16, got {bits!r}"
        )
    return ExportSource(
        folder=folder,
        dataset=dataset,
        rig=rig,
        dots=nominal,
        dot_diameters=(setup.plate.dot_diameter, setup.plate.mark_diameter),
        plate_images=[setup.images[name] for name in dataset.cameras],
        bit_depth=bits,
        max_speed=speed,
        **more,
    )


def _recorded_source(folder: Path) -> ExportSource:
    """The source of a recorded dataset: plates at the top, recordings in sequence<s>/."""
    spec = _spec(folder)
    count = 0
    while (sequence_folder(folder, count) / "experiment.json").is_file():
        count += 1
    if not count:
        raise ValueError(f"{folder / 'sequence0'}: no experiment.json")
    try:
        recordings = tuple(open_dataset(sequence_folder(folder, s)) for s in range(count))
        setup = plate_setup(folder)
    except FileNotFoundError as err:
        raise ValueError(str(err)) from None
    for s, recording in enumerate(recordings):
        if recording.sequence is None:
            raise ValueError(
                f"{sequence_folder(folder, s) / 'experiment.json'}: not a time-resolved "
                "recording (no time_resolved)"
            )
        if not (sequence_folder(folder, s) / "truth.h5").is_file():
            raise ValueError(f"{sequence_folder(folder, s)}: no truth.h5")
    truth = read_recording_truth(sequence_folder(folder, 0))
    first = truth.frame < SPEED_SNAPSHOTS
    return _source(
        folder,
        spec,
        recordings[0],
        setup,
        truth.rig,
        speed_bound(truth.velocity[first]),
        recordings=recordings,
        max_acceleration=speed_bound(truth.acceleration[first]),
    )


def true_max_speed(truth: TruthFile) -> float:
    """|U| + 5 max_i σ_i of the true particle velocities at t of the first snapshots
    (at most :data:`SPEED_SNAPSHOTS`), m/s: U their mean, σ_i the rms of each component
    about it; the rule synptv applies to its own measured links
    (:mod:`ptv.tracking.link_speed`), here on the exact velocities."""
    velocity = truth.runs(0, min(SPEED_SNAPSHOTS, truth.frames))[0].velocity.reshape(-1, 3)
    return speed_bound(velocity)


def speed_bound(vectors: np.ndarray) -> float:
    """|V| + 5 max_i σ_i of vectors (N, 3) (velocities or accelerations), V their mean
    and σ_i the rms of each component about it; non-finite rows left out."""
    vectors = vectors[np.isfinite(vectors).all(axis=1)]
    mean = vectors.mean(axis=0)
    return float(np.linalg.norm(mean) + SPEED_SIGMAS * vectors.std(axis=0).max())


def rotation_angles(matrix: np.ndarray) -> tuple[float, float, float]:
    """Angles (a, b, c), rad, with ``matrix`` = R_x(a) R_y(b) R_z(c).

    Both OpenPTV (ω, φ, κ) and MyPTV (θ₁, θ₂, θ₃) write a rotation as this product of
    rotations about the fixed x, y and z axes.

    Parameters
    ----------
    matrix : ndarray, shape (3, 3)
        A proper rotation.

    Returns
    -------
    (float, float, float)
        a, b, c, rad; b in [−π/2, π/2].
    """
    r = np.asarray(matrix, dtype=float)
    b = math.asin(float(np.clip(r[0, 2], -1.0, 1.0)))
    a = math.atan2(-r[1, 2], r[2, 2])
    c = math.atan2(-r[0, 1], r[0, 0])
    return a, b, c
