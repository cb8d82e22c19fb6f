"""Refraction through general (non-planar) interfaces given as triangle meshes.

An interface stack is an ordered sequence of surfaces (mesh, n_before, n_after): a ray
leaving the camera in a medium of index n_before of the first surface meets the
surfaces in that order. At each surface the ray is cast against the mesh (trimesh's
ray intersector, which uses Embree through ``embreex`` when installed), the first hit
further than ``min_distance`` along the ray is taken, and the ray is refracted there
by the vector form of Snell's law (:func:`simulator.optics.interfaces.refract`) about
the hit triangle's normal (flat facets: the normal is constant over a triangle).

Precision: Embree works in single precision, so it is used only to find *which*
triangle a ray hits. The hit point is then recomputed in double precision as the
intersection of the ray with that triangle's plane, and the normal is the double-
precision unit normal of that triangle. A flat window built from planar meshes
therefore gives the rays of the exact planar formulas (``FlatInterfaces``) to
rounding error. Rays that Embree reports as missing (possible within ~1e-7 of a
triangle edge) are re-cast with trimesh's double-precision intersector.

A surface may be the same mesh as the one before it (e.g. a closed glass slab entered
and left through one mesh): the triangle just hit is then excluded from the next cast.
"""

import logging
from dataclasses import dataclass, field

import numpy as np
import trimesh

from simulator.optics.camera import BLOCK, Camera
from simulator.optics.interfaces import FlatInterfaces, refract
from simulator.optics.rays import Rays, as_points

logger = logging.getLogger(__name__)

#: Default smallest distance (m) along a ray for a hit to count: rejects the
#: surface the ray is leaving, far below any glass thickness.
MIN_HIT_DISTANCE = 1e-6
#: Barycentric slack of the double-precision fallback intersector.
EDGE_SLACK = 1e-9
#: Newton tolerance of :meth:`MeshCamera.project`, px.
PROJECT_TOLERANCE = 1e-9
#: Iteration cap of :meth:`MeshCamera.project`.
PROJECT_MAX_ITERATIONS = 40
#: Finite-difference step of the Jacobian in :meth:`MeshCamera.project`, px.
PROJECT_STEP = 1e-4


def _index(name: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float | np.floating | np.integer):
        raise ValueError(f"{name} must be a refractive index (a number); got {value!r}")
    value = float(value)
    if not (np.isfinite(value) and value > 0):
        raise ValueError(f"{name} must be a finite refractive index > 0; got {value!r}")
    return value


