"""Read a PTV dataset folder: the experiment description and its particle images.

The layout is the one ``synptv render`` writes, and any real double-frame experiment
can be put in it (lengths in m, times in s)::

    experiment.json                              camera names and image sizes, Δt values,
                                                 frame pairs per Δt, bit depth, file layout
    particles/dt<k>/<camera>/<mmmmmm>_a.tif      frame pair m of the run at Δt_k: frame a
    particles/dt<k>/<camera>/<mmmmmm>_b.tif      at t, frame b at t + Δt_k

``experiment.json`` is checked against its JSON Schema first (:mod:`ptv.io.experiment_file`,
docs/experiment.md: every problem named in one line). Keys used here: ``cameras``
({name: {"image_size": [width, height], "mask": optional image path}}), ``dt`` (list
of s), ``frames_per_dt`` (an int, or one int per Δt),
``bit_depth`` (optional; sets the saturation level 2^B − 1 of images stored in wider
integers), ``shared_first_frame`` (optional, default false: true when snapshot m of
every Δt starts from the same frame a, as when a time-resolved recording is cut into
pairs; the statistics then follow the same particles over every Δt) and
``particle_images`` (optional pattern, default
``particles/dt{k}/{camera}/{m:06d}_{a|b}.tif``; null for a dataset without particle
images, which cannot be processed here). A time-resolved recording gives instead
``time_resolved`` (frame rate, frame-number pattern, steps; :mod:`ptv.io.sequence`), from
which the Δt values, the frame pairs and the shared first frame follow; every frame of
it is read by its number (:meth:`Dataset.read_recorded`) for tracking. Images are
8- or 16-bit TIFF or PNG
(:mod:`ptv.io.images`); a camera's mask (pixels at 0 are not used) must have its image
size. Nothing else of the folder (plate images, a ground truth) is read.

:func:`open_dataset` checks the description and that every image file exists, so a
run fails at once, not after an hour; :meth:`Dataset.read_frame` checks each image's
shape against the declared size. Bad input raises :class:`DatasetError` (a
``ValueError``) or ``FileNotFoundError``, naming the file and what was expected.
"""

import logging
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ptv.errors import DatasetError
from ptv.io.experiment_file import read_experiment
from ptv.io.images import read_image, read_mask
from ptv.io.sequence import TimeResolved
from ptv.names import FILE_NAME_RULE, is_file_name

__all__ = [
    "DEFAULT_PARTICLE_IMAGES",
    "Dataset",
    "DatasetError",
    "FramePair",
    "Snapshot",
    "cameras_in_order",
    "open_dataset",
]

log = logging.getLogger(__name__)

#: File pattern of the particle images when experiment.json does not give one.
DEFAULT_PARTICLE_IMAGES = "particles/dt{k}/{camera}/{m:06d}_{a|b}.tif"


@dataclass(frozen=True, eq=False)
class FramePair:
    """The two frames of one camera for one snapshot.

    Attributes
    ----------
    camera : str
        Camera name.
    a, b : ndarray, shape (H, W)
        Frame a (time t) and frame b (t + Δt), as stored (DN).
    path_a, path_b : Path
        Their files.
    """

    camera: str
    a: np.ndarray
    b: np.ndarray
    path_a: Path
    path_b: Path


@dataclass(frozen=True, eq=False)
class Snapshot:
    """All cameras' frame pairs of snapshot ``m`` of the run at Δt_k.

    Attributes
    ----------
    k : int
        Δt index.
    dt : float
        Δt, s.
    m : int
        Snapshot (frame pair) number within the run.
    frames : tuple of FramePair
        One per camera, in the dataset's camera order.
    """

    k: int
    dt: float
    m: int
    frames: tuple[FramePair, ...]


def _fail(path: Path, message: str) -> DatasetError:
    return DatasetError(f"{path}: {message}")


def _positive_int(value: object) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and value >= 1


