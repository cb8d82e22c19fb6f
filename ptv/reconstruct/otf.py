"""The optical transfer function (OTF): the particle image of one camera, by image region.

A particle image is modelled as a pixel-integrated elliptical Gaussian (the kernels of
:mod:`ptv.reconstruct._spots`) with covariance

    Σ = [[σ_x², ρ σ_x σ_y], [ρ σ_x σ_y, σ_y²]]  (px²),

whose major axis makes the angle θ = ½ atan2(2ρσ_xσ_y, σ_x² − σ_y²) with the image x
axis (towards +y, i.e. downwards in the image), and an integrated intensity that a
typical particle gives there (image units above the background, e.g. DN). The four
numbers vary smoothly over the sensor: they are given at the centres of a coarse grid of
regions (rows × columns) and interpolated bilinearly between them, held constant beyond
the outermost centres.

Optionally they also vary with the particle's depth (its world coordinate along
``depth_axis``, m), on a grid of depth slabs: Schanz et al. (2013, Meas. Sci. Technol.
24 024009) measure the OTF per sub-volume, since defocus widens the images of particles
away from the plane in focus, and the light sheet's profile dims them. Without a depth
grid the spot of a region is the average over the volume's depth.

The OTF is measured from particle images by :func:`ptv.reconstruct.measure_otf`, its
depth dependence from reconstructed particles by :func:`ptv.reconstruct.refine_otf`,
or it is given (:meth:`OpticalTransferFunction.uniform`).
"""

from dataclasses import dataclass

import numpy as np
from scipy.special import erf

from ptv.reconstruct._spots import RHO_SEPARABLE


def _grid(name: str, value: object) -> np.ndarray:
    arr = np.asarray(value, dtype=np.float64)
    if arr.ndim != 1 or arr.size < 1 or not np.isfinite(arr).all() or np.any(np.diff(arr) <= 0):
        raise ValueError(f"{name} must be a non-empty increasing 1-D array of px, got {value!r}")
    return arr


