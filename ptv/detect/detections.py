"""The result of particle detection: aligned arrays, one row per detected particle."""

import enum
from dataclasses import dataclass

import numpy as np


class DetectionFlag(enum.IntFlag):
    """Bits of :attr:`Detections.flags` (0: an isolated, clean detection).

    OVERLAP
        The particle shared its connected region above threshold with other resolved
        maxima and was split from them (each pixel goes to the nearest maximum), or it
        is one of the particles of a blend split by the model test of the "gauss"
        estimator (one maximum, two or three spots fitted; see :mod:`ptv.detect.locate`).
    ELONGATED
        A single maximum whose spot is elongated beyond ``max_elongation``, that the
        model test (estimator "gauss") did not split: one particle, most likely, seen
        elongated through noise (or a streak); with the other estimators, probably two
        unresolved overlapping particles. Also a region with too many maxima to split
        (more than 64: a blob such as a reflection, or a threshold set inside the
        noise), reported at its brightest maximum.
    SATURATED
        At least one of its pixels is at or above the saturation level.
    EDGE
        Its pixels touch the image border: the spot is cut and its centre biased.
    FALLBACK
        The chosen Gaussian estimator was ill-posed (a value <= background, a flat or
        non-concave profile, the border) and a simpler one was used: the 3-point
        Gaussian for ``"gauss"``, the centroid for ``"gauss3"`` (on the axis concerned).

    Examples
    --------
    >>> import numpy as np
    >>> import ptv
    >>> flags = np.array([0, 1, 12], dtype=np.uint8)  # Detections.flags of three particles
    >>> (flags & ptv.DetectionFlag.EDGE) != 0
    array([False, False,  True])
    >>> [flag.name for flag in ptv.DetectionFlag if flag & flags[2]]
    ['SATURATED', 'EDGE']
    """

    OVERLAP = 1
    ELONGATED = 2
    SATURATED = 4
    EDGE = 8
    FALLBACK = 16


@dataclass(frozen=True, eq=False)
class Detections:
    """Particles detected on one image.

    Parameters
    ----------
    xy : ndarray, shape (N, 2), float64
        Sub-pixel centres (x = column, y = row), px; the centre of the top-left pixel
        is (0, 0) (OpenCV convention).
    intensity : ndarray, shape (N,), float64
        Integrated intensity above background, Σ (I − background) over the particle's
        pixels above threshold, DN (the spot's tails below threshold are not counted).
        The particles of a blend split by the model test share the blend's intensity,
        peak and size in proportion to their fitted amplitudes.
    peak : ndarray, shape (N,), float64
        Brightest pixel above background, I_max − background, DN.
    size : ndarray, shape (N,), int64
        Pixels above threshold that belong to the particle.
    flags : ndarray, shape (N,), uint8
        Bitwise OR of :class:`DetectionFlag` values; 0 for a clean detection.
    shape : (H, W)
        Rows and columns of the image.

    Examples
    --------
    Detections from another program, made the stack's: a clean one and one cut by the
    image border.

    >>> import ptv
    >>> found = ptv.Detections(
    ...     xy=[[10.2, 5.1], [3.0, 0.4]],
    ...     intensity=[900.0, 300.0],
    ...     peak=[400.0, 150.0],
    ...     size=[9, 4],
    ...     flags=[0, ptv.DetectionFlag.EDGE],
    ...     shape=(32, 32),
    ... )
    >>> len(found), found.clean
    (2, array([ True, False]))
    >>> found.select(found.clean).xy  # px
    array([[10.2,  5.1]])
    """

    xy: np.ndarray
    intensity: np.ndarray
    peak: np.ndarray
    size: np.ndarray
    flags: np.ndarray
    shape: tuple[int, int]

    def __post_init__(self) -> None:
        xy = np.asarray(self.xy, dtype=np.float64)
        if xy.ndim != 2 or xy.shape[1] != 2:
            raise ValueError(f"xy must have shape (N, 2), got {xy.shape}")
        n = xy.shape[0]
        fields = {
            "intensity": np.float64,
            "peak": np.float64,
            "size": np.int64,
            "flags": np.uint8,
        }
        object.__setattr__(self, "xy", xy)
        for name, dtype in fields.items():
            arr = np.asarray(getattr(self, name), dtype=dtype)
            if arr.shape != (n,):
                raise ValueError(f"{name} must have shape ({n},) like xy, got {arr.shape}")
            object.__setattr__(self, name, arr)
        shape = tuple(int(v) for v in self.shape)
        if len(shape) != 2 or min(shape) < 1:
            raise ValueError(f"shape must be (rows, cols) of positive integers, got {self.shape}")
        object.__setattr__(self, "shape", shape)

    def __len__(self) -> int:
        return self.xy.shape[0]

    def has(self, flag: DetectionFlag) -> np.ndarray:
        """(N,) bool: detections carrying any bit of ``flag``."""
        return (self.flags & np.uint8(flag)) != 0

    @property
    def clean(self) -> np.ndarray:
        """(N,) bool: detections with no flag except FALLBACK."""
        return (self.flags & np.uint8(0xFF ^ DetectionFlag.FALLBACK)) == 0

    def select(self, mask: object) -> "Detections":
        """The detections picked by a boolean mask or an index array."""
        idx = np.asarray(mask)
        return Detections(
            xy=self.xy[idx],
            intensity=self.intensity[idx],
            peak=self.peak[idx],
            size=self.size[idx],
            flags=self.flags[idx],
            shape=self.shape,
        )

    def within(self, mask: np.ndarray) -> "Detections":
        """The detections whose centre's pixel is True in ``mask`` (H, W), bool."""
        mask = np.asarray(mask, dtype=bool)
        if mask.shape != self.shape:
            raise ValueError(f"mask of shape {mask.shape} for an image of shape {self.shape}")
        col, row = np.round(self.xy).astype(np.int64).T
        rows, cols = self.shape
        on = (row >= 0) & (row < rows) & (col >= 0) & (col < cols)
        keep = np.zeros(len(self), dtype=bool)
        keep[on] = mask[row[on], col[on]]
        return self.select(keep)
