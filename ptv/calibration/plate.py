"""The calibration plate as an experimentalist describes it (:class:`PlateDescription`)
and the dots identified on one of its images (:class:`PlaneDots`, what
:func:`ptv.calibration.targets.find_dots` returns)."""

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from ptv.calibration.observations import PlaneObservation

#: Bit flags of :attr:`PlaneDots.flags`.
FLAG_MARK = 1
FLAG_SATURATED = 2


@dataclass(frozen=True)
class PlateDescription:
    """The nominal plate, as an experimentalist describes it to the calibration software.

    Parameters
    ----------
    pitch : float
        Dot spacing along X and Y, m.
    dot_diameter : float
        Diameter of the ordinary dots, m.
    mark_diameter : float or None
        Diameter of the three marked dots, m (larger than ``dot_diameter``); None for a
        plate without marks.
    marks : dict of str to (int, int)
        Grid indices (i, j) of the three marks, e.g. ``{"origin": (0, 0),
        "x_axis": (2, 0), "y_axis": (0, 3)}``, not collinear; or of a single mark, with
        ``axes``; empty for a plate without marks (then every image needs seed dots,
        :func:`find_dots`). Plate coordinates are (X, Y) = pitch·(i, j).
    dots : str
        ``"bright"`` (back-lit dots on a dark plate) or ``"dark"`` (dark dots on a
        bright plate).
    extent : ((int, int), (int, int)) or None
        ((i_min, i_max), (j_min, j_max)), inclusive: the grid nodes the plate has.
        None when unknown (then only holes inside the found grid count as missing).
    axes : (str, str) or None
        With a single mark: the image directions of +i and +j, one of "right" and
        "left" and one of "up" and "down" (e.g. ``("right", "up")``: i grows to the
        right, j upwards), each within 40° of the grid's own directions on the images.

    Examples
    --------
    A plate of 9 × 7 dots 5 mm apart, with three marks twice the dots' diameter:

    >>> import ptv
    >>> plate = ptv.PlateDescription(
    ...     pitch=5e-3,
    ...     dot_diameter=1e-3,
    ...     mark_diameter=2e-3,
    ...     marks={"origin": (0, 0), "x_axis": (2, 0), "y_axis": (0, 3)},
    ...     extent=((-4, 4), (-3, 3)),
    ... )
    >>> plate.mark_area_ratio  # what tells a mark from a dot on the images
    4.0
    >>> plate.in_extent([[0, 0], [4, 3], [5, 0]])
    array([ True,  True, False])
    """

    pitch: float
    dot_diameter: float
    mark_diameter: float | None = None
    marks: Mapping[str, tuple[int, int]] = field(default_factory=dict)
    dots: str = "bright"
    extent: tuple[tuple[int, int], tuple[int, int]] | None = None
    axes: tuple[str, str] | None = None

    def __post_init__(self) -> None:
        sizes = ("pitch", "dot_diameter") + (
            () if self.mark_diameter is None else ("mark_diameter",)
        )
        for name in sizes:
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | float | np.floating):
                raise ValueError(f"plate {name} must be a number (m), got {value!r}")
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"plate {name} must be finite and > 0 (m), got {value!r}")
            object.__setattr__(self, name, float(value))
        if self.marks and self.mark_diameter is None:
            raise ValueError("a plate with marks needs their mark_diameter")
        if self.mark_diameter is not None and not self.dot_diameter < self.mark_diameter:
            raise ValueError(
                f"the marks must be larger than the dots: mark_diameter {self.mark_diameter} "
                f"m <= dot_diameter {self.dot_diameter} m"
            )
        if self.mark_diameter is not None and not self.mark_diameter < self.pitch:
            raise ValueError(
                f"mark_diameter {self.mark_diameter} m must be smaller than the pitch "
                f"{self.pitch} m"
            )
        if self.dots not in ("bright", "dark"):
            raise ValueError(f"dots must be 'bright' or 'dark', got {self.dots!r}")
        if not isinstance(self.marks, Mapping) or len(self.marks) not in (0, 1, 3):
            raise ValueError(
                f"the plate needs three marks {{name: (i, j)}}, one with its axes, or none, "
                f"got {self.marks!r}"
            )
        marks = {str(k): _grid_pair(v, f"mark {k!r}") for k, v in self.marks.items()}
        g = np.array(list(marks.values()), dtype=float).reshape(-1, 2)
        if len(marks) == 3 and abs(np.linalg.det(np.column_stack([g, np.ones(3)]))) < 0.5:
            raise ValueError(f"the three marks must not be collinear, got {marks}")
        object.__setattr__(self, "marks", marks)
        object.__setattr__(self, "axes", _axes(self.axes, len(marks)))
        if self.extent is not None:
            ext = np.asarray(self.extent)
            if ext.shape != (2, 2) or not np.issubdtype(ext.dtype, np.integer):
                raise ValueError(
                    f"extent must be ((i_min, i_max), (j_min, j_max)) integers, got {self.extent!r}"
                )
            if np.any(ext[:, 0] > ext[:, 1]):
                raise ValueError(f"extent must have min <= max, got {self.extent!r}")
            ext_t = ((int(ext[0, 0]), int(ext[0, 1])), (int(ext[1, 0]), int(ext[1, 1])))
            for name, (i, j) in marks.items():
                if not (ext_t[0][0] <= i <= ext_t[0][1] and ext_t[1][0] <= j <= ext_t[1][1]):
                    raise ValueError(f"mark {name!r} at {(i, j)} lies outside the extent {ext_t}")
            object.__setattr__(self, "extent", ext_t)

    @property
    def mark_area_ratio(self) -> float:
        """Nominal area of a mark over that of a dot, (D_mark/D_dot)² (1 without marks)."""
        if self.mark_diameter is None:
            return 1.0
        return (self.mark_diameter / self.dot_diameter) ** 2

    def in_extent(self, indices: np.ndarray) -> np.ndarray:
        """Whether grid indices (N, 2) lie on the plate (all True when the extent is unknown)."""
        idx = np.asarray(indices).reshape(-1, 2)
        if self.extent is None:
            return np.ones(len(idx), dtype=bool)
        (i0, i1), (j0, j1) = self.extent
        return (idx[:, 0] >= i0) & (idx[:, 0] <= i1) & (idx[:, 1] >= j0) & (idx[:, 1] <= j1)

    @classmethod
    def from_dict(cls, spec: Mapping, *, source: str = "target description") -> "PlateDescription":
        """Read the ``"target"`` entry of ``experiment.json`` (SI units).

        Required: ``pitch`` and ``dot_diameter`` (m). Optional: ``marks`` ({name: [i, j]},
        three of them, or one with ``axes``) with ``mark_diameter`` (m), absent for a
        plate without marks;
        ``extent``
        ([[i_min, i_max], [j_min, j_max]]), or ``columns`` and ``rows``, which give
        the extent of synptv's layout with the origin mark in the middle of the grid
        (i from −⌊columns/2⌋ to columns − 1 − ⌊columns/2⌋, likewise j); ``dots`` or
        ``dots_are`` (text starting with "bright" or "dark"; bright by default).
        Other fields (e.g. ``thickness``) are ignored.

        Raises
        ------
        ValueError
            Naming ``source`` and the field, for a missing or malformed field.
        """
        if not isinstance(spec, Mapping):
            raise ValueError(f"{source}: the target must be a table of fields, got {spec!r}")
        missing = [k for k in ("pitch", "dot_diameter") if k not in spec]
        if "marks" in spec and "mark_diameter" not in spec:
            missing.append("mark_diameter")
        if missing:
            raise ValueError(
                f"{source}: the target description lacks the field(s) {', '.join(missing)} "
                "(needs pitch and dot_diameter in m; marks {name: [i, j]} with their "
                "mark_diameter, if the plate has marks)"
            )
        marks = spec.get("marks", {})
        if not isinstance(marks, Mapping):
            raise ValueError(f"{source}: 'marks' must map names to [i, j], got {marks!r}")
        dots = spec.get("dots", spec.get("dots_are", "bright"))
        if not isinstance(dots, str) or not dots.strip():
            raise ValueError(f"{source}: 'dots' must be 'bright' or 'dark', got {dots!r}")
        word = dots.strip().split()[0].lower()
        extent = spec.get("extent")
        if extent is None and ("columns" in spec or "rows" in spec):
            if not ("columns" in spec and "rows" in spec):
                raise ValueError(f"{source}: give both 'columns' and 'rows' (or neither)")
            columns, rows = spec["columns"], spec["rows"]
            for name, value in (("columns", columns), ("rows", rows)):
                if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                    raise ValueError(
                        f"{source}: '{name}' must be a positive integer, got {value!r}"
                    )
            extent = (
                (-(columns // 2), columns - 1 - columns // 2),
                (-(rows // 2), rows - 1 - rows // 2),
            )
        try:
            return cls(
                pitch=spec["pitch"],
                dot_diameter=spec["dot_diameter"],
                mark_diameter=spec.get("mark_diameter"),
                marks={
                    str(k): tuple(v) if isinstance(v, list | tuple) else v for k, v in marks.items()
                },
                dots=word,
                extent=None if extent is None else tuple(tuple(e) for e in extent),
                axes=spec.get("axes"),
            )
        except (ValueError, TypeError) as err:
            raise ValueError(f"{source}: {err}") from None


def _axes(axes: object, marks: int) -> tuple[str, str] | None:
    """``axes`` checked against the number of marks: a pair of image directions, one
    horizontal and one vertical, for a single mark; None otherwise."""
    if marks != 1:
        if axes is not None:
            raise ValueError(f"axes go with a single mark, the plate has {marks}")
        return None
    if axes is None:
        raise ValueError("a single mark needs the axes: the image directions of +i and +j")
    pair = tuple(axes) if isinstance(axes, list | tuple) else ()
    horizontal = sum(word in ("right", "left") for word in pair)
    vertical = sum(word in ("up", "down") for word in pair)
    if not (len(pair) == 2 and horizontal == 1 and vertical == 1):
        raise ValueError(
            f"axes must name one of right and left and one of up and down, got {axes!r}"
        )
    return pair


def _grid_pair(value: object, what: str) -> tuple[int, int]:
    arr = np.asarray(value)
    if arr.shape != (2,) or not (
        np.issubdtype(arr.dtype, np.integer)
        or (np.issubdtype(arr.dtype, np.floating) and np.all(arr == np.round(arr)))
    ):
        raise ValueError(f"{what} must be two integers (i, j), got {value!r}")
    return int(arr[0]), int(arr[1])


@dataclass(frozen=True, eq=False)
class PlaneDots:
    """The identified dots of one plate image.

    Attributes
    ----------
    pixels : ndarray, shape (N, 2), float64
        Intensity-weighted dot centres, px (x = column, y = row).
    indices : ndarray, shape (N, 2), int64
        Grid index (i, j) of each dot.
    world_xy : ndarray, shape (N, 2), float64
        Nominal plate coordinates pitch·(i, j), m.
    area : ndarray, shape (N,), int64
        Pixels of each dot above the threshold, px.
    flags : ndarray, shape (N,), uint8
        Bit flags: :data:`FLAG_MARK` (a mark), :data:`FLAG_SATURATED`
        (a pixel at the saturation level: the centroid may be biased).
    marks : dict of str to int
        Row of each mark (by its name in the description).
    missing : ndarray, shape (M, 2), int64
        Grid nodes expected on the image (whole, inside the plate's extent) but not found.
    rejected_pixels : ndarray, shape (K, 2), float64
        Centroids of blobs that were not used, px.
    rejected_reasons : tuple of str
        Why, per rejected blob: ``"edge"`` (cut by the image edge), ``"area"``
        (implausible size), ``"crowded"`` (touching another blob's window),
        ``"unindexed"`` (not on the grid), ``"outlier"`` (off the smooth grid fit).
    image_size : (int, int)
        (width, height) of the image, px.
    background : float
        Median background level, image units.
    noise : float
        Pixel noise σ, image units.
    threshold : float
        Median threshold of the dot mask, image units.
    source : str
        The image's name (used in messages).
    """

    pixels: np.ndarray
    indices: np.ndarray
    world_xy: np.ndarray
    area: np.ndarray
    flags: np.ndarray
    marks: dict[str, int]
    missing: np.ndarray
    rejected_pixels: np.ndarray
    rejected_reasons: tuple[str, ...]
    image_size: tuple[int, int]
    background: float
    noise: float
    threshold: float
    source: str = field(default="image")

    def __len__(self) -> int:
        return len(self.pixels)

    def observation(self, z: float) -> PlaneObservation:
        """The dots as a calibration plane at traverse position ``z`` (m)."""
        return PlaneObservation(
            z=float(z), pixels=self.pixels.copy(), world_xy=self.world_xy.copy()
        )
