"""Images of the back-lit calibration plate, by per-pixel ray casting (docs/optics.md §4, §6–7).

Model
-----
The plate (``simulator.target``) is opaque with translucent, back-lit dots: dots are
bright on a black background. A pixel at (x, y) (OpenCV convention: x = column,
y = row, the centre of the top-left pixel at (0, 0); fill factor 1) records the mean
radiance over its area, estimated with S × S sub-samples on a regular grid at
(x + (a + ½)/S − ½, y + (b + ½)/S − ½), a, b = 0 … S − 1. For every sub-sample:

1. its exact ray in the water (``Camera.pixel_to_ray``, evaluated by a compiled copy
   of the same mapping, ``simulator.render._raycast``);
2. the intersection with the plate plane of the pose at traverse plane j, then
   ``bow_iterations`` fixed-point steps s ← (h(uv) − a_z)/b_z along the ray, which put
   the point on the bowed surface (plate frame height h = ``plate.surface_height``,
   which must be a paraboloid h0 + q|uv|²: it is probed and checked, and any other
   surface model is refused rather than misrendered). Each step shrinks the error
   by the surface slope times the tangent of the incidence angle (< 10⁻³ for a
   20 µm bow), so two steps leave < 10⁻¹¹ m;
3. its plate coordinates uv and the dot whose nominal grid cell contains it (dots
   are discs of the design's diameters centred at ``plate.dot_xy``; every dot lies
   inside its own cell, which is checked);
4. radiance = ``plate.brightness(uv)`` (uneven back-lighting) × dot coverage.

Coverage, three modes:

- ``antialias=True`` (default, hard edge): the exact fraction of the sub-sample's
  own 1/S × 1/S square (in pixels) that lies inside the disc, with the disc edge
  taken as straight across that square. With r the distance from the dot centre in
  uv, g = ∇_xy r (from the pixel's Jacobian ∂uv/∂xy, by central differences of four
  extra rays at ±½ px) and δ = (r − R)/|g| the signed distance in pixels, the
  fraction is P(X + Y < −δ) for independent X ~ U(±a|g_x|/2|g|), Y ~ U(±a|g_y|/2|g|),
  a = 1/S (a piecewise quadratic). The edge curvature within a sub-sample (radius
  ≳ 10 px against a/2 = 0.125 px) is neglected. This removes the aliasing of point
  sampling: dot centroids agree with a forward-projected quadrature to ~5·10⁻⁵ px
  at S = 4 (point sampling: ~10⁻² px), totals to ~10⁻⁴.
- ``antialias=False``: the indicator r < R at the sub-sample point.
- ``edge_width`` w > 0 (soft edge): the linear ramp clip(½ − (r − R)/w, 0, 1) at
  the sub-sample point. It adds π w²/12 to each dot's area.

The pixel value is the mean over its sub-samples times ``full_brightness`` (expected
photo-electrons of a pixel wholly inside a dot where the brightness is 1); the result
is the expected signal, float64 e⁻, to feed ``Sensor.record``.

Adaptive supersampling (exact): one ray per pixel centre first. From the distances
in uv between neighbouring centres, each pixel gets a bound m on how far from its
centre's uv its sub-samples (with ``antialias``, their squares) can reach:
½(|Δ_x uv| + |Δ_y uv|) (× (S − 1)/S for point samples), Δ the larger of the forward
and backward differences, times a safety factor 1.5. Pixels whose centre lies more
than m (+ w/2) inside a dot take the centre's brightness; more than m outside, 0;
the others, and every pixel next to one whose ray is invalid, are supersampled
(about 4 % of a 2048 × 1088 plate image). Because the brightness is linear across the plate and
a pixel's footprint is linear to ~10⁻⁶, the centre value equals the sub-sample mean
to ~10⁻⁸ relative. ``adaptive=False`` supersamples every pixel (the reference path).

Ground truth, per dot (``PlateImage``): its world centre, the projection of that
centre (``camera.project``), whether its whole image lies on the sensor, and the
intensity-weighted centroid and total of the light rendered for it, computed from
the same sub-samples (each at its point; interior pixels at their centre, see above):
exactly the light in the image, placed to ~10⁻⁴ px. The centroid is
*not* the projected centre: the image of a disc is not centred on the image of the
disc's centre. To second order in R, with L = ∂(x, y)/∂(u, v) the image Jacobian
(px/m) and c = ∇_uv ln Z the relative gradient of the depth along the plate (1/m),

    centroid − projected ≈ −R² L c,

of magnitude ≈ R² f_px sin θ cos θ / Z² toward the image of the plate's nearer side
(θ: angle between the line of sight and the plate normal; f_px: principal distance
in px; Z: distance, m; pinhole; through a window Z is roughly the apparent
distance). For 2 mm dots at 0.9 m seen 35° off the normal with f_px ≈ 9700 this is
≈ 0.006 px, 0.014 px for the 3.2 mm marks. (Derivation: expand the plane-to-image
homography to second order in the plate offset u from the dot centre; the image
area element is ∝ (1 + c·u)⁻³; averaging over the disc, E[u uᵀ] = (R²/4) I, the
terms add up to −R² L c.) An uneven back-light moves it further by L (R²/4) ∇b/b
(≈ 0.005 px for a 2 /m gradient). Both are in ``PlateImage.bias``. Through the
benchmark's oblique window (``benchmarks/bench_plate.py``) it is 0.005–0.006 px for
the dots and 0.015 px for the marks of an evenly lit plate, about twice that with
the ``REALISTIC`` back-light gradient.

Defocus (``defocus=True``), a locally uniform approximation: each dot's light is
blurred by its own Gaussian, of σ = d_blur/4 with d_blur = ``defocus_blur`` of the
optics at the dot's centre (σ = d/4 matches the second moment of the uniform blur
disc of diameter d). The variation of the blur across one dot (a few per cent of it
for a 2 mm dot) is neglected. The kernel is scipy's sampled Gaussian, normalised and
symmetric, so each dot's total light and centroid are unchanged unless its blurred
image reaches the sensor edge; light that the sharp image has off the sensor is not
blurred back onto it.

No randomness is involved: the image is the noise-free expectation.
"""

