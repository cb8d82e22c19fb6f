"""The dotted calibration plate, its imperfections, and the traverse that moves it along Z.

The plate is opaque with translucent dots and is lit from behind, so dots image bright
on a dark background. Dots are 2 mm in diameter on a 5 mm pitch; three larger dots mark
the origin and the X and Y axes (the X mark two pitches along +X from the origin, the Y
mark three pitches along +Y, so the marks cannot be confused under any view). The dots
lie on the plate's front face; its nominal position on the traverse is Z_j.

Imperfections a real plate and traverse have (all optional, truth kept):

* dot-position manufacturing error (independent Gaussian per dot, in the plate plane);
* traverse positioning error (Gaussian per plane, along Z);
* plate tilt (small rotations about X and Y, fixed for the whole traverse);
* non-flatness (a paraboloidal bow: height ``bow`` at the centre, zero at the rim);
* uneven back-lighting (a linear gradient of brightness across the plate).
"""

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class PlateDesign:
    """Nominal plate geometry, as a user would describe it to calibration software.

    Parameters
    ----------
    pitch : float
        Dot spacing, m.
    dot_diameter : float
        Diameter of ordinary dots, m.
    mark_diameter : float
        Diameter of the three marked dots, m.
    columns, rows : int
        Dots along X and Y; the origin dot sits in the middle of the grid.
    thickness : float
        Plate thickness, m (for the scene picture; dots are on the front face).
    """

    pitch: float = 5e-3
    dot_diameter: float = 2e-3
    mark_diameter: float = 3.2e-3
    columns: int = 21
    rows: int = 21
    thickness: float = 0.2e-3

    def __post_init__(self) -> None:
        for name in ("pitch", "dot_diameter", "mark_diameter", "thickness"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be > 0, got {value!r}")
        if not self.dot_diameter < self.mark_diameter < self.pitch:
            raise ValueError(
                "need dot_diameter < mark_diameter < pitch, got "
                f"{self.dot_diameter}, {self.mark_diameter}, {self.pitch}"
            )
        for name in ("columns", "rows"):
            value = getattr(self, name)
            if not isinstance(value, int) or value < 5:
                raise ValueError(f"{name} must be an integer >= 5, got {value!r}")

    @property
    def indices(self) -> np.ndarray:
        """Integer grid indices (i, j) of every dot, origin at (0, 0), shape (D, 2)."""
        i = np.arange(self.columns) - self.columns // 2
        j = np.arange(self.rows) - self.rows // 2
        ii, jj = np.meshgrid(i, j, indexing="xy")
        return np.column_stack([ii.ravel(), jj.ravel()])

    @property
    def nominal_xy(self) -> np.ndarray:
        """Nominal (X, Y) of every dot on the plate, shape (D, 2), m."""
        return self.indices * self.pitch

    @property
    def marks(self) -> dict[str, tuple[int, int]]:
        """Grid indices of the marked dots: the origin and the X and Y axis marks."""
        return {"origin": (0, 0), "x_axis": (2, 0), "y_axis": (0, 3)}

    @property
    def diameters(self) -> np.ndarray:
        """Diameter of every dot, shape (D,), m."""
        d = np.full(len(self.indices), self.dot_diameter)
        for mark in self.marks.values():
            d[np.all(self.indices == mark, axis=1)] = self.mark_diameter
        return d

    def as_dict(self) -> dict:
        """The nominal description written beside a dataset (JSON), SI units."""
        return {
            "pitch": self.pitch,
            "dot_diameter": self.dot_diameter,
            "mark_diameter": self.mark_diameter,
            "columns": self.columns,
            "rows": self.rows,
            "thickness": self.thickness,
            "marks": {name: list(ij) for name, ij in self.marks.items()},
            "dots_are": "bright on dark (back-lit translucent dots)",
        }


@dataclass(frozen=True)
class Imperfections:
    """Deviations of the physical plate and traverse from their nominal geometry.

    Parameters
    ----------
    dot_position_std : float
        Manufacturing scatter of each dot centre in the plate plane, m (per axis).
    traverse_std : float
        Positioning error of the traverse per plane, along Z, m.
    tilt : tuple of 2 floats
        Rotation of the plate about X and about Y, rad.
    bow : float
        Out-of-plane height of the plate centre relative to its rim, m.
    lighting_gradient : tuple of 2 floats
        Relative change of back-light brightness per metre along X and Y, 1/m.
    """

    dot_position_std: float = 0.0
    traverse_std: float = 0.0
    tilt: tuple[float, float] = (0.0, 0.0)
    bow: float = 0.0
    lighting_gradient: tuple[float, float] = (0.0, 0.0)

    def __post_init__(self) -> None:
        for name in ("dot_position_std", "traverse_std"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be >= 0, got {value!r}")
        for name in ("tilt", "lighting_gradient"):
            value = np.asarray(getattr(self, name), dtype=float)
            if value.shape != (2,) or not np.all(np.isfinite(value)):
                raise ValueError(f"{name} must be two finite numbers, got {getattr(self, name)!r}")
        if not np.isfinite(self.bow):
            raise ValueError(f"bow must be finite, got {self.bow!r}")


#: Imperfections of a machined laboratory plate on a good traverse (docs/optics.md §6): 5 µm
#: dot-position scatter (0.05 px at 0.1 mm per pixel), a 10 µm traverse, 0.1° of tilt.
#: How the calibration comparison depends on the dot-centre scatter is a study of its
#: own (``validation.studies.calibration_methods``): printed plates scatter by tenths of a pixel.
REALISTIC = Imperfections(
    dot_position_std=5e-6,
    traverse_std=10e-6,
    tilt=(np.deg2rad(0.1), np.deg2rad(-0.07)),
    bow=20e-6,
    lighting_gradient=(2.0, -1.5),
)


@dataclass(frozen=True)
class PlatePose:
    """The physical plate at one traverse position.

    Attributes
    ----------
    z_nominal : float
        Traverse reading Z_j, m.
    z_actual : float
        Where the plate centre really is, m.
    rotation : ndarray, shape (3, 3)
        Plate frame → world (columns: plate u, v and normal axes).
    """

    z_nominal: float
    z_actual: float
    rotation: np.ndarray


@dataclass(frozen=True)
class PhysicalPlate:
    """A plate design with its drawn imperfections, on a traverse.

    Attributes
    ----------
    design : PlateDesign
        Nominal geometry.
    imperfections : Imperfections
        The statistics the deviations were drawn from.
    dot_xy : ndarray, shape (D, 2)
        Actual dot centres in the plate frame, m.
    poses : tuple of PlatePose
        One per traverse position.
    """

    design: PlateDesign
    imperfections: Imperfections
    dot_xy: np.ndarray
    poses: tuple[PlatePose, ...] = field(repr=False)

    def surface_height(self, uv: np.ndarray) -> np.ndarray:
        """Bow of the plate surface at plate coordinates uv (..., 2), m (along the normal)."""
        uv = np.asarray(uv)
        radius2 = (0.5 * self.design.pitch) ** 2 * (
            (self.design.columns - 1) ** 2 + (self.design.rows - 1) ** 2
        )
        return self.imperfections.bow * (1.0 - np.sum(uv**2, axis=-1) / radius2)

    def plate_to_world(self, plane: int, uv: np.ndarray) -> np.ndarray:
        """World points of plate-surface coordinates uv (N, 2) at traverse plane j, m."""
        pose = self.poses[plane]
        uv = np.asarray(uv, dtype=float)
        local = np.column_stack([uv, self.surface_height(uv)])
        return local @ pose.rotation.T + np.array([0.0, 0.0, pose.z_actual])

    def dot_centres(self, plane: int) -> np.ndarray:
        """True world centres of every dot at traverse plane j, shape (D, 3), m."""
        return self.plate_to_world(plane, self.dot_xy)

    def brightness(self, uv: np.ndarray) -> np.ndarray:
        """Relative back-light brightness at plate coordinates uv (..., 2)."""
        g = np.asarray(self.imperfections.lighting_gradient)
        return np.clip(1.0 + np.asarray(uv) @ g, 0.05, None)

    @property
    def z_nominal(self) -> np.ndarray:
        """Traverse readings Z_j, shape (N_Z,), m."""
        return np.array([p.z_nominal for p in self.poses])


def traverse_positions(planes: int = 13, spacing: float = 1e-3) -> np.ndarray:
    """Nominal Z_j of ``planes`` positions ``spacing`` apart, centred on Z = 0, m."""
    if not isinstance(planes, int) or planes < 2:
        raise ValueError(f"a traverse needs at least two planes, got {planes!r}")
    if not (np.isfinite(spacing) and spacing > 0):
        raise ValueError(f"spacing must be > 0, got {spacing!r}")
    return (np.arange(planes) - (planes - 1) / 2) * spacing


def _rotation_xy(tilt_x: float, tilt_y: float) -> np.ndarray:
    cx, sx, cy, sy = np.cos(tilt_x), np.sin(tilt_x), np.cos(tilt_y), np.sin(tilt_y)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    return ry @ rx


def build_plate(
    design: PlateDesign,
    z_positions: np.ndarray,
    *,
    imperfections: Imperfections = Imperfections(),
    rng: np.random.Generator | int | None = None,
) -> PhysicalPlate:
    """Draw a physical plate and its traverse poses.

    Parameters
    ----------
    design : PlateDesign
        Nominal geometry.
    z_positions : array_like, shape (N_Z,)
        Traverse readings Z_j, m; at least two, distinct.
    imperfections : Imperfections
        Deviation statistics (none by default).
    rng : numpy.random.Generator, int or None
        Source of the deviations.

    Returns
    -------
    PhysicalPlate
    """
    z = np.asarray(z_positions, dtype=float)
    if z.ndim != 1 or len(z) < 2 or len(np.unique(z)) != len(z) or not np.all(np.isfinite(z)):
        raise ValueError(f"need at least two distinct, finite plane positions, got {z_positions!r}")
    rng = np.random.default_rng(rng)
    xy = design.nominal_xy + rng.normal(
        0.0, imperfections.dot_position_std, design.nominal_xy.shape
    )
    rotation = _rotation_xy(*imperfections.tilt)
    errors = rng.normal(0.0, imperfections.traverse_std, len(z))
    poses = tuple(
        PlatePose(float(zj), float(zj + e), rotation) for zj, e in zip(z, errors, strict=True)
    )
    return PhysicalPlate(design=design, imperfections=imperfections, dot_xy=xy, poses=poses)
