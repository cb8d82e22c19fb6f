"""Water tanks as trimesh meshes: the paper's icosahedron and a rectangular box.

A tank mesh is the wet (inner) surface of the vessel; a wall's dry face lies a glass
thickness further out. A camera looks through the wall its line of sight to the target
crosses (:func:`sight_face`), a flat air | glass | water window (:func:`wall_window`).

The vessel is a regular icosahedron centred on the origin. Its inradius r (the
distance from the centre to every face, m) is the rig's ``tank.inradius``: the wet
faces of the windows lie at n̂·X = r. It is oriented so that two faces have outward
normals in the XZ plane at azimuths ±35.26° from +Z,

    n̂_± = (±sin α, 0, cos α),  α = arctan(1/√2) = 35.26°,

which are 70.53° apart (cos = 1/3, the angle between two face normals of an
icosahedron that share a vertex but no edge). The stereo cameras of the
``paper-stereo`` rig sit at those azimuths and look through those faces. The mesh is
also symmetric under X → −X and under inversion through the centre (so the two
window faces are equivalent and each has a parallel face opposite).

Construction: the standard icosahedron with vertices (0, ±1, ±φ), (±1, ±φ, 0),
(±φ, 0, ±1) has faces with normals (±1, ±1, ±1)/√3 among others; the pair
(±1, 1, 1)/√3 is rotated onto n̂_± (new X = old x, new Z = (0, 1, 1)/√2).
"""

import logging

import numpy as np
import trimesh

from simulator.optics.interfaces import N_AIR, N_PMMA, N_WATER, FlatInterfaces, flat_window
from simulator.optics.mesh_interfaces import MeshInterfaces, MeshSurface

logger = logging.getLogger(__name__)

#: Golden ratio φ.
PHI = (1.0 + np.sqrt(5.0)) / 2.0
#: Azimuth of the two stereo window faces from +Z, rad (35.26°).
WINDOW_AZIMUTH = float(np.arctan(1.0 / np.sqrt(2.0)))
#: Angle between two icosahedron face normals sharing only a vertex, rad (70.53°).
WINDOW_SEPARATION = 2.0 * WINDOW_AZIMUTH
#: Circumradius / inradius of a regular icosahedron.
CIRCUM_OVER_IN = float(np.sqrt(3.0) * np.sqrt(10.0 + 2.0 * np.sqrt(5.0)) / (3.0 + np.sqrt(5.0)))

# Rows: the new X, Y, Z axes written in the standard icosahedron's frame.
_ORIENT = np.array(
    [
        [1.0, 0.0, 0.0],
        [0.0, 1.0, -1.0] / np.sqrt(2.0),
        [0.0, 1.0, 1.0] / np.sqrt(2.0),
    ]
)


def _positive_length(name: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float | np.floating | np.integer):
        raise ValueError(f"{name} must be a length in m; got {value!r}")
    value = float(value)
    if not (np.isfinite(value) and value > 0):
        raise ValueError(f"{name} must be finite and > 0 m; got {value!r}")
    return value


def icosahedral_tank(inradius: float) -> trimesh.Trimesh:
    """The tank: a regular icosahedron of inradius ``inradius`` (see the module docstring).

    Parameters
    ----------
    inradius : float
        Distance from the centre (origin) to every face, m (> 0); a rig's
        ``tank.inradius``.

    Returns
    -------
    trimesh.Trimesh
        12 vertices, 20 faces wound counter-clockwise seen from outside (outward face
        normals), closed and watertight, in m.
    """
    inradius = _positive_length("inradius", inradius)
    base = []
    for a in (-1.0, 1.0):
        for b in (-PHI, PHI):
            base += [(0.0, a, b), (a, b, 0.0), (b, 0.0, a)]
    vertices = np.array(base) @ _ORIENT.T
    hull = trimesh.convex.convex_hull(vertices)
    faces = np.asarray(hull.faces)
    verts = np.asarray(hull.vertices)
    # Scale so that the distance from the origin to every face plane is the inradius.
    normals = np.asarray(hull.face_normals)
    current = float(np.mean(np.einsum("ij,ij->i", normals, verts[faces[:, 0]])))
    mesh = trimesh.Trimesh(verts * (inradius / current), faces, process=False)
    if len(mesh.faces) != 20 or not mesh.is_watertight:  # pragma: no cover (construction)
        raise RuntimeError("icosahedron construction failed")
    return mesh


