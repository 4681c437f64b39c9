"""What a geometry is: the vertices and faces of a mesh or point cloud, triangle areas, closedness,
and the checks of functions that need faces or a closed surface.

Plain NumPy on concrete inputs: a :class:`trimesh.Trimesh`, a :class:`trimesh.PointCloud` (or
anything with ``vertices`` and optional ``faces``) or an ``(n, 3)`` array of points.
"""
from __future__ import annotations

import os
import warnings
from typing import NamedTuple

import numpy as np

from ._validate import InvalidInputError, OpenMeshWarning, check_concrete, check_faces, check_points

__all__ = ["Surface", "split_geometry", "is_pair", "triangle_areas", "surface_labels", "is_closed", "require_faces", "warn_if_open"]


# the extents (largest coordinate range) whose face areas float64 holds: the cross product of two edges
# is at most 2 extent^2 per component, and areas square it (triangle_areas); outside, a mesh is refused
MAX_EXTENT = float(np.finfo(np.float64).max / 12.0) ** 0.25  # 6.2e76
MIN_EXTENT = float(np.finfo(np.float64).tiny) ** 0.25  # 1.2e-77: below, every area is 0 or subnormal


class Surface(NamedTuple):
    """A triangle mesh as two arrays, without a trimesh object: what a file read by the fast
    readers becomes where nothing else of trimesh is needed (:func:`jaxpose.io.mesh.read`), and
    what the functions of a mesh accept and give back in its place.

    Attributes:
      vertices: (n, 3) float64.
      faces: (m, 3) int64, every index in [0, n).

    Example::

        surface = Surface(np.eye(3), np.array([[0, 1, 2]]))
        vertices, faces = split_geometry(surface)
    """

    vertices: np.ndarray
    faces: np.ndarray


def is_pair(value) -> bool:
    """Whether ``value`` is a bare tuple or list of two 2-d arrays (vertices and faces), not points
    nor a :class:`Surface` (a named tuple): such a pair is refused where a geometry is read, with
    :class:`Surface` as the fix."""
    if hasattr(value, "vertices"):
        return False
    try:
        return isinstance(value, (tuple, list)) and len(value) == 2 and all(np.ndim(a) == 2 for a in value)
    except ValueError:  # a ragged element: NumPy refuses its ndim
        return False


def split_geometry(mesh_or_points):
    """Split the input into vertices and faces.

    Returns
    -------
    vertices : (n, 3) float64
    faces : (f, 3) int or None   (None for point clouds and meshes without faces)

    Raises InvalidInputError for a path (str, bytes or os.PathLike: the message says how to load
    it), a (vertices, faces) pair (the message names :class:`Surface`), bad vertices or faces, for faces of zero total area ("the mesh has no area": such a mesh
    is not silently taken as its points), and for traced
    vertices or faces (under jit, vmap or grad: every function that reads a geometry here is NumPy).

    Example::

        vertices, faces = split_geometry(trimesh.creation.box())   # (8, 3), (12, 3)
        vertices, faces = split_geometry(points)                   # (n, 3), None
    """
    if isinstance(mesh_or_points, (str, bytes, os.PathLike)):  # ("vertices must have shape (m, 3), got ()")
        raise InvalidInputError(
            f"expected a loaded geometry (a Trimesh, PointCloud, jaxpose.geometry.Surface or (n, 3) points), got the "
            f"path {os.fsdecode(mesh_or_points)!r}: load it first with jaxpose.mesh.load(path) (jaxpose.sample_surface "
            "and jaxpose.normalize_mesh read a path themselves)")
    check_concrete("the geometry (mesh or points)", getattr(mesh_or_points, "vertices", mesh_or_points),
                   getattr(mesh_or_points, "faces", None))
    if is_pair(mesh_or_points):  # (NumPy's "inhomogeneous shape" ValueError)
        raise InvalidInputError("a (vertices, faces) pair: pass jaxpose.geometry.Surface(vertices, faces) for a mesh "
                                "(an array of points is a point cloud)")
    faces = None
    if hasattr(mesh_or_points, "vertices"):  # Trimesh, PointCloud
        vertices = np.asarray(mesh_or_points.vertices, dtype=np.float64)
        f = getattr(mesh_or_points, "faces", None)
        if f is not None and len(f) > 0:
            faces = np.asarray(f)  # (its kind checked below: a fraction was truncated into another face)
    else:
        vertices = np.asarray(mesh_or_points)
    check_points(vertices, name="vertices", min_points=1)
    vertices = np.asarray(vertices, dtype=np.float64)
    if faces is not None:
        faces = check_faces(faces, len(vertices))
        with np.errstate(over="ignore"):  # the flat range bounds every axis's extent, at a tenth of their cost
            wide = float(vertices.max() - vertices.min()) > MAX_EXTENT
        if wide and _extent(vertices) > MAX_EXTENT:  # the areas' squared cross products would overflow: NaN areas
            raise InvalidInputError(
                f"the mesh spans {_extent(vertices):.3g}: beyond {MAX_EXTENT:.3g} its face areas overflow float64; "
                "rescale it")
        if not _has_area(vertices, faces):  # no silent switch to the points
            extent = _extent(vertices)
            if 0.0 < extent < MIN_EXTENT:  # not degenerate faces: areas that underflow to 0
                raise InvalidInputError(
                    f"the mesh spans {extent:.3g}: below {MIN_EXTENT:.3g} its face areas underflow float64 "
                    "(to 0); rescale it")
            raise InvalidInputError(
                f"the mesh has no area: all its {len(faces)} faces are degenerate (zero area); to use its "
                "vertices as points, pass trimesh.PointCloud(mesh.vertices)"
            )
    return vertices, faces