import logging
import time
from dataclasses import dataclass
from numbers import Integral

import numpy as np
from scipy import ndimage

from simulator.optics.camera import Camera
from simulator.optics.scheimpflug import defocus_blur
from simulator.render._checks import positive_float
from simulator.render._raycast import cast_to_plate
from simulator.render.plate_kernels import classify, coverage
from simulator.target import PhysicalPlate

logger = logging.getLogger(__name__)

#: Safety factor on the sub-sample reach m of the adaptive supersampling.
MARGIN_SAFETY = 1.5
#: Pixel centres cast per call of the ray kernel (bounds the temporaries).
CENTRE_CHUNK = 1 << 18
#: Sub-sample rays evaluated per chunk.
SUBSAMPLE_CHUNK = 1 << 18
#: Rim points per dot used to decide whether a dot's image is wholly on the sensor.
RIM_POINTS = 64
#: A dot is "on the sensor" when its image stays this far inside the edge, px (plus 3σ
#: of blur with defocus).
ON_SENSOR_MARGIN = 0.1
#: Blur σ below which the defocus filter is skipped for a dot, px.
MIN_BLUR_SIGMA = 0.05


@dataclass(frozen=True, eq=False)
class PlateImage:
    """Expected photo-electron image of the plate at one traverse plane, with its truth.

    Attributes
    ----------
    image : ndarray, shape (H, W), float64
        Expected signal photo-electrons per pixel, e⁻ (no noise, no background).
    plane : int
        Traverse plane index j.
    supersampling : int
        S: sub-samples per pixel are S × S.
    full_brightness : float
        e⁻ of a pixel wholly inside a dot of back-light brightness 1.
    indices : ndarray, shape (D, 2), int
        Grid indices (i, j) of every dot (``PlateDesign.indices``).
    diameters : ndarray, shape (D,)
        Dot diameters, m (marks are larger).
    marks : dict of str to int
        Row of each marked dot (``PlateDesign.marks``: origin, x_axis, y_axis).
    world : ndarray, shape (D, 3)
        True world centre of every dot at this plane, m.
    projected : ndarray, shape (D, 2)
        ``camera.project(world)``: the image of each centre, px; NaN if not imaged.
    on_sensor : ndarray of bool, shape (D,)
        True where the dot's whole image (and 3σ of its blur) lies on the sensor.
    centroid : ndarray, shape (D, 2)
        Intensity-weighted centroid of the dot's rendered light (before the defocus
        blur, which preserves it away from the sensor edge), px; NaN for dots that
        put no light on the sensor.
    electrons : ndarray, shape (D,)
        Total of the dot's rendered light on the sensor (sharp image), e⁻.
    blur_sigma : ndarray, shape (D,)
        Gaussian σ of the defocus blur applied to each dot, px (0 without defocus).
    supersampled_pixels : int
        Pixels evaluated with S × S sub-samples (the others exactly from their centre).
    """

    image: np.ndarray
    plane: int
    supersampling: int
    full_brightness: float
    indices: np.ndarray
    diameters: np.ndarray
    marks: dict[str, int]
    world: np.ndarray
    projected: np.ndarray
    on_sensor: np.ndarray
    centroid: np.ndarray
    electrons: np.ndarray
    blur_sigma: np.ndarray
    supersampled_pixels: int

    @property
    def shape(self) -> tuple[int, int]:
        """(H, W) of the image, px."""
        return self.image.shape  # type: ignore[return-value]

    @property
    def bias(self) -> np.ndarray:
        """centroid − projected, shape (D, 2), px: the disc's perspective/refraction bias."""
        return self.centroid - self.projected

    @property
    def visible(self) -> np.ndarray:
        """(D,) bool: the dot put some light on the sensor."""
        return self.electrons > 0