@dataclass(frozen=True, eq=False)
class Dataset:
    """A dataset folder's description (built by :func:`open_dataset`).

    Attributes
    ----------
    folder : Path
        The folder.
    cameras : tuple of str
        Camera names, in the order of experiment.json.
    image_shape : dict of str to (int, int)
        Expected (rows, columns) of each camera's images.
    dt : ndarray, shape (K,)
        Time separations, s (K ≥ 2, all > 0 and distinct).
    frames : tuple of int, length K
        Frame pairs (snapshots) of the run at each Δt.
    saturation : float or None
        Saturation level of the images, DN (2^bit_depth − 1), None if not declared.
    pattern : str
        Particle image file pattern, relative to the folder.
    shared_first_frame : bool
        Snapshot m of every Δt shares its frame a (same particles at t).
    masks : dict of str to ndarray of bool, shape (H, W)
        The masks of the cameras that have one: True where the image is used.
    sequence : TimeResolved or None
        The frame-numbered recording the frame pairs are cut from (then ``pattern`` is
        its file pattern, with ``{n}``), or None for frame pairs stored as such.
    """

    folder: Path
    cameras: tuple[str, ...]
    image_shape: dict[str, tuple[int, int]]
    dt: np.ndarray
    frames: tuple[int, ...]
    saturation: float | None
    pattern: str
    shared_first_frame: bool = False
    masks: Mapping[str, np.ndarray] = field(default_factory=dict)
    sequence: TimeResolved | None = None

    @property
    def n_dt(self) -> int:
        """K, the number of Δt values."""
        return int(self.dt.size)

    def frame_path(self, k: int, camera: str, m: int, frame: str) -> Path:
        """File of frame ``frame`` ("a" or "b") of snapshot m, camera, run k."""
        if frame not in ("a", "b"):
            raise ValueError(f"frame must be 'a' or 'b', got {frame!r}")
        if self.sequence is not None:
            n = self.sequence.frame_number(k, m, frame)
            return self.folder / self.pattern.format(camera=camera, n=n)
        name = self.pattern.replace("{a|b}", "{frame}")
        return self.folder / name.format(k=k, camera=camera, m=m, frame=frame)

    def recorded_path(self, camera: str, n: int) -> Path:
        """File of frame number n of a time-resolved recording, camera ``camera``."""
        if self.sequence is None:
            raise DatasetError(f"{self.folder}: frame pairs, not a time-resolved recording")
        return self.folder / self.pattern.format(camera=camera, n=n)

    def read_frame(self, k: int, camera: str, m: int, frame: str) -> np.ndarray:
        """Read one image and check its shape, (H, W) as declared in experiment.json.

        Raises
        ------
        FileNotFoundError
            The file is missing.
        DatasetError
            Not readable as an image (:class:`ptv.io.images.ImageError`), not 2-D, of the
            wrong size, not grey levels, or with NaN or infinite pixels.
        """
        return self._read(self.frame_path(k, camera, m, frame), camera)

    def read_recorded(self, camera: str, n: int) -> np.ndarray:
        """Frame number n of a time-resolved recording, checked as :meth:`read_frame`."""
        return self._read(self.recorded_path(camera, n), camera)

    def missing_recorded(self, numbers: Iterable[int]) -> list[Path]:
        """The files of the recorded frames ``numbers`` (every camera) that do not exist."""
        return [
            self.recorded_path(c, n)
            for n in numbers
            for c in self.cameras
            if not self.recorded_path(c, n).is_file()
        ]

    def _read(self, path: Path, camera: str) -> np.ndarray:
        """The image at ``path`` of ``camera``, checked (see :meth:`read_frame`)."""
        if not path.is_file():
            raise FileNotFoundError(f"particle image {path} is missing")
        image = read_image(path)
        expected = self.image_shape[camera]
        if image.shape != expected:
            raise _fail(
                path,
                f"image of the wrong size: {image.shape[1]} × {image.shape[0]} px, but "
                f"experiment.json gives {expected[1]} × {expected[0]} px for camera {camera!r}",
            )
        if not np.issubdtype(image.dtype, np.number) or np.issubdtype(
            image.dtype, np.complexfloating
        ):
            raise _fail(path, f"expected grey levels (integers or reals), got {image.dtype}")
        if np.issubdtype(image.dtype, np.floating) and not np.isfinite(image).all():
            bad = int(np.count_nonzero(~np.isfinite(image)))
            raise _fail(path, f"{bad} pixels are NaN or infinite")
        return image

    def snapshot(self, k: int, m: int, cameras: Sequence[str] | None = None) -> Snapshot:
        """Read snapshot m of the run at Δt_k (frames a and b of each camera)."""
        if not 0 <= k < self.n_dt:
            raise IndexError(f"Δt index {k} out of range 0 … {self.n_dt - 1}")
        if not 0 <= m < self.frames[k]:
            raise IndexError(f"snapshot {m} out of range 0 … {self.frames[k] - 1} at Δt_{k}")
        names = self.cameras if cameras is None else tuple(cameras)
        pairs = tuple(
            FramePair(
                camera=c,
                a=self.read_frame(k, c, m, "a"),
                b=self.read_frame(k, c, m, "b"),
                path_a=self.frame_path(k, c, m, "a"),
                path_b=self.frame_path(k, c, m, "b"),
            )
            for c in names
        )
        return Snapshot(k=k, dt=float(self.dt[k]), m=m, frames=pairs)

    def snapshots(
        self, k: int, *, limit: int | None = None, cameras: Sequence[str] | None = None
    ) -> Iterator[Snapshot]:
        """Snapshots of the run at Δt_k in order (the first ``limit`` if given)."""
        n = self.frames[k] if limit is None else min(limit, self.frames[k])
        for m in range(n):
            yield self.snapshot(k, m, cameras)

    def runs(
        self, *, limit: int | None = None, cameras: Sequence[str] | None = None
    ) -> Iterator[Iterator[Snapshot]]:
        """One snapshot iterator per Δt, in the order of ``dt``."""
        for k in range(self.n_dt):
            yield self.snapshots(k, limit=limit, cameras=cameras)


