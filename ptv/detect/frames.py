"""Particle detections of a double-frame dataset, frame by frame: what the pipeline reads.

The PTV pipeline (:mod:`ptv.pipeline.double_frame`) needs, for every Δt_k and snapshot m, the
particle image centres of frame a (time t) and frame b (t + Δt_k) on every camera. They
come from a :class:`FrameDetections` source:

- :class:`ImageDetector` reads the images of a dataset folder (:mod:`ptv.io.dataset`) and
  detects the particles on them (:func:`ptv.detect.detect_particles`);
- :class:`ptv.detect.store.DetectionStore` reads detections saved earlier
  (:func:`ptv.detect.store.write_detections`), so that several analyses of the same
  images (other calibrations, other statistics) detect them once.

With a shared first frame (``shared_first_frame``: snapshot m of every Δt starts from
the same frame a, as when a time-resolved recording is cut into pairs), frame a of
snapshot m is the same exposure for every k: a source returns the same detections for
it whatever k.
"""

import dataclasses
import hashlib
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

import numpy as np

from ptv.detect import Detections, detect_particles
from ptv.detect.background import BackgroundEstimate, estimate_background
from ptv.detect.preprocess import invert, median_background, particles_left_by_median, tophat
from ptv.io.dataset import Dataset, DatasetError
from ptv.settings import DetectorSettings

__all__ = [
    "ChunkDetections",
    "DetectedCentres",
    "FrameDetections",
    "ImageDetector",
    "exposures",
]


class FrameDetections(Protocol):
    """Detected particle image centres of a double-frame dataset.

    Attributes
    ----------
    folder : Path
        What was measured (recorded in the results).
    cameras : tuple of str
        Camera names, in the order of the lists :meth:`detections` returns.
    dt : ndarray, shape (K,)
        Time separations, s.
    frames : tuple of int, length K
        Snapshots (frame pairs) of the run at each Δt.
    shared_first_frame : bool
        Snapshot m of every Δt shares its frame a.
    detector : dict
        How the particles were detected (:meth:`ptv.settings.DetectorSettings.as_dict`).
    """

    folder: Path
    cameras: tuple[str, ...]
    dt: np.ndarray
    frames: tuple[int, ...]
    shared_first_frame: bool
    detector: dict

    def detections(self, k: int, m: int, frame: str) -> list[np.ndarray]:
        """Centres (N_c, 2), px, on frame ``frame`` ("a" or "b") of snapshot m at Δt_k,
        one array per camera."""
        ...


#: A frame that keeps less than this fraction of its particle images once its temporal
#: median is subtracted lost them to it: the median removes only the fixed structure as
#: narrow as a particle (a glint, a scratch), a few of them on a usable recording.
STILL_FRACTION = 0.25
#: Fewest particle images on the frame for that check to speak.
MIN_STILL_CHECK = 10


def exposures(
    frames: Sequence[int], snapshots: Sequence[int], *, shared_first_frame: bool
) -> list[tuple[int, int, str]]:
    """The distinct exposures (k, m, frame) of some snapshots, in a fixed order.

    Per snapshot m: frame a (with a shared first frame once, as k = −1; otherwise once
    per k), then frame b of every k; runs of fewer frame pairs than m + 1 have none.

    Parameters
    ----------
    frames : sequence of int
        Frame pairs of the run at each Δt (K entries).
    snapshots : sequence of int
        Snapshot numbers m.
    shared_first_frame : bool
        Frame a shared by every Δt (then every run has the same frame count).

    Returns
    -------
    list of (int, int, str)
    """
    out = []
    for m in snapshots:
        runs = [k for k, n in enumerate(frames) if m < n]
        if shared_first_frame and runs:
            out.append((-1, m, "a"))
        elif not shared_first_frame:
            out.extend((k, m, "a") for k in runs)
        out.extend((k, m, "b") for k in runs)
    return out