def _extent(vertices):
    """The largest of the vertices' coordinate ranges, per axis."""
    with np.errstate(over="ignore"):
        return max(float(np.ptp(vertices[:, axis])) for axis in range(vertices.shape[1]))


def _has_area(vertices, faces, block=4096):
    """Whether the total area of the faces is > 0, i.e. some face has an area > 0: blocks of faces
    in turn, so that a mesh with area (nearly every one) is answered from its first block."""
    return any(triangle_areas(vertices[faces[i:i + block]]).sum() > 0.0 for i in range(0, len(faces), block))


def triangle_areas(triangles):
    """Areas |(b - a) x (c - a)| / 2 of triangles (f, 3, 3) float, in squared units -> (f,) float.

    The cross product and its norm are written per component (the values of ``np.cross`` and
    ``np.linalg.norm``, without their temporaries).

    Raises:
      InvalidInputError: `triangles` not of shape (f, 3, 3) (one triangle (3, 3): ``triangles[None]``).
    """
    check_concrete("triangles", triangles)
    if not hasattr(triangles, "shape"):  # (a list: its indexing below is NumPy's)
        triangles = np.asarray(triangles, dtype=np.float64)
    if len(triangles.shape) != 3 or tuple(triangles.shape[1:]) != (3, 3):  # (a (3, 3) array: an IndexError)
        raise InvalidInputError(f"triangles must have shape (f, 3, 3), f triangles of 3 corners, got "
                                f"{tuple(triangles.shape)}" + (" (one triangle: pass triangles[None])"
                                                               if tuple(triangles.shape) == (3, 3) else ""))
    u = triangles[:, 1] - triangles[:, 0]
    v = triangles[:, 2] - triangles[:, 0]
    x = u[:, 1] * v[:, 2] - u[:, 2] * v[:, 1]
    y = u[:, 2] * v[:, 0] - u[:, 0] * v[:, 2]
    z = u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]
    return 0.5 * np.sqrt(x * x + y * y + z * z)


def surface_labels(count, faces):
    """The face-connected surfaces of a mesh: vertices joined by the edges of its faces.

    count: the number of vertices n; faces: (f, 3) int indices of them.
    Returns (k, labels): the number of surfaces and (n,) int64, each vertex's surface in
    0 ... k - 1 (a vertex in no face is a surface of its own).

    Example::

        k, labels = surface_labels(len(mesh.vertices), mesh.faces)  # a box and a stray sphere: k = 2
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    f = np.asarray(faces, np.int64).reshape(-1, 3)
    edges = np.concatenate([f[:, [0, 1]], f[:, [1, 2]]])
    graph = coo_matrix((np.ones(len(edges), bool), (edges[:, 0], edges[:, 1])), shape=(count, count))
    k, labels = connected_components(graph, directed=False)
    return int(k), labels.astype(np.int64)


def is_closed(faces):
    """Whether every edge of the faces (f, 3) is shared by exactly two faces (no boundary, no
    non-manifold edge): the surface bounds a volume. ``is_closed(trimesh.creation.box().faces)`` is True."""
    faces = np.asarray(faces, dtype=np.int64)
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    n = int(faces.max()) + 1
    key = np.sort(np.minimum(e[:, 0], e[:, 1]) * n + np.maximum(e[:, 0], e[:, 1]))
    _, counts = np.unique(key, return_counts=True)
    return bool(np.all(counts == 2))


def require_faces(mesh_or_points, what):
    """``(vertices, faces)`` of a mesh; raises InvalidInputError naming `what` on points only."""
    vertices, faces = split_geometry(mesh_or_points)
    if faces is None:
        raise InvalidInputError(f"{what} needs a mesh with faces (a surface); got points only")
    return vertices, faces


def warn_if_open(faces, what, strict):
    """Nothing on a closed surface; else an :class:`OpenMeshWarning` naming `what`, reported at the
    line that called the function calling this one, or with `strict` an InvalidInputError."""
    if is_closed(faces):
        return
    message = (f"{what}: the mesh is not closed (it has boundary or non-manifold edges); the closed-form "
               "solid of an open surface is not its volume")
    if strict:
        raise InvalidInputError(message + " (strict=True)")
    warnings.warn(message, OpenMeshWarning, stacklevel=3)