@dataclass(frozen=True, eq=False)
class OpticalTransferFunction:
    """Particle-image model of one camera on a grid of image regions.

    Attributes
    ----------
    shape : (H, W)
        Rows and columns of the camera's images.
    grid_x : ndarray, shape (nx,)
        Column coordinate of each region centre, px, increasing.
    grid_y : ndarray, shape (ny,)
        Row coordinate of each region centre, px, increasing.
    sigma_x, sigma_y : ndarray, shape (nz, ny, nx) (or (ny, nx) without depth grid)
        Gaussian widths along the image x and y axes, px, > 0.
    rho : ndarray, shape (nz, ny, nx)
        Correlation coefficient of x and y in the spot, in (−1, 1) (0: axes aligned).
    intensity : ndarray, shape (nz, ny, nx)
        Integrated intensity of a typical particle image, image units (e.g. DN above
        the background), > 0. Reconstructed particles carry an intensity relative to it.
    counts : ndarray of int, shape (nz, ny, nx)
        Particle images measured in each cell (0 where the model was given).
    background : float
        Background level of the images it was measured on, image units.
    noise : float
        Background noise (σ) of those images, image units, >= 0.
    grid_z : ndarray, shape (nz,), optional
        Depth of each slab's centre along ``depth_axis``, m, increasing; None: one slab
        (no depth dependence).
    depth_axis : int
        World axis (0: X, 1: Y, 2: Z) of the depth.
    """

    shape: tuple[int, int]
    grid_x: np.ndarray
    grid_y: np.ndarray
    sigma_x: np.ndarray
    sigma_y: np.ndarray
    rho: np.ndarray
    intensity: np.ndarray
    counts: np.ndarray
    background: float = 0.0
    noise: float = 0.0
    grid_z: np.ndarray | None = None
    depth_axis: int = 2

    def __post_init__(self) -> None:
        try:
            rows, cols = (int(v) for v in self.shape)
        except (TypeError, ValueError):
            raise ValueError(f"shape must be (H, W), got {self.shape!r}") from None
        if rows < 1 or cols < 1:
            raise ValueError(f"shape must be (H, W) with H, W >= 1, got {self.shape!r}")
        object.__setattr__(self, "shape", (rows, cols))
        gx = _grid("grid_x", self.grid_x)
        gy = _grid("grid_y", self.grid_y)
        object.__setattr__(self, "grid_x", gx)
        object.__setattr__(self, "grid_y", gy)
        gz = np.zeros(1) if self.grid_z is None else _grid("grid_z", self.grid_z)
        object.__setattr__(self, "grid_z", gz)
        if self.depth_axis not in (0, 1, 2):
            raise ValueError(f"depth_axis must be 0, 1 or 2, got {self.depth_axis!r}")
        want = (gz.size, gy.size, gx.size)
        for name, low, high in (
            ("sigma_x", 0.0, np.inf),
            ("sigma_y", 0.0, np.inf),
            ("rho", -1.0, 1.0),
            ("intensity", 0.0, np.inf),
        ):
            arr = np.array(getattr(self, name), dtype=np.float64)
            if arr.shape == want[1:]:
                arr = arr[None]
            if arr.shape != want:
                raise ValueError(
                    f"{name} must have shape {want} (grid_z, grid_y, grid_x), got {arr.shape}"
                )
            if not (np.isfinite(arr).all() and np.all(arr > low) and np.all(arr < high)):
                raise ValueError(f"{name} must lie in ({low}, {high}), got {arr!r}")
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)
        counts = np.array(self.counts, dtype=np.int64)
        if counts.shape == want[1:]:
            counts = counts[None]
        if counts.shape != want or np.any(counts < 0):
            raise ValueError(f"counts must be >= 0 with shape {want}, got {counts!r}")
        object.__setattr__(self, "counts", counts)
        for name in ("background", "noise"):
            value = float(getattr(self, name))
            if not np.isfinite(value) or (name == "noise" and value < 0):
                raise ValueError(f"{name} must be finite (noise >= 0), got {value!r}")
            object.__setattr__(self, name, value)

    @classmethod
    def uniform(
        cls,
        shape: tuple[int, int],
        sigma: float,
        *,
        sigma_y: float | None = None,
        rho: float = 0.0,
        intensity: float = 1.0,
        background: float = 0.0,
        noise: float = 0.0,
    ) -> "OpticalTransferFunction":
        """The same spot everywhere on the sensor.

        Parameters
        ----------
        shape : (H, W)
            Image rows and columns.
        sigma : float
            σ_x, px (and σ_y unless given).
        sigma_y : float, optional
            σ_y, px.
        rho : float
            Correlation coefficient, in (−1, 1).
        intensity : float
            Integrated intensity of a typical particle, image units.
        background, noise : float
            Background level and noise of the images, image units.
        """
        one = np.ones((1, 1, 1))
        rows, cols = shape
        return cls(
            shape=(rows, cols),
            grid_x=np.array([0.5 * (cols - 1)]),
            grid_y=np.array([0.5 * (rows - 1)]),
            sigma_x=sigma * one,
            sigma_y=(sigma if sigma_y is None else sigma_y) * one,
            rho=rho * one,
            intensity=intensity * one,
            counts=np.zeros((1, 1, 1), dtype=np.int64),
            background=background,
            noise=noise,
        )

    @property
    def has_depth(self) -> bool:
        """Whether the model varies with the particle's depth (more than one slab)."""
        return self.grid_z.size > 1

    @property
    def orientation(self) -> np.ndarray:
        """Angle θ of each cell's major axis from the image x axis, rad, (nz, ny, nx)."""
        sxy = self.rho * self.sigma_x * self.sigma_y
        return 0.5 * np.arctan2(2 * sxy, self.sigma_x**2 - self.sigma_y**2)

    def at(
        self, xy: np.ndarray, points: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The spot model at image points, interpolated (bi- or trilinearly) between cells.

        Parameters
        ----------
        xy : ndarray, shape (N, 2)
            Image points (x = column, y = row), px; NaN rows give NaN.
        points : ndarray, shape (N, 3), optional
            The particles' world positions, m, for an OTF with a depth grid (without
            them, the middle slab is used).

        Returns
        -------
        sigma_x, sigma_y, rho, intensity : ndarray, shape (N,)
            As the attributes (px, px, 1, image units). ρ below 10⁻⁶ in magnitude is
            returned as 0 (axis-aligned spot, exact separable integration).
        """
        xy = np.asarray(xy, dtype=np.float64)
        if xy.ndim != 2 or xy.shape[1] != 2:
            raise ValueError(f"xy must have shape (N, 2), got {xy.shape}")
        ix, fx = _cell(self.grid_x, xy[:, 0])
        iy, fy = _cell(self.grid_y, xy[:, 1])
        if self.has_depth and points is not None:
            depth = np.asarray(points, dtype=np.float64)[:, self.depth_axis]
            iz, fz = _cell(self.grid_z, depth)
        else:
            iz = np.full(len(xy), (self.grid_z.size - 1) // 2, dtype=np.intp)
            fz = np.zeros(len(xy)) if self.grid_z.size % 2 else np.full(len(xy), 0.5)
            if self.grid_z.size == 1:
                fz[:] = 0.0
        out = []
        for table in (self.sigma_x, self.sigma_y, self.rho, self.intensity):
            if table.size == 1:
                value = np.full(len(xy), float(table.flat[0]))
            else:
                value = _trilinear(table, iz, fz, iy, fy, ix, fx)
            out.append(np.where(np.isfinite(xy).all(axis=1), value, np.nan))
        rho = out[2]
        out[2] = np.where(np.abs(rho) < RHO_SEPARABLE, 0.0, rho)
        return out[0], out[1], out[2], out[3]

    def typical_peak(self) -> float:
        """Brightest pixel of a typical particle centred on a pixel, median over regions,
        image units (the peak threshold of the reconstruction is relative to it)."""
        return float(np.median(self.intensity * peak_fraction(self.sigma_x, self.sigma_y)))


def peak_fraction(sigma_x: np.ndarray, sigma_y: np.ndarray) -> np.ndarray:
    """Light on the central pixel of a unit axis-aligned spot centred on it, same shape."""
    with np.errstate(invalid="ignore", divide="ignore"):
        return erf(0.5 / (np.sqrt(2) * sigma_x)) * erf(0.5 / (np.sqrt(2) * sigma_y))


def _trilinear(table, iz, fz, iy, fy, ix, fx) -> np.ndarray:
    """Table (nz, ny, nx) interpolated at lower indices and fractions per axis."""
    nz, ny, nx = table.shape
    iz1 = np.minimum(iz + 1, nz - 1)
    iy1 = np.minimum(iy + 1, ny - 1)
    ix1 = np.minimum(ix + 1, nx - 1)

    def plane(k):
        return (1 - fy) * ((1 - fx) * table[k, iy, ix] + fx * table[k, iy, ix1]) + fy * (
            (1 - fx) * table[k, iy1, ix] + fx * table[k, iy1, ix1]
        )

    return (1 - fz) * plane(iz) + fz * plane(iz1)


def _cell(grid: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Lower grid index and fraction in [0, 1] of each value, clamped to the grid."""
    if grid.size == 1:
        return np.zeros(v.shape, dtype=np.intp), np.zeros(v.shape)
    vv = np.clip(np.nan_to_num(v, nan=grid[0]), grid[0], grid[-1])
    i = np.clip(np.searchsorted(grid, vv, side="right") - 1, 0, grid.size - 2)
    f = (vv - grid[i]) / (grid[i + 1] - grid[i])
    return i, np.clip(f, 0.0, 1.0)