def box_tank(size: object, yaw: float = 0.0) -> trimesh.Trimesh:
    """A rectangular tank of inner size (L_X, L_Y, L_Z), m, centred on the origin.

    Parameters
    ----------
    size : sequence of 3 float
        Inner lengths along the box's own axes, m.
    yaw : float
        Turn of the box about the world Y axis, rad, from +Z toward +X (a camera's
        azimuth turns the same way): yaw = 45° presents a corner of the box to +Z.

    Returns
    -------
    trimesh.Trimesh
        8 vertices, 12 faces (two per wall) with outward normals, watertight, in m.
    """
    values = list(size) if isinstance(size, list | tuple | np.ndarray) else []
    if len(values) != 3:
        raise ValueError(f"box size must be 3 lengths (L_X, L_Y, L_Z) in m; got {size!r}")
    extents = [_positive_length(f"box size[{i}]", v) for i, v in enumerate(values)]
    if not np.isfinite(yaw):
        raise ValueError(f"box yaw must be finite (rad); got {yaw!r}")
    return trimesh.creation.box(
        extents=extents, transform=trimesh.transformations.rotation_matrix(yaw, [0.0, 1.0, 0.0])
    )


def _planes(tank: trimesh.Trimesh) -> tuple[np.ndarray, np.ndarray]:
    """Outward unit normals (F, 3) and offsets d (F,), m, of the face planes n̂·X = d."""
    normals = np.asarray(tank.face_normals, dtype=np.float64)
    corners = np.asarray(tank.vertices, dtype=np.float64)[np.asarray(tank.faces)[:, 0]]
    return normals, np.einsum("ij,ij->i", normals, corners)


def sight_face(tank: trimesh.Trimesh, center: object, target: object) -> int:
    """The face through which the straight line from a camera to a target enters a
    convex tank.

    Parameters
    ----------
    tank : trimesh.Trimesh
        A convex vessel.
    center : array_like, shape (3,)
        Camera centre, m, outside the tank.
    target : array_like, shape (3,)
        A point inside the tank, m.

    Returns
    -------
    int
        Face index into ``tank.faces``.

    Raises
    ------
    ValueError
        The target outside or the camera inside the tank.
    """
    c, t = (np.asarray(v, dtype=np.float64) for v in (center, target))
    normals, offsets = _planes(tank)
    if not (normals @ t < offsets).all():
        raise ValueError(f"the point {t.tolist()} m is not inside the tank")
    outside = normals @ c - offsets
    if not (outside > 0).any():
        raise ValueError(f"the camera at {c.tolist()} m is inside the tank")
    # The line X(s) = c + s (t − c) leaves the half-space of face i at s_i; it enters the
    # tank where it has left the last of the half-spaces the camera lies outside.
    leaves = outside > 0
    s = np.full(outside.shape, -np.inf)
    s[leaves] = outside[leaves] / (outside[leaves] - (normals[leaves] @ t - offsets[leaves]))
    return int(np.argmax(s))


def face_plane(tank: trimesh.Trimesh, face: int) -> tuple[np.ndarray, float]:
    """The plane of a tank face.

    Parameters
    ----------
    tank : trimesh.Trimesh
        A convex vessel.
    face : int
        Face index, e.g. from :func:`sight_face`.

    Returns
    -------
    normal : ndarray, shape (3,)
        Unit outward normal n̂ of the face.
    offset : float
        d in n̂·X = d, m (the inradius for an icosahedron centred on the origin).
    """
    normals, offsets = _planes(tank)
    return normals[face], float(offsets[face])


def wall_window(
    tank: trimesh.Trimesh,
    face: int,
    thickness: float,
    *,
    n_air: float = N_AIR,
    n_glass: float = N_PMMA,
    n_water: float = N_WATER,
) -> FlatInterfaces:
    """The flat air | glass | water window of a tank face.

    The tank mesh is the wet (inner) surface; the dry face of the wall lies
    ``thickness`` further out.

    Parameters
    ----------
    tank : trimesh.Trimesh
        A convex vessel.
    face : int
        Face index (:func:`sight_face`).
    thickness : float
        Wall (glass) thickness, m (≥ 0).
    n_air, n_glass, n_water : float
        Refractive indices.

    Returns
    -------
    FlatInterfaces
        Normal −n̂ (toward the water), planes at −(d + thickness) and −d.
    """
    normal, offset = face_plane(tank, face)
    return flat_window(
        -normal, -(offset + thickness), thickness, n_air=n_air, n_glass=n_glass, n_water=n_water
    )


def tank_surfaces(
    inner: trimesh.Trimesh,
    outer: trimesh.Trimesh,
    *,
    n_air: float = N_AIR,
    n_glass: float = N_PMMA,
    n_water: float = N_WATER,
) -> MeshInterfaces:
    """A tank wall as two refracting meshes: outer (air → glass) and inner (glass → water).

    Parameters
    ----------
    inner, outer : trimesh.Trimesh
        The wet surface and the dry surface a wall thickness further out (e.g.
        ``icosahedral_tank(r)`` and ``icosahedral_tank(r + t)``, or ``box_tank(L)`` and
        ``box_tank(L + 2t)``).
    n_air, n_glass, n_water : float
        Refractive indices.

    Returns
    -------
    MeshInterfaces
        For :class:`simulator.optics.mesh_interfaces.MeshCamera` or
        :func:`simulator.optics.mesh_interfaces.trace_meshes`.
    """
    return MeshInterfaces(
        (MeshSurface(outer, n_air, n_glass), MeshSurface(inner, n_glass, n_water))
    )
