"""pyrender helpers: OpenCV cameras as OpenGL cameras, and a sphere rasteriser.

pyrender draws offscreen through EGL (``PYOPENGL_PLATFORM=egl``, set here unless the
environment already chose a platform; it must be set before PyOpenGL is first
imported). It is a second, independent renderer for cameras *without refraction*:
it cannot refract, so it is not the accuracy path (docs/optics.md §7).

Conventions (see the derivation in :func:`intrinsics_camera`):

- camera axes: OpenCV x right, y down, z forward; OpenGL x right, y up, looking
  along −z. The OpenGL camera-to-world pose has columns (r₀, −r₁, −r₂, C) where rᵢ
  are the rows of the world→camera rotation R and C is the pupil centre.
- pixels: OpenGL window coordinates put pixel edges on integers (the centre of the
  first pixel at 0.5, measured from the left and, after pyrender flips the image,
  from the top); OpenCV puts pixel centres on integers. pyrender's
  ``IntrinsicsCamera`` maps x_window = f_x·X/Z + c_x, so an OpenCV principal point
  (c_x, c_y) becomes (c_x + ½, c_y + ½) in pyrender, and a k-times supersampled
  render uses k·f and k·(c + ½).
"""

import logging
import os
import warnings
from types import ModuleType

import numpy as np
import trimesh

logger = logging.getLogger(__name__)

#: OpenCV camera axes → OpenGL camera axes (flip y and z).
CV_TO_GL = np.diag([1.0, -1.0, -1.0])


def import_pyrender() -> ModuleType:
    """Import pyrender for offscreen EGL rendering.

    Sets ``PYOPENGL_PLATFORM=egl`` unless already set, and hides only the
    DeprecationWarnings that PyOpenGL, pyrender and their imports may raise while
    being imported.

    Returns
    -------
    module
        The ``pyrender`` module.
    """
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    with warnings.catch_warnings():
        for module in ("OpenGL", "pyrender", "pyglet", "imageio", "networkx", "PIL"):
            warnings.filterwarnings("ignore", category=DeprecationWarning, module=module)
        import pyrender
    return pyrender


def opengl_pose(center: object, rotation: object) -> np.ndarray:
    """OpenGL camera-to-world pose (4, 4) of an OpenCV camera.

    Parameters
    ----------
    center : array_like, shape (3,)
        Camera (pupil) centre C in the world, m.
    rotation : array_like, shape (3, 3)
        World → camera rotation R (OpenCV axes: X_c = R (X − C)).

    Returns
    -------
    ndarray, shape (4, 4)
        [[Rᵀ·diag(1, −1, −1), C], [0, 1]].
    """
    c = np.asarray(center, dtype=np.float64)
    r = np.asarray(rotation, dtype=np.float64)
    if c.shape != (3,) or r.shape != (3, 3):
        raise ValueError(f"need a (3,) centre and a (3, 3) rotation; got {c.shape}, {r.shape}")
    pose = np.eye(4)
    pose[:3, :3] = r.T @ CV_TO_GL
    pose[:3, 3] = c
    return pose


def intrinsics_camera(
    fx: float,
    fy: float,
    cx: float,
    cy: float,
    *,
    supersample: int = 1,
    znear: float = 0.01,
    zfar: float = 100.0,
) -> object:
    """A pyrender ``IntrinsicsCamera`` reproducing OpenCV intrinsics (no distortion).

    In OpenGL the window coordinate of a point at normalized position x = X/Z is
    x_w = f_x·x + c_x' (pyrender's projection matrix), and pixel i covers
    [i, i + 1) in x_w; in OpenCV pixel i is centred on u = i = f_x·x + c_x. Hence
    c_x' = c_x + ½. Rows: pyrender returns images top row first, with the same
    mapping for y (its sign flips cancel). Supersampled by k, the window coordinate
    is k·(u + ½): f' = k·f and c' = k·(c + ½).

    Parameters
    ----------
    fx, fy, cx, cy : float
        OpenCV focal lengths and principal point, px.
    supersample : int
        Render k pixels per sensor pixel along each axis (k ≥ 1).
    znear, zfar : float
        Clipping planes, m.

    Returns
    -------
    pyrender.IntrinsicsCamera
    """
    k = _supersample(supersample)
    pyrender = import_pyrender()
    return pyrender.IntrinsicsCamera(
        fx=k * fx, fy=k * fy, cx=k * (cx + 0.5), cy=k * (cy + 0.5), znear=znear, zfar=zfar
    )