@dataclass(frozen=True, eq=False)
class MeshSurface:
    """One refracting surface: a triangle mesh between two media.

    Attributes
    ----------
    mesh : trimesh.Trimesh
        The surface, m (open or closed; any winding: normals are oriented per ray).
    n_before : float
        Refractive index on the side the rays come from (the camera's side).
    n_after : float
        Refractive index after crossing the surface.
    """

    mesh: trimesh.Trimesh
    n_before: float
    n_after: float
    _normals: np.ndarray = field(init=False, repr=False)
    _anchors: np.ndarray = field(init=False, repr=False)
    _edges: np.ndarray = field(init=False, repr=False)
    _fast: object = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if not isinstance(self.mesh, trimesh.Trimesh):
            raise ValueError(
                f"MeshSurface.mesh must be a trimesh.Trimesh; got {type(self.mesh).__name__}"
            )
        if len(self.mesh.faces) == 0:
            raise ValueError("MeshSurface.mesh has no faces")
        vertices = np.asarray(self.mesh.vertices, dtype=np.float64)
        if not np.isfinite(vertices).all():
            raise ValueError("MeshSurface.mesh has non-finite vertices")
        object.__setattr__(self, "n_before", _index("MeshSurface.n_before", self.n_before))
        object.__setattr__(self, "n_after", _index("MeshSurface.n_after", self.n_after))
        tri = vertices[np.asarray(self.mesh.faces)]
        normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        norms = np.linalg.norm(normals, axis=1)
        with np.errstate(invalid="ignore", divide="ignore"):
            normals = normals / norms[:, None]  # NaN for degenerate triangles
        normals.setflags(write=False)
        anchors = np.ascontiguousarray(tri[:, 0])
        anchors.setflags(write=False)
        object.__setattr__(self, "_normals", normals)
        object.__setattr__(self, "_anchors", anchors)
        edges = np.ascontiguousarray(np.stack([tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]]))
        edges.setflags(write=False)
        object.__setattr__(self, "_edges", edges)
        object.__setattr__(self, "_fast", self.mesh.ray)  # Embree when available

    @property
    def face_normals(self) -> np.ndarray:
        """Double-precision unit normals (F, 3) of the triangles (mesh winding)."""
        return self._normals

    def first_hits(
        self,
        origins: np.ndarray,
        directions: np.ndarray,
        *,
        exclude: np.ndarray | None = None,
        min_distance: float = MIN_HIT_DISTANCE,
    ) -> tuple[np.ndarray, np.ndarray]:
        """The first triangle each ray meets beyond ``min_distance``.

        Parameters
        ----------
        origins : ndarray, shape (N, 3)
            Ray origins, m (finite).
        directions : ndarray, shape (N, 3)
            Unit directions (finite).
        exclude : ndarray of int, shape (N,), optional
            A triangle index per ray to ignore (the one the ray is leaving), −1 for none.
        min_distance : float
            Smallest accepted distance along the ray, m.

        Returns
        -------
        faces : ndarray of int, shape (N,)
            Hit triangle, −1 where the ray misses.
        distances : ndarray, shape (N,)
            Double-precision distance to that triangle's plane, m; NaN on a miss.
        """
        n = len(origins)
        faces = np.full(n, -1, dtype=np.int64)
        distances = np.full(n, np.nan)
        if n == 0:
            return faces, distances
        if exclude is None:
            exclude = np.full(n, -1, dtype=np.int64)
        tri, ray = self._fast.intersects_id(origins, directions, multiple_hits=True)
        self._pick(origins, directions, tri, ray, exclude, min_distance, faces, distances)
        retry = np.flatnonzero(faces < 0)
        if retry.size:
            tri, ray = self._exact_candidates(origins[retry], directions[retry])
            sub_faces = np.full(retry.size, -1, dtype=np.int64)
            sub_dist = np.full(retry.size, np.nan)
            self._pick(
                origins[retry],
                directions[retry],
                tri,
                ray,
                exclude[retry],
                min_distance,
                sub_faces,
                sub_dist,
            )
            faces[retry], distances[retry] = sub_faces, sub_dist
        return faces, distances

    def _exact_candidates(
        self, origins: np.ndarray, directions: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Every (triangle, ray) crossing, by a brute-force double-precision test.

        Möller–Trumbore with a barycentric slack of ``EDGE_SLACK`` (rays through an
        edge count for both triangles). Cost O(N·F): used only for the few rays the
        single-precision intersector lost.
        """
        e1, e2 = self._edges
        anchors = self._anchors
        tris, rays = [], []
        chunk = max(1, 2_000_000 // max(1, len(anchors)))
        for lo in range(0, len(origins), chunk):
            o = origins[lo : lo + chunk, None, :]
            d = directions[lo : lo + chunk, None, :]
            p = np.cross(d, e2[None])
            det = np.einsum("nfk,fk->nf", p, e1)
            with np.errstate(invalid="ignore", divide="ignore"):
                inv = 1.0 / det
                s = o - anchors[None]
                u = np.einsum("nfk,nfk->nf", s, p) * inv
                q = np.cross(s, e1[None])
                v = np.einsum("nfk,nk->nf", q, d[:, 0]) * inv
                inside = (u >= -EDGE_SLACK) & (v >= -EDGE_SLACK) & (u + v <= 1.0 + EDGE_SLACK)
            ray, tri = np.nonzero(inside & np.isfinite(inv))
            tris.append(tri)
            rays.append(ray + lo)
        return np.concatenate(tris), np.concatenate(rays)

    def _pick(self, origins, directions, tri, ray, exclude, min_distance, faces, distances):
        """Nearest valid candidate (tri, ray) per ray, with exact plane distances."""
        tri = np.asarray(tri, dtype=np.int64)
        ray = np.asarray(ray, dtype=np.int64)
        if tri.size == 0:
            return
        normals = self._normals[tri]
        with np.errstate(invalid="ignore", divide="ignore"):
            t = np.einsum("ij,ij->i", normals, self._anchors[tri] - origins[ray]) / np.einsum(
                "ij,ij->i", normals, directions[ray]
            )
        ok = np.isfinite(t) & (t > min_distance) & (tri != exclude[ray])
        tri, ray, t = tri[ok], ray[ok], t[ok]
        if tri.size == 0:
            return
        order = np.lexsort((t, ray))
        ray_sorted = ray[order]
        first = np.ones(order.size, dtype=bool)
        first[1:] = ray_sorted[1:] != ray_sorted[:-1]
        chosen = order[first]
        faces[ray[chosen]] = tri[chosen]
        distances[ray[chosen]] = t[chosen]


@dataclass(frozen=True, eq=False)
class MeshInterfaces:
    """An ordered stack of refracting mesh surfaces, camera side first.

    Attributes
    ----------
    surfaces : tuple of MeshSurface
        In the order a ray from the camera crosses them; the index after surface k
        must equal the index before surface k + 1.
    """

    surfaces: tuple[MeshSurface, ...]

    def __post_init__(self) -> None:
        surfaces = tuple(self.surfaces)
        if not surfaces:
            raise ValueError("MeshInterfaces needs at least one surface")
        for k, surface in enumerate(surfaces):
            if not isinstance(surface, MeshSurface):
                raise ValueError(
                    f"MeshInterfaces.surfaces[{k}] must be a MeshSurface; "
                    f"got {type(surface).__name__}"
                )
        for k in range(len(surfaces) - 1):
            if surfaces[k].n_after != surfaces[k + 1].n_before:
                raise ValueError(
                    f"MeshInterfaces: surface {k} leaves the ray in index "
                    f"{surfaces[k].n_after!r} but surface {k + 1} expects it in index "
                    f"{surfaces[k + 1].n_before!r}"
                )
        object.__setattr__(self, "surfaces", surfaces)

    def __len__(self) -> int:
        return len(self.surfaces)

    @property
    def indices(self) -> np.ndarray:
        """Refractive indices (S + 1,) of the media, camera side first."""
        return np.array([self.surfaces[0].n_before] + [s.n_after for s in self.surfaces])


@dataclass(frozen=True, eq=False)
class MeshRayPath:
    """Rays traced through a mesh stack, surface by surface.

    Attributes
    ----------
    points : ndarray, shape (S + 1, N, 3)
        The start point and the hit point on each of the S surfaces, m.
    directions : ndarray, shape (S + 1, N, 3)
        Unit direction in each medium 0 … S (after refraction at each surface).
    faces : ndarray of int, shape (S, N)
        Triangle hit on each surface, −1 where the ray did not get there.
    normals : ndarray, shape (S, N, 3)
        Unit normal of the hit triangle, oriented against the incoming ray (N·d < 0).
    missed : ndarray of bool, shape (N,)
        True where a ray missed a surface.
    tir : ndarray of bool, shape (N,)
        True where a ray was totally internally reflected.

    Entries after a miss or a total internal reflection are NaN (faces −1).
    """

    points: np.ndarray
    directions: np.ndarray
    faces: np.ndarray
    normals: np.ndarray
    missed: np.ndarray
    tir: np.ndarray


def _rays_in(origins: object, directions: object) -> tuple[np.ndarray, np.ndarray]:
    o = np.ascontiguousarray(origins, dtype=np.float64)
    d = np.ascontiguousarray(directions, dtype=np.float64)
    if o.ndim != 2 or o.shape[1] != 3:
        raise ValueError(f"ray origins must have shape (N, 3); got {o.shape}")
    if d.shape != o.shape:
        raise ValueError(
            f"ray directions must have the shape of the origins {o.shape}; got {d.shape}"
        )
    if np.isinf(o).any() or np.isinf(d).any():
        raise ValueError("ray origins and directions must be finite (NaN rows mark invalid rays)")
    return o, d


def trace_meshes(
    origins: object,
    directions: object,
    interfaces: MeshInterfaces,
    *,
    min_distance: float = MIN_HIT_DISTANCE,
) -> MeshRayPath:
    """Trace rays from the camera side through every surface of a mesh stack.

    Parameters
    ----------
    origins : array_like, shape (N, 3)
        Start points in the first medium, m; NaN rows are invalid rays.
    directions : array_like, shape (N, 3)
        Unit directions in the first medium; NaN rows are invalid rays.
    interfaces : MeshInterfaces
        The surfaces, in order.
    min_distance : float
        Smallest distance, m, from the previous point for a hit to count (> 0).

    Returns
    -------
    MeshRayPath
        Hit points, directions, faces and oriented normals at each surface.
    """
    if not isinstance(interfaces, MeshInterfaces):
        raise ValueError(f"interfaces must be MeshInterfaces; got {type(interfaces).__name__}")
    if not (np.isfinite(min_distance) and min_distance > 0):
        raise ValueError(f"min_distance must be finite and > 0 m; got {min_distance!r}")
    o, d = _rays_in(origins, directions)
    n_rays, n_surf = len(o), len(interfaces)
    points = np.full((n_surf + 1, n_rays, 3), np.nan)
    dirs = np.full((n_surf + 1, n_rays, 3), np.nan)
    faces = np.full((n_surf, n_rays), -1, dtype=np.int64)
    normals = np.full((n_surf, n_rays, 3), np.nan)
    active = np.isfinite(o).all(axis=1) & np.isfinite(d).all(axis=1)
    norms = np.linalg.norm(d[active], axis=1)
    if norms.size and np.max(np.abs(norms - 1.0)) > 1e-9:
        raise ValueError("ray directions must be unit vectors")
    points[0, active], dirs[0, active] = o[active], d[active]
    missed = np.zeros(n_rays, dtype=bool)
    tir_any = np.zeros(n_rays, dtype=bool)
    previous: MeshSurface | None = None
    for k, surface in enumerate(interfaces.surfaces):
        idx = np.flatnonzero(active)
        cur_o, cur_d = points[k, idx], dirs[k, idx]
        exclude = None
        if previous is not None and surface.mesh is previous.mesh:
            exclude = faces[k - 1, idx]
        hit, t = surface.first_hits(cur_o, cur_d, exclude=exclude, min_distance=min_distance)
        lost = hit < 0
        missed[idx[lost]] = True
        idx, hit, t, cur_o, cur_d = idx[~lost], hit[~lost], t[~lost], cur_o[~lost], cur_d[~lost]
        new_o = cur_o + t[:, None] * cur_d
        new_d = np.empty_like(cur_d)
        tir = np.zeros(idx.size, dtype=bool)
        order = np.argsort(hit, kind="stable")
        unique, starts = np.unique(hit[order], return_index=True)
        bounds = [*starts.tolist(), order.size]
        for j, face in enumerate(unique):
            members = order[bounds[j] : bounds[j + 1]]
            with np.errstate(invalid="ignore"):
                new_d[members], tir[members] = refract(
                    cur_d[members], surface.face_normals[face], surface.n_before, surface.n_after
                )
        n_hit = surface.face_normals[hit]
        sign = np.where(np.einsum("ij,ij->i", n_hit, cur_d) > 0, -1.0, 1.0)
        points[k + 1, idx] = new_o
        faces[k, idx] = hit
        normals[k, idx] = sign[:, None] * n_hit
        dirs[k + 1, idx] = np.where(tir[:, None], np.nan, new_d)
        tir_any[idx[tir]] = True
        active[:] = False
        active[idx[~tir]] = True
        previous = surface
    if missed.any() or tir_any.any():
        logger.debug(
            "mesh trace: %d of %d ray(s) missed a surface, %d totally internally reflected",
            missed.sum(),
            n_rays,
            tir_any.sum(),
        )
    return MeshRayPath(
        points=points, directions=dirs, faces=faces, normals=normals, missed=missed, tir=tir_any
    )


def back_project_meshes(
    origins: object,
    directions: object,
    interfaces: MeshInterfaces,
    *,
    min_distance: float = MIN_HIT_DISTANCE,
) -> Rays:
    """Rays in the camera's medium → the same rays after the last surface (water).

    Parameters
    ----------
    origins : array_like, shape (N, 3)
        Start points in the first medium, m.
    directions : array_like, shape (N, 3)
        Unit directions in the first medium.
    interfaces : MeshInterfaces
        The surfaces.
    min_distance : float
        See :func:`trace_meshes`.

    Returns
    -------
    Rays
        Origin on the last surface and unit direction beyond it; NaN for rays that
        miss a surface or are totally internally reflected.
    """
    path = trace_meshes(origins, directions, interfaces, min_distance=min_distance)
    return Rays(origins=path.points[-1], directions=path.directions[-1])


def _plane_basis(normal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    helper = np.eye(3)[int(np.argmin(np.abs(normal)))]
    u = np.cross(normal, helper)
    u /= np.linalg.norm(u)
    return u, np.cross(normal, u)


def plane_mesh(normal: object, offset: float, *, centre: object, size: float) -> trimesh.Trimesh:
    """A square of side ``size`` (m) on the plane n̂·X = offset, centred near ``centre``.

    Parameters
    ----------
    normal : array_like, shape (3,)
        Unit normal of the plane (it is also the winding normal of the two triangles).
    offset : float
        d in n̂·X = d, m.
    centre : array_like, shape (3,)
        The square is centred on the projection of this point onto the plane, m.
    size : float
        Side length, m (> 0).

    Returns
    -------
    trimesh.Trimesh
        4 vertices, 2 triangles.
    """
    n = np.asarray(normal, dtype=np.float64)
    c = np.asarray(centre, dtype=np.float64)
    if n.shape != (3,) or not np.isfinite(n).all() or abs(np.linalg.norm(n) - 1) > 1e-9:
        raise ValueError(f"normal must be a finite unit 3-vector; got {normal!r}")
    if c.shape != (3,) or not np.isfinite(c).all():
        raise ValueError(f"centre must be a finite 3-vector in m; got {centre!r}")
    if not (np.isfinite(size) and size > 0):
        raise ValueError(f"size must be finite and > 0 m; got {size!r}")
    if not np.isfinite(offset):
        raise ValueError(f"offset must be finite (m); got {offset!r}")
    u, v = _plane_basis(n)
    origin = c + (offset - n @ c) * n
    h = 0.5 * size
    corners = np.array(
        [origin + a * h * u + b * h * v for a, b in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
    )
    return trimesh.Trimesh(corners, [[0, 1, 2], [0, 2, 3]], process=False)


def flat_window_meshes(
    stack: FlatInterfaces, *, centre: object, size: float = 2.0
) -> MeshInterfaces:
    """A flat interface stack as planar square meshes (for tests and comparisons).

    Parameters
    ----------
    stack : FlatInterfaces
        Parallel planes; every layer between two planes must have a thickness > 0.
    centre : array_like, shape (3,)
        The squares are centred on the projections of this point, m (e.g. the
        camera's target).
    size : float
        Side of each square, m.

    Returns
    -------
    MeshInterfaces
        One square per plane, with the stack's refractive indices.
    """
    if not isinstance(stack, FlatInterfaces):
        raise ValueError(f"stack must be FlatInterfaces; got {type(stack).__name__}")
    if np.any(stack.thicknesses <= 0):
        raise ValueError(
            "flat_window_meshes: layers of zero thickness cannot be separate meshes; "
            f"got thicknesses {stack.thicknesses.tolist()} m"
        )
    return MeshInterfaces(
        tuple(
            MeshSurface(
                plane_mesh(stack.normal, d, centre=centre, size=size),
                stack.indices[k],
                stack.indices[k + 1],
            )
            for k, d in enumerate(stack.offsets)
        )
    )


@dataclass(frozen=True, eq=False)
class MeshCamera:
    """A camera looking through refracting mesh surfaces (the camera protocol).

    Attributes
    ----------
    camera : Camera
        The dry camera (pose, lens, tilted sensor) without flat interfaces.
    interfaces : MeshInterfaces
        The surfaces between the camera and the measurement volume.
    min_distance : float
        See :func:`trace_meshes`, m.
    """

    camera: Camera
    interfaces: MeshInterfaces
    min_distance: float = MIN_HIT_DISTANCE

    def __post_init__(self) -> None:
        if not isinstance(self.camera, Camera):
            raise ValueError(
                f"MeshCamera.camera must be a Camera; got {type(self.camera).__name__}"
            )
        if self.camera.interfaces is not None:
            raise ValueError(
                "MeshCamera.camera must have no flat interfaces (use MeshCamera.from_camera "
                "to strip them)"
            )
        if not isinstance(self.interfaces, MeshInterfaces):
            raise ValueError(
                "MeshCamera.interfaces must be MeshInterfaces; "
                f"got {type(self.interfaces).__name__}"
            )
        if not (np.isfinite(self.min_distance) and self.min_distance > 0):
            raise ValueError(
                f"MeshCamera.min_distance must be finite and > 0 m; got {self.min_distance!r}"
            )

    @classmethod
    def from_camera(
        cls, camera: Camera, interfaces: MeshInterfaces, *, min_distance: float = MIN_HIT_DISTANCE
    ) -> "MeshCamera":
        """The same pose and lens looking through ``interfaces`` instead of its flat window."""
        dry = Camera(camera.center, camera.rotation, camera.lens)
        return cls(dry, interfaces, min_distance)

    @property
    def center(self) -> np.ndarray:
        """Entrance-pupil centre (3,), m."""
        return self.camera.center

    @property
    def rotation(self) -> np.ndarray:
        """World → camera rotation (3, 3)."""
        return self.camera.rotation

    @property
    def lens(self):
        """The Lens."""
        return self.camera.lens

    def trace(self, xy: object) -> MeshRayPath:
        """The full path of the ray of each pixel (see :func:`trace_meshes`).

        Parameters
        ----------
        xy : array_like, shape (N, 2)
            Pixel coordinates, px (finite).
        """
        xy = as_points(xy, 2, "pixel coordinates xy")
        directions = self.camera.pixel_directions(xy)
        origins = np.broadcast_to(self.camera.center, directions.shape)
        return trace_meshes(origins, directions, self.interfaces, min_distance=self.min_distance)

    def pixel_to_ray(self, xy: object) -> Rays:
        """The ray imaged at each pixel, after the last surface.

        Parameters
        ----------
        xy : array_like, shape (N, 2)
            Pixel coordinates, px (finite; off-sensor positions allowed).

        Returns
        -------
        Rays
            Origin on the last surface and direction beyond it; NaN for pixels with no
            physical ray, rays that miss a surface or are totally internally reflected.
        """
        xy = as_points(xy, 2, "pixel coordinates xy")
        origins = np.empty((len(xy), 3))
        directions = np.empty((len(xy), 3))
        for lo in range(0, len(xy), BLOCK):
            path = self.trace(xy[lo : lo + BLOCK])
            origins[lo : lo + BLOCK] = path.points[-1]
            directions[lo : lo + BLOCK] = path.directions[-1]
        return Rays(origins=origins, directions=directions)

    def _residual(self, xy: np.ndarray, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Offset of each point from its pixel's ray, in the camera's x, y axes (m)."""
        rays = self.pixel_to_ray(xy)
        v = points - rays.origins
        along = np.einsum("ij,ij->i", v, rays.directions)
        perp = v - along[:, None] * rays.directions
        return perp @ self.rotation[:2].T, along

    def project(self, points: object) -> np.ndarray:
        """Pixel positions of world points (2-D Newton on :meth:`pixel_to_ray`).

        Parameters
        ----------
        points : array_like, shape (N, 3)
            World points beyond the last surface, m (finite).

        Returns
        -------
        ndarray, shape (N, 2)
            Pixel coordinates, px; NaN rows for points not imaged (no converged ray,
            behind the last surface, off the sensor).
        """
        return self.project_visible(points)[0]

    def project_visible(self, points: object) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`project` and the visibility mask (N,).

        The start is the straight-line (unrefracted) projection; the Jacobian of the
        ray offset with respect to the pixel is taken by forward differences.
        Convergence: a Newton step below ``PROJECT_TOLERANCE`` px.
        """
        points = as_points(points, 3, "points")
        n = len(points)
        # Start: the straight-line projection; the principal point where it has none.
        xy = np.array(self.camera.project(points), dtype=np.float64)
        bad = ~np.isfinite(xy).all(axis=1)
        xy[bad] = self.camera.lens.principal_point
        converged = np.zeros(n, dtype=bool)
        failed = np.zeros(n, dtype=bool)
        h = PROJECT_STEP
        for _ in range(PROJECT_MAX_ITERATIONS):
            idx = np.flatnonzero(~converged & ~failed)
            if idx.size == 0:
                break
            cur, pts = xy[idx], points[idx]
            shift = np.array([[0.0, 0.0], [h, 0.0], [0.0, h]])
            stacked = np.concatenate([cur + s for s in shift])
            res, _ = self._residual(stacked, np.concatenate([pts, pts, pts]))
            r0, rx, ry = np.split(res, 3)
            jac = np.stack([(rx - r0) / h, (ry - r0) / h], axis=2)  # (M, 2, 2)
            det = jac[:, 0, 0] * jac[:, 1, 1] - jac[:, 0, 1] * jac[:, 1, 0]
            with np.errstate(invalid="ignore", divide="ignore"):
                dx = (jac[:, 1, 1] * r0[:, 0] - jac[:, 0, 1] * r0[:, 1]) / det
                dy = (jac[:, 0, 0] * r0[:, 1] - jac[:, 1, 0] * r0[:, 0]) / det
            step = np.column_stack([dx, dy])
            ok = np.isfinite(step).all(axis=1)
            failed[idx[~ok]] = True
            # Damp wild steps (e.g. from a start far off): at most 200 px per iteration.
            size = np.linalg.norm(step, axis=1)
            scale = np.where(size > 200.0, 200.0 / np.where(size > 0, size, 1.0), 1.0)
            xy[idx[ok]] = cur[ok] - (scale[ok, None] * step[ok])
            converged[idx[ok & (size <= PROJECT_TOLERANCE)]] = True
        along = self._residual(xy, points)[1] if n else np.zeros(0)
        visible = converged & ~failed & (along > 0) & self.camera.lens.on_sensor(xy)
        xy[~visible] = np.nan
        n_lost = int((converged & ~visible).sum()) + int((~converged).sum())
        if n_lost:
            logger.debug("mesh projection: %d of %d point(s) not imaged", n_lost, n)
        return xy, visible