@dataclass(frozen=True, eq=False)
class DetectedCentres:
    """What is kept of the detections on one image: centres and flags.

    Attributes
    ----------
    xy : ndarray, shape (N, 2)
        Centres, px (OpenCV convention).
    flags : ndarray of uint8, shape (N,)
        :class:`ptv.detect.DetectionFlag` bits.
    """

    xy: np.ndarray
    flags: np.ndarray

    @classmethod
    def of(cls, detections: Detections) -> "DetectedCentres":
        """The centres and flags of full detections."""
        return cls(detections.xy, detections.flags)


@dataclass(frozen=True, eq=False)
class ChunkDetections:
    """:class:`FrameDetections` of a range of snapshots, held in memory.

    What a chunk of a parallel run hands over: every exposure of snapshots m0 … m1 − 1
    (:func:`exposures`) with the dataset's description.

    Attributes
    ----------
    folder, cameras, dt, frames, shared_first_frame, detector :
        As :class:`FrameDetections` (of the whole dataset).
    snapshots : (int, int)
        m0, m1.
    found : dict of (int, int, str) to list of C detections
        Per exposure (k, m, frame), with k = −1 for a shared frame a, the detections of
        each camera: objects with ``xy`` (N, 2), px, and ``flags`` (N,)
        (:class:`ptv.detect.Detections` or :class:`DetectedCentres`).
    """

    folder: Path
    cameras: tuple[str, ...]
    dt: np.ndarray
    frames: tuple[int, ...]
    shared_first_frame: bool
    detector: dict
    snapshots: tuple[int, int]
    found: dict

    @classmethod
    def of(cls, source, snapshots: tuple[int, int], found: dict) -> "ChunkDetections":
        """The chunk ``snapshots`` of the dataset ``source`` describes (a
        :class:`FrameDetections`), with its detections ``found``."""
        return cls(
            source.folder,
            tuple(source.cameras),
            np.asarray(source.dt),
            tuple(source.frames),
            source.shared_first_frame,
            source.detector,
            tuple(snapshots),
            found,
        )

    def detections(self, k: int, m: int, frame: str) -> list[np.ndarray]:
        """Centres (N_c, 2), px, per camera, of frame ``frame`` of snapshot m at Δt_k."""
        key = (-1 if frame == "a" and self.shared_first_frame else k, m, frame)
        try:
            return [d.xy for d in self.found[key]]
        except KeyError:
            raise KeyError(f"no detections of Δt_{k}, snapshot {m}, frame {frame}") from None