@dataclass(frozen=True)
class _Dots:
    """Dot lookup in plate coordinates (private): every dot lies in its nominal cell."""

    xy: np.ndarray  # (D, 2) actual centres, m
    radius: np.ndarray  # (D,) m
    cells: np.ndarray  # (rows, columns) dot index of each nominal grid cell
    pitch: float
    offset: tuple[int, int]  # grid index of cell (0, 0): (columns // 2, rows // 2)
    edge_width: float

    @property
    def args(self) -> tuple:
        """Arguments of the compiled kernels."""
        return (
            self.cells, self.pitch, self.offset[0], self.offset[1], self.xy, self.radius,
            self.edge_width,
        )


def _dots(plate: PhysicalPlate, edge_width: float) -> _Dots:
    design = plate.design
    idx = design.indices
    offset = (design.columns // 2, design.rows // 2)
    cells = np.full((design.rows, design.columns), -1, dtype=np.int64)
    cells[idx[:, 1] + offset[1], idx[:, 0] + offset[0]] = np.arange(len(idx))
    radius = 0.5 * design.diameters
    xy = np.ascontiguousarray(plate.dot_xy, dtype=np.float64)
    reach = np.max(np.abs(xy - design.nominal_xy), axis=1) + radius + 0.5 * edge_width
    worst = int(np.argmax(reach))
    if reach[worst] >= 0.5 * design.pitch:
        raise ValueError(
            f"dot {idx[worst].tolist()} reaches {reach[worst]:.6g} m from its nominal centre "
            f"(radius + manufacturing offset + half edge_width), beyond half the pitch "
            f"{0.5 * design.pitch:.6g} m: the renderer needs every dot inside its own grid cell"
        )
    return _Dots(xy, radius, cells, float(design.pitch), offset, float(edge_width))


def _bow_model(plate: PhysicalPlate) -> tuple[float, float]:
    """(h0, q) with ``plate.surface_height(uv) = h0 + q |uv|²``, probed and checked.

    The compiled ray caster evaluates the surface in this form; a plate whose surface
    is not a rotationally symmetric paraboloid is refused rather than misrendered.
    """
    design = plate.design
    span = 0.5 * design.pitch * max(design.columns, design.rows)
    h0 = float(plate.surface_height(np.zeros((1, 2)))[0])
    q = float(plate.surface_height(np.array([[span, 0.0]]))[0] - h0) / span**2
    probe = span * np.array([[0.0, 1.0], [-0.7, 0.3], [0.4, -0.9], [0.05, 0.02]])
    got = plate.surface_height(probe)
    want = h0 + q * np.sum(probe**2, axis=1)
    scale = max(abs(h0), abs(q) * span**2, 1e-300)
    if not np.allclose(got, want, rtol=0.0, atol=1e-9 * scale):
        raise ValueError(
            "plate.surface_height is not of the form h0 + q (u² + v²), which the plate "
            f"renderer supports; probed {got.tolist()} against {want.tolist()} m"
        )
    return h0, q


@dataclass(frozen=True, eq=False)
class _Light:
    """Accumulators of a render (private; arrays filled in place).

    value, label: (H·W,) pixel value (units of full brightness) and lit dot (−1: none);
    light, moment_x, moment_y: (D,) Σ w, Σ w x, Σ w y of each dot's light.
    """

    value: np.ndarray
    label: np.ndarray
    light: np.ndarray
    moment_x: np.ndarray
    moment_y: np.ndarray

    @classmethod
    def empty(cls, n_dots: int, n_pixels: int) -> "_Light":
        return cls(
            np.zeros(n_pixels), np.full(n_pixels, -1, dtype=np.int64), np.zeros(n_dots),
            np.zeros(n_dots), np.zeros(n_dots),
        )

    def add(self, k: np.ndarray, w: np.ndarray, x: np.ndarray, y: np.ndarray) -> None:
        """Add light w at image positions (x, y), px, to dots k."""
        n = len(self.light)
        self.light[:] += np.bincount(k, weights=w, minlength=n)
        self.moment_x[:] += np.bincount(k, weights=w * x, minlength=n)
        self.moment_y[:] += np.bincount(k, weights=w * y, minlength=n)


def _centre_pass(
    hits, plate: PhysicalPlate, dots: _Dots, acc: _Light, width: int, height: int,
    factor: float,
) -> np.ndarray:
    """Cast one ray per pixel centre, fill the pixels wholly inside or outside a dot, and
    return the flat indices of the pixels that need supersampling."""
    n_pixels = width * height
    uv = np.empty((n_pixels, 2))
    cols = np.arange(width, dtype=np.float64)
    rows_per_chunk = max(1, CENTRE_CHUNK // width)
    for r0 in range(0, height, rows_per_chunk):
        r1 = min(height, r0 + rows_per_chunk)
        uv[r0 * width : r1 * width] = hits(
            np.tile(cols, r1 - r0), np.repeat(np.arange(r0, r1, dtype=np.float64), width)
        )
    state = np.empty((height, width), dtype=np.int8)
    classify(
        uv.reshape(height, width, 2), factor, *dots.args, state,
        acc.label.reshape(height, width),
    )
    state = state.ravel()
    pure = np.flatnonzero(state == 1)
    if pure.size:
        brightness = plate.brightness(uv[pure])
        acc.value[pure] = brightness
        acc.add(acc.label[pure], brightness, pure % width, pure // width)
    return np.flatnonzero(state == 2)


def _subsample_pass(
    hits, plate: PhysicalPlate, dots: _Dots, acc: _Light, todo: np.ndarray, width: int,
    s_count: int, area_coverage: bool,
) -> None:
    """Evaluate the pixels ``todo`` (flat indices) with S × S sub-samples each."""
    offsets = (np.arange(s_count) + 0.5) / s_count - 0.5
    sub_dx = np.tile(offsets, s_count)
    sub_dy = np.repeat(offsets, s_count)
    n_sub = s_count * s_count
    # Jacobian ∂(u, v)/∂(x, y) of each supersampled pixel from four rays at ±½ px.
    jac_dx = np.array([0.5, -0.5, 0.0, 0.0])
    jac_dy = np.array([0.0, 0.0, 0.5, -0.5])
    pixels_per_chunk = max(1, SUBSAMPLE_CHUNK // n_sub)
    for lo in range(0, todo.size, pixels_per_chunk):
        pix = todo[lo : lo + pixels_per_chunk]
        px = (pix % width).astype(np.float64)
        py = (pix // width).astype(np.float64)
        if area_coverage:
            ends = hits(
                (px[:, None] + jac_dx[None, :]).ravel(), (py[:, None] + jac_dy[None, :]).ravel()
            ).reshape(-1, 4, 2)
            jac = np.stack([ends[:, 0] - ends[:, 1], ends[:, 2] - ends[:, 3]], axis=2)
        else:
            jac = np.full((pix.size, 2, 2), np.nan)
        xs = (px[:, None] + sub_dx[None, :]).ravel()
        ys = (py[:, None] + sub_dy[None, :]).ravel()
        uv = hits(xs, ys)
        k = np.empty(xs.size, dtype=np.int64)
        weight = np.empty(xs.size)
        coverage(uv, jac, n_sub, 1.0 / s_count, *dots.args, k, weight)
        lit = np.flatnonzero(k >= 0)
        w_lit = weight[lit] * plate.brightness(uv[lit]) / n_sub
        weight[lit] = w_lit
        acc.value[pix] = weight.reshape(-1, n_sub).sum(axis=1)
        acc.label[pix] = k.reshape(-1, n_sub).max(axis=1)
        acc.add(k[lit], w_lit, xs[lit], ys[lit])


def _check_inputs(
    plate: object, camera: object, plane: object, supersampling: object, edge_width: object,
    bow_iterations: object,
) -> None:
    if not isinstance(plate, PhysicalPlate):
        raise ValueError(
            f"plate must be a simulator.target.PhysicalPlate; got {type(plate).__name__}"
        )
    if not isinstance(camera, Camera):
        raise ValueError(
            f"camera must be a simulator.optics.Camera; got {type(camera).__name__}"
        )
    n_planes = len(plate.poses)
    if (
        not isinstance(plane, Integral)
        or isinstance(plane, bool)
        or not 0 <= plane < n_planes
    ):
        raise ValueError(
            f"plane must be a traverse plane index from 0 to {n_planes - 1} "
            f"(the plate has {n_planes} planes); got {plane!r}"
        )
    if (
        not isinstance(supersampling, Integral)
        or isinstance(supersampling, bool)
        or not 1 <= supersampling <= 32
    ):
        raise ValueError(
            f"supersampling must be an integer from 1 to 32 (S × S sub-samples per pixel); "
            f"got {supersampling!r}"
        )
    positive_float("edge_width", edge_width, allow_zero=True)
    if (
        not isinstance(bow_iterations, Integral)
        or isinstance(bow_iterations, bool)
        or bow_iterations < 0
    ):
        raise ValueError(f"bow_iterations must be an integer >= 0; got {bow_iterations!r}")


def render_plate(
    plate: PhysicalPlate,
    camera: Camera,
    plane: int,
    *,
    supersampling: int = 4,
    full_brightness: float = 4000.0,
    edge_width: float = 0.0,
    defocus: bool = False,
    bow_iterations: int = 2,
    antialias: bool = True,
    adaptive: bool = True,
) -> PlateImage:
    """Render the back-lit plate at traverse plane ``plane`` as seen by ``camera``.

    Parameters
    ----------
    plate : PhysicalPlate
        Plate, imperfections and traverse poses (``simulator.target.build_plate``).
    camera : Camera
        Physical camera (lens, tilted sensor, windows); the image has the shape
        (rows, cols) = (height, width) of ``camera.lens.sensor_size``.
    plane : int
        Traverse plane index j, 0 ≤ j < number of planes.
    supersampling : int
        S, 1 to 32: each pixel is the mean of S × S sub-samples (module docstring).
    full_brightness : float
        Expected photo-electrons of a pixel wholly inside a dot of back-light
        brightness 1, e⁻, > 0.
    edge_width : float
        Width of a linear soft edge of the dots on the plate, m, ≥ 0 (0: hard edge).
    defocus : bool
        Blur every dot with a Gaussian of σ = d_blur/4, d_blur = ``defocus_blur`` at
        its centre (a locally uniform approximation; module docstring).
    bow_iterations : int
        Fixed-point steps along each ray onto the bowed surface, ≥ 0 (2 suffice).
    antialias : bool
        True: each sub-sample takes the exact fraction of its 1/S × 1/S square inside
        the dot (edge locally straight; module docstring). False: the dot indicator
        at the sub-sample point. Ignored with a soft edge (point-sampled ramp).
    adaptive : bool
        True: supersample only pixels near a dot edge (exact; module docstring).
        False: supersample every pixel (reference path, ~S² times slower).

    Returns
    -------
    PlateImage
        The (H, W) float64 image in e⁻ and the truth of every dot.

    Raises
    ------
    ValueError
        For a plane index out of range, a bad option, a plate whose dots do not lie
        inside their own grid cells, or a camera that sees no dot of the plate.
    """
    _check_inputs(plate, camera, plane, supersampling, edge_width, bow_iterations)
    _check_switches(defocus=defocus, antialias=antialias, adaptive=adaptive)
    full_brightness = positive_float("full_brightness", full_brightness)
    plane, s_count, start = int(plane), int(supersampling), time.perf_counter()
    dots = _dots(plate, float(edge_width))
    width, height = camera.lens.sensor_size
    acc, todo = _sample_light(
        camera, plate, plane, dots, s_count, bow_iterations, adaptive=adaptive,
        antialias=antialias and float(edge_width) == 0.0, point_antialias=antialias,
    )
    light = acc.light
    world = plate.dot_centres(plane)
    if not np.any(light > 0):
        raise ValueError(_sees_no_dot(camera, plate, plane, world))
    with np.errstate(invalid="ignore", divide="ignore"):
        centroid = np.column_stack([acc.moment_x / light, acc.moment_y / light])
    centroid[~(light > 0)] = np.nan
    image = (acc.value * full_brightness).reshape(height, width)
    sigma = np.zeros(len(light))
    if defocus:
        label = acc.label.reshape(height, width)
        image, sigma = _defocused(image, label, camera, world, light > 0)
    on_sensor = _on_sensor(camera, plate, plane, dots, sigma)
    projected = camera.project(world)
    logger.debug(
        "plate image plane %d: %d of %d px supersampled (%d×%d), %d dots lit, %.3f s",
        plane, todo.size, width * height, s_count, s_count, int(np.sum(light > 0)),
        time.perf_counter() - start,
    )
    return PlateImage(
        image=image,
        plane=plane,
        supersampling=s_count,
        full_brightness=full_brightness,
        indices=plate.design.indices.copy(),
        diameters=plate.design.diameters.copy(),
        marks=_mark_rows(plate),
        world=world,
        projected=projected,
        on_sensor=on_sensor,
        centroid=centroid,
        electrons=light * full_brightness,
        blur_sigma=sigma,
        supersampled_pixels=int(todo.size),
    )


def _sample_light(
    camera: Camera,
    plate: PhysicalPlate,
    plane: int,
    dots: _Dots,
    s_count: int,
    bow_iterations: int,
    *,
    adaptive: bool,
    antialias: bool,
    point_antialias: bool,
) -> tuple[_Light, np.ndarray]:
    """The light of every pixel and dot (``render_plate``'s options), and the pixels that
    were supersampled. ``antialias``: exact coverage of each sub-sample (hard edges);
    ``point_antialias``: the option as given, which sets the adaptive pass's margin."""
    h0, q = _bow_model(plate)
    pose = plate.poses[plane]

    def hits(xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
        return cast_to_plate(
            camera, xs, ys, rotation=pose.rotation, z=pose.z_actual, h0=h0, q=q,
            iterations=bow_iterations,
        )

    width, height = camera.lens.sensor_size
    acc = _Light.empty(len(dots.xy), width * height)
    if adaptive:
        factor = MARGIN_SAFETY * (1.0 if point_antialias else (s_count - 1) / s_count)
        todo = _centre_pass(hits, plate, dots, acc, width, height, factor)
    else:
        todo = np.arange(width * height)
    _subsample_pass(hits, plate, dots, acc, todo, width, s_count, antialias)
    return acc, todo


def _check_switches(**switches: object) -> None:
    """Refuse options that must be True or False but are not."""
    for name, flag in switches.items():
        if not isinstance(flag, bool):
            raise ValueError(f"{name} must be True or False; got {flag!r}")


def _defocused(
    image: np.ndarray, label: np.ndarray, camera: Camera, world: np.ndarray, lit: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The image with each dot blurred by σ = d_blur/4 at its centre, and those σ (px)."""
    blur = defocus_blur(camera, world) / 4.0
    missing = ~np.isfinite(blur) & lit
    if missing.any():
        logger.warning(
            "plate image: no defocus blur defined for %d visible dot(s); left sharp",
            int(missing.sum()),
        )
    sigma = np.where(np.isfinite(blur), blur, 0.0)
    return _blur_dots(image, label, sigma), sigma


def _sees_no_dot(camera: Camera, plate: PhysicalPlate, plane: int, world: np.ndarray) -> str:
    """Why a camera recorded no light of the plate at ``plane``."""
    return (
        f"the camera at {camera.center.tolist()} (m) looking along "
        f"{camera.axis.round(4).tolist()} sees no dot of the plate at plane {plane} "
        f"(Z = {plate.poses[plane].z_nominal!r} m, dots from "
        f"{world.min(axis=0).round(4).tolist()} to {world.max(axis=0).round(4).tolist()} m)"
    )


def _mark_rows(plate: PhysicalPlate) -> dict[str, int]:
    """Row of each mark in the plate's dot list."""
    return {
        name: int(np.flatnonzero(np.all(plate.design.indices == ij, axis=1))[0])
        for name, ij in plate.design.marks.items()
    }


def _blur_dots(image: np.ndarray, label: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """Blur each dot's light by its own Gaussian σ (px) in a padded region of interest."""
    height, width = image.shape
    out = np.zeros_like(image)
    for k, box in enumerate(ndimage.find_objects(label + 1)):
        if box is None:
            continue
        own = label[box] == k
        if sigma[k] < MIN_BLUR_SIGMA:
            out[box][own] += image[box][own]
            continue
        pad = int(np.ceil(4.0 * sigma[k])) + 1
        rows = slice(max(0, box[0].start - pad), min(height, box[0].stop + pad))
        cols = slice(max(0, box[1].start - pad), min(width, box[1].stop + pad))
        patch = np.where(label[rows, cols] == k, image[rows, cols], 0.0)
        out[rows, cols] += ndimage.gaussian_filter(patch, sigma[k], mode="constant", truncate=4.0)
    return out


def _on_sensor(
    camera: Camera, plate: PhysicalPlate, plane: int, dots: _Dots, sigma: np.ndarray
) -> np.ndarray:
    """(D,) bool: every rim point's image at least 0.1 px + 3σ inside the sensor area."""
    angle = np.linspace(0.0, 2.0 * np.pi, RIM_POINTS, endpoint=False)
    ring = np.column_stack([np.cos(angle), np.sin(angle)])
    rim = (dots.xy[:, None, :] + dots.radius[:, None, None] * ring[None]).reshape(-1, 2)
    xy = camera.project(plate.plate_to_world(plane, rim)).reshape(len(dots.xy), RIM_POINTS, 2)
    width, height = camera.lens.sensor_size
    margin = (ON_SENSOR_MARGIN + 3.0 * sigma)[:, None]
    with np.errstate(invalid="ignore"):
        inside = (
            (xy[..., 0] >= -0.5 + margin)
            & (xy[..., 0] <= width - 0.5 - margin)
            & (xy[..., 1] >= -0.5 + margin)
            & (xy[..., 1] <= height - 0.5 - margin)
        )
    return inside.all(axis=1)