def _supersample(value: object) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
        raise ValueError(f"supersample must be an integer >= 1; got {value!r}")
    return int(value)


def check_plain_pinhole(camera: object) -> None:
    """Raise ValueError unless ``camera`` is a pinhole pyrender can reproduce exactly.

    That is: no refractive interfaces, no lens distortion and an untilted sensor.
    """
    problems = []
    if getattr(camera, "interfaces", None) is not None:
        problems.append("it looks through refractive interfaces (a rasteriser cannot refract)")
    lens = camera.lens
    if any(lens.distortion):
        problems.append(f"its lens has distortion {lens.distortion}")
    if lens.tau_x or lens.tau_y:
        problems.append(f"its sensor is tilted (tau = {lens.tau_x!r}, {lens.tau_y!r} rad)")
    if problems:
        raise ValueError("pyrender cannot reproduce this camera: " + "; ".join(problems))


def render_spheres(
    camera: object,
    centres: object,
    radius: float,
    *,
    supersample: int = 8,
    subdivisions: int = 3,
) -> np.ndarray:
    """Image of white spheres on black seen by a plain pinhole camera, via pyrender.

    Flat (unlit) shading, so each pixel holds the fraction of its area covered by
    spheres: the scene is rendered at ``supersample`` × the sensor resolution (with
    pyrender's multisampling on top) and averaged over k × k blocks.

    Parameters
    ----------
    camera : Camera
        Pose and lens (no interfaces, distortion or tilt: see :func:`check_plain_pinhole`).
    centres : array_like, shape (N, 3)
        Sphere centres, m (world frame).
    radius : float
        Sphere radius, m (> 0).
    supersample : int
        k, sub-pixels per pixel along each axis.
    subdivisions : int
        Icosphere subdivisions of each sphere mesh (3: 642 vertices).

    Returns
    -------
    ndarray, shape (H, W), float64
        Covered fraction of each pixel, in [0, 1].
    """
    check_plain_pinhole(camera)
    centres = np.asarray(centres, dtype=np.float64)
    if centres.ndim != 2 or centres.shape[1] != 3 or not np.isfinite(centres).all():
        raise ValueError(f"centres must be a finite (N, 3) array in m; got shape {centres.shape}")
    if not (np.isfinite(radius) and radius > 0):
        raise ValueError(f"radius must be finite and > 0 m; got {radius!r}")
    k = _supersample(supersample)
    pyrender = import_pyrender()
    width, height = camera.lens.sensor_size
    scene = pyrender.Scene(bg_color=[0.0, 0.0, 0.0, 1.0], ambient_light=[0.0, 0.0, 0.0])
    if len(centres):
        sphere = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
        material = pyrender.MetallicRoughnessMaterial(baseColorFactor=[1.0, 1.0, 1.0, 1.0])
        poses = np.tile(np.eye(4), (len(centres), 1, 1))
        poses[:, :3, 3] = centres
        scene.add(pyrender.Mesh.from_trimesh(sphere, material=material, poses=poses, smooth=False))
    depth = np.linalg.norm(centres - camera.center, axis=1) if len(centres) else np.ones(1)
    cx, cy = camera.lens.principal_point
    gl_camera = intrinsics_camera(
        camera.lens.fx,
        camera.lens.fx,
        cx,
        cy,
        supersample=k,
        znear=max(1e-4, 0.5 * float(depth.min()) - radius),
        zfar=2.0 * float(depth.max()) + radius,
    )
    scene.add(gl_camera, pose=opengl_pose(camera.center, camera.rotation))
    renderer = pyrender.OffscreenRenderer(k * width, k * height)
    try:
        color, _ = renderer.render(scene, flags=pyrender.RenderFlags.FLAT)
    finally:
        renderer.delete()
    fine = color[:, :, 0].astype(np.float64) / 255.0
    return fine.reshape(height, k, width, k).mean(axis=(1, 3))