class ImageDetector:
    """:class:`FrameDetections` of a dataset folder, detected from its images on demand.

    With a shared first frame, frame a of snapshot m is detected once (for the first k
    asked) and reused for the others; whenever a frame of snapshot m at Δt_k is asked
    for, frame a of that k is checked to be the same images (a content digest per
    camera): a dataset that declares a shared first frame wrongly is an error, not a
    silent mix of frames. Only the last snapshot's frame a is kept.

    Parameters
    ----------
    dataset : Dataset
        The folder (:func:`ptv.io.dataset.open_dataset`).
    settings : DetectorSettings
        Threshold; its saturation, when None, is the dataset's declared one.

    Attributes
    ----------
    settings : DetectorSettings
        The settings used, saturation resolved.
    warnings : list of str
        What the detection found wrong with the images, per camera: a temporal median
        that kept the particles (slow particles, :data:`STILL_FRACTION`).

    Examples
    --------
    A dataset of two cameras with 12-bit images, of which only frame a of the first
    snapshot at Δt_0 is written here: one particle on each camera's image, at
    x = 20.3 and 30.6 px, y = 12 px.

    >>> import json, pathlib, tempfile
    >>> import numpy as np
    >>> import tifffile
    >>> import ptv
    >>> tmp = tempfile.TemporaryDirectory()
    >>> folder = pathlib.Path(tmp.name)
    >>> spec = {"cameras": {"c1": {"image_size": [48, 32]}, "c2": {"image_size": [48, 32]}},
    ...         "dt": [1e-3, 2e-3], "frames_per_dt": 1, "bit_depth": 12,
    ...         "particle_images": "{camera}_{k}_{m}_{a|b}.tif"}
    >>> _ = (folder / "experiment.json").write_text(json.dumps(spec))
    >>> rows, cols = np.mgrid[:32, :48]
    >>> noise = np.random.default_rng(0).normal(0, 2, rows.shape)
    >>> for name, x in (("c1", 20.3), ("c2", 30.6)):
    ...     spot = 1000 * np.exp(-((cols - x) ** 2 + (rows - 12) ** 2) / 2)
    ...     image = (100 + spot + noise).astype(np.uint16)
    ...     tifffile.imwrite(folder / f"{name}_0_0_a.tif", image)
    >>> dataset = ptv.open_dataset(folder, check_files=False)
    >>> detector = ptv.ImageDetector(dataset, ptv.DetectorSettings(min_peak=50))
    >>> detector.settings.saturation  # the dataset's bit depth, DN
    4095.0
    >>> [found.xy.round(2) for found in detector.detect(0, 0, "a")]  # per camera, px
    [array([[20.3, 12. ]]), array([[30.6, 12. ]])]
    >>> tmp.cleanup()
    """

    def __init__(self, dataset: Dataset, settings: DetectorSettings = DetectorSettings()) -> None:
        self.dataset = dataset
        self.folder = dataset.folder
        self.cameras = dataset.cameras
        self.dt = dataset.dt
        self.frames = dataset.frames
        self.shared_first_frame = dataset.shared_first_frame
        saturation = settings.saturation
        if saturation is None:
            saturation = dataset.saturation
        self.settings = dataclasses.replace(settings, saturation=saturation)
        self.detector = self.settings.as_dict()
        self._frame_a: tuple[int, tuple[bytes, ...], list[Detections]] | None = None
        self._medians: dict[str, np.ndarray] = {}
        self.warnings: list[str] = []

    def detect(self, k: int, m: int, frame: str) -> list[Detections]:
        """Detections on frame ``frame`` of snapshot m at Δt_k, one per camera.

        Raises
        ------
        DatasetError
            Frame a of a dataset declaring a shared first frame differs between Δt
            (checked whenever a frame of snapshot m at Δt_k is asked for).
        """
        if self.shared_first_frame:
            shared = self._shared_frame_a(k, m)
            if frame == "a":
                return shared
        return [self._detect(self.dataset.read_frame(k, c, m, frame), c) for c in self.cameras]

    def _shared_frame_a(self, k: int, m: int) -> list[Detections]:
        """Frame a of snapshot m: detected the first time, checked against it after."""
        images = [self.dataset.read_frame(k, c, m, "a") for c in self.cameras]
        digest = tuple(
            hashlib.blake2b(np.ascontiguousarray(image), digest_size=16).digest()
            for image in images
        )
        if self._frame_a is None or self._frame_a[0] != m:
            self._frame_a = (
                m,
                digest,
                [self._detect(image, c) for image, c in zip(images, self.cameras, strict=True)],
            )
        elif self._frame_a[1] != digest:
            raise DatasetError(
                f"{self.dataset.frame_path(k, self.cameras[0], m, 'a')}: the dataset declares "
                f"a shared first frame, but frame a of snapshot {m} at Δt_{k} is not the "
                "one of the other Δt"
            )
        return self._frame_a[2]

    def detections(self, k: int, m: int, frame: str) -> list[np.ndarray]:
        """Centres (N_c, 2), px, per camera (see :meth:`detect`)."""
        return [d.xy for d in self.detect(k, m, frame)]

    def detect_recorded(self, n: int) -> list[Detections]:
        """Detections on frame number n of a time-resolved recording, one per camera."""
        return [self._detect(self.dataset.read_recorded(c, n), c) for c in self.cameras]

    def detect_chunk(self, m0: int, m1: int) -> ChunkDetections:
        """Every exposure of snapshots m0 … m1 − 1 detected (:func:`exposures`)."""
        found = {
            (k, m, frame): self.detect(max(k, 0), m, frame)
            for k, m, frame in exposures(
                self.frames, range(m0, m1), shared_first_frame=self.shared_first_frame
            )
        }
        return ChunkDetections.of(self, (m0, m1), found)

    def _detect(self, image: np.ndarray, camera: str) -> Detections:
        """The particles on one image of ``camera`` (prepared as the settings ask), those
        on its mask's 0 pixels and those fainter than ``min_peak`` dropped."""
        s = self.settings
        prepared, background = (image, None) if s.raw else self._prepared(image, camera)
        found = detect_particles(
            prepared,
            threshold_sigmas=s.threshold_sigmas,
            saturation=s.saturation if s.raw else None,
            min_size=s.min_size,
            background=background,
            diameter=s.diameter,
        )
        if s.min_peak > 0:
            found = found.select(found.peak >= s.min_peak)
        mask = self.dataset.masks.get(camera)
        return found if mask is None else found.within(mask)

    def _prepared(
        self, image: np.ndarray, camera: str
    ) -> tuple[np.ndarray, BackgroundEstimate | None]:
        """The image with its particles bright and its background removed (float32), and
        the background the detector should assume (None: its own estimate).

        After a top-hat the pixel noise is measured on the image before it: the top-hat
        of pure noise is skewed (never negative), and its adjacent-pixel differences
        would understate the spread of its upper tail, where the threshold lies.
        """
        s = self.settings
        bright = invert(image, s.saturation) if s.particles == "dark" else image
        if s.background == "tophat":
            removed = tophat(bright, s.tophat_radius)
            level = estimate_background(removed).level
            noise = estimate_background(bright).noise
            return removed, BackgroundEstimate(level, noise, removed.shape)
        if s.background == "median":
            return np.asarray(bright, dtype=np.float32) - self._median(camera), None
        return np.asarray(bright, dtype=np.float32), None

    def _median(self, camera: str) -> np.ndarray:
        """The temporal median of ``camera``: ``median_frames`` exposures spread evenly
        over the recording (particles bright), computed once."""
        if camera not in self._medians:
            order = exposures(
                self.frames,
                range(max(self.frames)),
                shared_first_frame=self.shared_first_frame,
            )
            picks = np.unique(np.linspace(0, len(order) - 1, self.settings.median_frames).round())
            dark = self.settings.particles == "dark"
            frames = []
            for i in picks.astype(int):
                k, m, frame = order[i]
                image = self.dataset.read_frame(max(k, 0), camera, m, frame)
                frames.append(invert(image, self.settings.saturation) if dark else image)
            self._medians[camera] = median_background(frames)
            self._check_median(camera, frames)
        return self._medians[camera]

    def _check_median(self, camera: str, frames: list[np.ndarray]) -> None:
        """Add to :attr:`warnings` when ``camera``'s median erases the particles of its
        frames (:func:`ptv.detect.preprocess.particles_left_by_median`)."""
        s = self.settings
        radius = max(s.tophat_radius, math.ceil((s.diameter or 0) / 2))
        before, after = particles_left_by_median(
            self._medians[camera],
            frames[len(frames) // 2],
            radius=radius,
            threshold_sigmas=s.threshold_sigmas,
            diameter=s.diameter,
        )
        if before >= MIN_STILL_CHECK and after < STILL_FRACTION * before:
            self.warnings.append(
                f"{camera}: one of the {len(frames)} frames of the temporal median shows "
                f"{before} particle images, {after} once the median is subtracted: the "
                "particles move less than their size between those frames, so the median "
                "keeps them and erases them from the frames; take median_frames from a "
                'longer stretch of the recording, or background = "tophat"'
            )