def _cameras(spec: dict, path: Path) -> dict[str, tuple[int, int]]:
    cams = spec.get("cameras")
    if not isinstance(cams, dict) or not cams:
        raise _fail(path, "'cameras' must be a non-empty object {name: {image_size: [w, h]}}")
    shapes = {}
    for name, entry in cams.items():
        if not is_file_name(name):  # it names the folders of the camera's images
            raise _fail(path, f"camera name: expected {FILE_NAME_RULE}, got {name!r}")
        size = entry.get("image_size") if isinstance(entry, dict) else None
        if not (isinstance(size, list) and len(size) == 2 and all(_positive_int(v) for v in size)):
            raise _fail(
                path, f"camera {name!r}: image_size must be [width, height] in px, got {size!r}"
            )
        shapes[str(name)] = (int(size[1]), int(size[0]))
    if len(shapes) < 2:
        raise _fail(path, f"3-D PTV needs at least two cameras, got {list(shapes)}")
    return shapes


def _dt(spec: dict, path: Path) -> np.ndarray:
    raw = spec.get("dt")
    if not isinstance(raw, list) or not raw:
        raise _fail(path, f"'dt' must be a list of time separations in s, got {raw!r}")
    try:
        dt = np.asarray(raw, dtype=np.float64)
    except (TypeError, ValueError):
        raise _fail(path, f"'dt' must hold numbers, got {raw!r}") from None
    if dt.ndim != 1 or not np.all(np.isfinite(dt)) or np.any(dt <= 0):
        raise _fail(path, f"'dt' values must be finite and > 0 s, got {raw!r}")
    if np.unique(dt).size != dt.size:
        raise _fail(path, f"'dt' values must be distinct, got {raw!r}")
    if dt.size < 2:
        raise _fail(
            path,
            f"a single Δt ({dt[0]:.6g} s): the multi-Δt method needs at least two Δt values",
        )
    return dt


def _frames(spec: dict, path: Path, n_dt: int) -> tuple[int, ...]:
    raw = spec.get("frames_per_dt")
    if _positive_int(raw):
        return (int(raw),) * n_dt
    if isinstance(raw, list) and len(raw) == n_dt and all(_positive_int(v) for v in raw):
        return tuple(int(v) for v in raw)
    raise _fail(
        path,
        f"'frames_per_dt' must be an integer >= 1 or a list of {n_dt} of them, got {raw!r}",
    )


def _saturation(spec: dict, path: Path) -> float | None:
    bits = spec.get("bit_depth")
    if bits is None:
        return None
    if not (_positive_int(bits) and bits <= 32):
        raise _fail(path, f"'bit_depth' must be an integer in 1 … 32, got {bits!r}")
    return float(2**bits - 1)


