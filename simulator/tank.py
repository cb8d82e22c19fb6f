"""The paper's icosahedral water tank as a trimesh mesh.

The vessel is a regular icosahedron centred on the origin. Its inradius r (the
distance from the centre to every face, m) is the rig's ``tank_inradius``: the wet
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
        ``tank_inradius``.

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


def nearest_face(tank: trimesh.Trimesh, direction: object) -> int:
    """Index of the tank face whose outward normal is closest to ``direction``.

    Parameters
    ----------
    tank : trimesh.Trimesh
        A convex vessel (e.g. from :func:`icosahedral_tank`).
    direction : array_like, shape (3,)
        A direction from the tank centre outward, e.g. toward a camera (any length > 0).

    Returns
    -------
    int
        Face index into ``tank.faces``.
    """
    d = np.asarray(direction, dtype=np.float64)
    norm = np.linalg.norm(d) if d.shape == (3,) else 0.0
    if d.shape != (3,) or not np.isfinite(d).all() or norm == 0:
        raise ValueError(f"direction must be a finite, non-zero 3-vector; got {direction!r}")
    return int(np.argmax(np.asarray(tank.face_normals) @ (d / norm)))


def face_plane(tank: trimesh.Trimesh, direction: object) -> tuple[np.ndarray, float]:
    """The plane of the tank face nearest a viewing direction.

    Parameters
    ----------
    tank : trimesh.Trimesh
        A convex vessel.
    direction : array_like, shape (3,)
        Direction from the tank centre outward (toward the camera), any length > 0.

    Returns
    -------
    normal : ndarray, shape (3,)
        Unit outward normal n̂ of the face.
    offset : float
        d in n̂·X = d, m (the inradius for a tank centred on the origin).
    """
    index = nearest_face(tank, direction)
    normal = np.array(tank.face_normals[index], dtype=np.float64)
    offset = float(normal @ np.asarray(tank.vertices[tank.faces[index, 0]]))
    return normal, offset


def camera_face(tank: trimesh.Trimesh, center: object) -> int:
    """Index of the face a camera at ``center`` (m) most directly looks through."""
    c = np.asarray(center, dtype=np.float64)
    if c.shape != (3,) or not np.isfinite(c).all():
        raise ValueError(f"center must be a finite 3-vector in m; got {center!r}")
    return nearest_face(tank, c - np.asarray(tank.centroid))


def face_window(
    tank: trimesh.Trimesh,
    direction: object,
    thickness: float,
    *,
    n_air: float = N_AIR,
    n_glass: float = N_PMMA,
    n_water: float = N_WATER,
) -> FlatInterfaces:
    """The flat air | glass | water window of the face nearest ``direction``.

    The tank mesh is the wet (inner) surface; the dry face of the wall lies
    ``thickness`` further out.

    Parameters
    ----------
    tank : trimesh.Trimesh
        A convex vessel.
    direction : array_like, shape (3,)
        Direction from the tank centre toward the camera.
    thickness : float
        Wall (glass) thickness, m (≥ 0).
    n_air, n_glass, n_water : float
        Refractive indices.

    Returns
    -------
    FlatInterfaces
        Normal −n̂ (toward the water), planes at −(d + thickness) and −d.
    """
    normal, offset = face_plane(tank, direction)
    return flat_window(
        -normal, -(offset + thickness), thickness, n_air=n_air, n_glass=n_glass, n_water=n_water
    )


def tank_surfaces(
    inradius: float,
    thickness: float,
    *,
    n_air: float = N_AIR,
    n_glass: float = N_PMMA,
    n_water: float = N_WATER,
) -> MeshInterfaces:
    """The tank wall as two refracting meshes: outer (air → glass) and inner (glass → water).

    Parameters
    ----------
    inradius : float
        Inradius of the wet (inner) surface, m.
    thickness : float
        Wall thickness, m (> 0): the outer icosahedron has inradius
        ``inradius + thickness``.
    n_air, n_glass, n_water : float
        Refractive indices.

    Returns
    -------
    MeshInterfaces
        For :class:`simulator.optics.mesh_interfaces.MeshCamera` or
        :func:`simulator.optics.mesh_interfaces.trace_meshes`.
    """
    inradius = _positive_length("inradius", inradius)
    thickness = _positive_length("thickness", thickness)
    return MeshInterfaces(
        (
            MeshSurface(icosahedral_tank(inradius + thickness), n_air, n_glass),
            MeshSurface(icosahedral_tank(inradius), n_glass, n_water),
        )
    )