def open_dataset(folder: str | Path, *, check_files: bool = True) -> Dataset:
    """Read and check a dataset folder's experiment.json.

    Parameters
    ----------
    folder : path-like
        The dataset folder.
    check_files : bool
        Check that every particle image file exists (cheap: no image is read).

    Returns
    -------
    Dataset

    Raises
    ------
    FileNotFoundError
        The folder, its experiment.json or a particle image is missing.
    DescriptionError
        experiment.json breaks the schema or lacks a field particles need (all the
        problems in one line).
    DatasetError
        A malformed description the schema cannot see: Δt values not distinct, a frame
        count per Δt that does not match, a bad pattern.
    ImageError
        A mask that cannot be read, of the wrong size, or 0 everywhere.

    Examples
    --------
    A folder with its experiment.json only: the description is read, and the images
    it names are checked for (``check_files=False`` skips that):

    >>> import json, pathlib, tempfile
    >>> import ptv
    >>> tmp = tempfile.TemporaryDirectory()
    >>> folder = pathlib.Path(tmp.name)
    >>> spec = {"cameras": {"c1": {"image_size": [48, 32]}, "c2": {"image_size": [48, 32]}},
    ...         "dt": [1e-3, 2e-3], "frames_per_dt": 1, "bit_depth": 12,
    ...         "particle_images": "{camera}_{k}_{m}_{a|b}.tif"}
    >>> _ = (folder / "experiment.json").write_text(json.dumps(spec))
    >>> dataset = ptv.open_dataset(folder, check_files=False)
    >>> dataset.cameras, dataset.dt, dataset.frames, dataset.saturation
    (('c1', 'c2'), array([0.001, 0.002]), (1, 1), 4095.0)
    >>> dataset.frame_path(1, "c2", 0, "b").name  # Δt_1, camera c2, snapshot 0, frame b
    'c2_1_0_b.tif'
    >>> ptv.open_dataset(folder)
    Traceback (most recent call last):
    ...
    FileNotFoundError: particle image .../c1_0_0_a.tif is missing (and 7 more)
    >>> tmp.cleanup()
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise FileNotFoundError(f"dataset folder {folder} does not exist")
    spec = read_experiment(folder, needs=("particles",))
    path = folder / "experiment.json"
    shapes = _cameras(spec, path)
    sequence = None
    if "time_resolved" in spec:
        try:
            sequence = TimeResolved.from_dict(spec["time_resolved"])
        except ValueError as err:
            raise _fail(path, str(err)) from None
        dt, pattern, shared = sequence.dt, sequence.images, True
        frames = (sequence.snapshots,) * dt.size
    else:
        dt = _dt(spec, path)
        frames = _frames(spec, path, dt.size)
        pattern = spec.get("particle_images", DEFAULT_PARTICLE_IMAGES)
        if pattern is None:
            raise _fail(path, "'particle_images' is null: this dataset holds no particle images")
        if not isinstance(pattern, str) or "{a|b}" not in pattern:
            raise _fail(
                path, f"'particle_images' must be a pattern with '{{a|b}}', got {pattern!r}"
            )
        shared = spec.get("shared_first_frame", False)
        if shared and len(set(frames)) != 1:
            raise _fail(
                path, f"a shared first frame needs the same frame count per Δt, got {frames}"
            )
    dataset = Dataset(
        folder=folder,
        cameras=tuple(shapes),
        image_shape=shapes,
        dt=dt,
        frames=frames,
        saturation=_saturation(spec, path),
        pattern=pattern,
        shared_first_frame=shared,
        masks=camera_masks(folder, spec, shapes),
        sequence=sequence,
    )
    try:
        dataset.frame_path(0, dataset.cameras[0], 0, "a")
    except (KeyError, IndexError, ValueError) as err:
        field = "time_resolved.images" if sequence else "particle_images"
        raise _fail(path, f"bad '{field}' pattern {pattern!r} ({err})") from None
    if check_files:
        missing = [
            dataset.frame_path(k, c, m, f)
            for k in range(dt.size)
            for c in dataset.cameras
            for m in range(frames[k])
            for f in "ab"
            if not dataset.frame_path(k, c, m, f).is_file()
        ]
        if missing:
            more = f" (and {len(missing) - 1} more)" if len(missing) > 1 else ""
            raise FileNotFoundError(f"particle image {missing[0]} is missing{more}")
    log.info(
        "dataset %s: cameras %s, %d Δt, %s frame pairs",
        folder,
        ", ".join(dataset.cameras),
        dt.size,
        frames,
    )
    return dataset


def camera_masks(
    folder: Path, spec: dict, shapes: Mapping[str, tuple[int, int]]
) -> dict[str, np.ndarray]:
    """The masks experiment.json gives (``cameras.<name>.mask``, relative to ``folder``),
    each checked against its camera's (rows, columns) in ``shapes``."""
    return {
        name: read_mask(folder / info["mask"], shapes[name])
        for name, info in spec["cameras"].items()
        if "mask" in info
    }


def cameras_in_order(dataset: Dataset, calibrations: Mapping[str, object]) -> list[object]:
    """The calibrations in the dataset's camera order; they must name the same cameras.

    Raises
    ------
    DatasetError
        "cameras don't match the calibration", naming the cameras missing on either side.
    """
    have, want = set(calibrations), set(dataset.cameras)
    if have != want:
        parts = []
        if want - have:
            parts.append(f"not calibrated: {', '.join(sorted(want - have))}")
        if have - want:
            parts.append(f"calibrated but not in the dataset: {', '.join(sorted(have - want))}")
        raise DatasetError(
            f"cameras don't match the calibration: the dataset {dataset.folder} has "
            f"{', '.join(dataset.cameras)}, the calibration has "
            f"{', '.join(calibrations)} ({'; '.join(parts)})"
        )
    return [calibrations[c] for c in dataset.cameras]
