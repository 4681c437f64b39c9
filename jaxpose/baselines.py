"""Classical centers and scales of 3D shapes, one interface.

Every function accepts a :class:`trimesh.Trimesh`, a :class:`trimesh.PointCloud`
or an ``(n, 3)`` array of points. Surface-based quantities (``surface_centroid``,
``mean_distance``) integrate over the triangles of a mesh and fall back to the
points of a point cloud (or of a mesh without faces).

These are the references the OCSVM normalization is compared against (paper,
section 2); they are plain NumPy and are not differentiated.

Centers : ``surface_centroid``, ``vertex_mean``, ``bbox_center``, ``min_ball``.
Scales  : ``mean_distance``, ``unit_cube``, ``unit_sphere``.
Dispatch: ``center(mesh, method)``, ``scale(mesh, method, center=None)``.
"""
from __future__ import annotations

import numpy as np

from ._validate import InvalidInputError, check_points

__all__ = [
    "CENTERS",
    "SCALES",
    "center",
    "scale",
    "surface_centroid",
    "vertex_mean",
    "bbox_center",
    "min_ball",
    "mean_distance",
    "unit_cube",
    "unit_sphere",
    "split_geometry",
    "triangle_areas",
]

CENTERS = ("surface_centroid", "vertex_mean", "bbox_center", "min_ball")
SCALES = ("mean_distance", "unit_cube", "unit_sphere")

# mean_distance splits each triangle into k*k congruent sub-triangles (k from
# _SUBDIVISIONS) whose centroids, weighted by area, form a deterministic quadrature.
_SUBDIVISIONS = np.array([1, 2, 4, 8, 16, 32, 64])
_RELATIVE_STEP = 0.03  # sub-triangle size / distance from the center
_CHUNK_NODES = 1 << 22  # quadrature nodes per block (bounds memory)


# --------------------------------------------------------------------------- coercion
def split_geometry(mesh_or_points):
    """Split the input into vertices and faces.

    Returns
    -------
    vertices : (n, 3) float64
    faces : (f, 3) int or None   (None for point clouds and meshes without faces)
    """
    faces = None
    if hasattr(mesh_or_points, "vertices"):  # Trimesh, PointCloud
        vertices = np.asarray(mesh_or_points.vertices, dtype=np.float64)
        f = getattr(mesh_or_points, "faces", None)
        if f is not None and len(f) > 0:
            faces = np.asarray(f, dtype=np.int64)
    else:
        vertices = np.asarray(mesh_or_points)
    check_points(vertices, name="vertices", min_points=1)
    vertices = np.asarray(vertices, dtype=np.float64)
    if faces is not None:
        if faces.ndim != 2 or faces.shape[1] != 3:
            raise InvalidInputError(f"faces must have shape (f, 3), got {faces.shape}")
        if faces.min() < 0 or faces.max() >= len(vertices):
            raise InvalidInputError("faces index vertices that do not exist")
        if triangle_areas(vertices[faces]).sum() <= 0.0:
            faces = None  # degenerate surface: use the points
    return vertices, faces


def triangle_areas(triangles):
    """triangles : (f, 3, 3) float -> areas : (f,) float"""
    cross = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    return 0.5 * np.linalg.norm(cross, axis=1)


def _coerce_center(mesh_or_points, center_point):
    if center_point is None:
        return surface_centroid(mesh_or_points)
    c = np.asarray(center_point, dtype=np.float64)
    if c.shape != (3,) or not np.all(np.isfinite(c)):
        raise InvalidInputError(f"center must be 3 finite numbers, got {center_point!r}")
    return c


# --------------------------------------------------------------------------- centers
def surface_centroid(mesh_or_points):
    """Area-weighted centroid of the surface: sum(area_f * centroid_f) / sum(area_f).

    Point clouds: the mean of the points.

    Returns
    -------
    center : (3,) float64
    """
    vertices, faces = split_geometry(mesh_or_points)
    if faces is None:
        return vertices.mean(axis=0)
    triangles = vertices[faces]
    areas = triangle_areas(triangles)
    return (areas[:, None] * triangles.mean(axis=1)).sum(axis=0) / areas.sum()


def vertex_mean(mesh_or_points):
    """Mean of the vertices (or points).  Returns center : (3,) float64."""
    vertices, _ = split_geometry(mesh_or_points)
    return vertices.mean(axis=0)


def bbox_center(mesh_or_points):
    """Center of the axis-aligned bounding box.  Returns center : (3,) float64."""
    vertices, _ = split_geometry(mesh_or_points)
    return 0.5 * (vertices.min(axis=0) + vertices.max(axis=0))


def min_ball(mesh_or_points):
    """Exact minimum enclosing ball of the vertices (or points).

    Welzl's randomized algorithm (fixed seed, so deterministic) on the convex-hull
    vertices, with vectorized "first point outside" scans; recursion depth is at
    most 4 in 3D.

    Returns
    -------
    center : (3,) float64
    radius : float
    """
    vertices, _ = split_geometry(mesh_or_points)
    points = _hull_vertices(vertices)
    points = points[np.random.default_rng(0).permutation(len(points))]
    c, r2 = _welzl(points, len(points), [])
    # the radius is the true max distance from the center (removes round-off)
    radius = float(np.sqrt(np.max(np.sum((vertices - c) ** 2, axis=1))))
    return c, radius


def _hull_vertices(vertices):
    """Distinct points that can lie on the minimum ball: the convex-hull vertices."""
    points = np.unique(vertices, axis=0)
    if len(points) <= 4:
        return points
    try:
        from scipy.spatial import ConvexHull

        return points[ConvexHull(points).vertices]
    except Exception:  # flat or degenerate sets: Welzl on every point is still exact
        return points


def _welzl(points, count, support):
    """Smallest ball enclosing points[:count] with the points of `support` on its boundary.

    points : (n, 3) float64, support : list of (3,) float64 (at most 4)
    Returns (center : (3,) float64, radius2 : float).
    """
    c, r2 = _ball_through(support)
    if len(support) == 4:
        return c, r2
    start = 0
    while start < count:
        d2 = np.sum((points[start:count] - c) ** 2, axis=1)
        outside = np.flatnonzero(d2 > r2 * (1.0 + 1e-12) + 1e-300)
        if outside.size == 0:
            break
        i = start + int(outside[0])
        c, r2 = _welzl(points, i, support + [points[i]])
        start = i + 1
    return c, r2


def _ball_through(support):
    """Smallest ball with all the support points (0 to 4) on its boundary."""
    if not support:
        return np.zeros(3), -1.0  # empty ball: every point is outside
    p0 = support[0]
    if len(support) == 1:
        return p0.copy(), 0.0
    q = np.array(support[1:]) - p0  # (k, 3)
    a = 2.0 * q @ q.T
    b = np.sum(q * q, axis=1)
    lam = np.linalg.lstsq(a, b, rcond=None)[0]
    c = p0 + lam @ q
    r2 = max(float(np.sum((s - c) ** 2)) for s in support)
    return c, r2


# --------------------------------------------------------------------------- scales
def mean_distance(mesh_or_points, center=None):
    """Area-weighted mean distance of the surface from `center`.

    The integral over each triangle uses a fixed, deterministic quadrature: the
    triangle is split into k x k congruent sub-triangles evaluated at their
    centroids, with k (1 to 64, a power of 2) the smallest for which sub-triangles
    are under 3% of their distance from `center` (relative error ~1e-4 or better,
    also when `center` lies on the surface). Point clouds: the mean distance of the
    points.

    center : (3,) float or None (surface centroid)
    Returns distance : float
    """
    vertices, faces = split_geometry(mesh_or_points)
    c = _coerce_center(mesh_or_points, center)
    if faces is None:
        return float(np.mean(np.linalg.norm(vertices - c, axis=1)))
    triangles = vertices[faces] - c  # (f, 3, 3)
    edge = np.linalg.norm(triangles - np.roll(triangles, 1, axis=1), axis=2).max(axis=1)
    distance = np.linalg.norm(triangles.mean(axis=1), axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        needed = np.where(distance > 0, edge / (_RELATIVE_STEP * distance), np.inf)
    levels = np.searchsorted(_SUBDIVISIONS, np.minimum(needed, _SUBDIVISIONS[-1]))
    areas = triangle_areas(triangles)
    total = 0.0
    for level in np.unique(levels):
        mask = levels == level
        total += _integrate_distance(triangles[mask], areas[mask], int(_SUBDIVISIONS[level]))
    return total / float(areas.sum())


def _integrate_distance(triangles, areas, subdivisions):
    """sum_f area_f * mean |x| over triangle f (sub-triangle centroid rule).

    triangles : (f, 3, 3) float (already relative to the center), areas : (f,) float
    """
    bary = _subtriangle_centroids(subdivisions)  # (k, 3)
    chunk = max(1, _CHUNK_NODES // len(bary))
    total = 0.0
    for lo in range(0, len(triangles), chunk):
        nodes = np.einsum("kj,bjd->bkd", bary, triangles[lo : lo + chunk])  # (b, k, 3)
        total += float(np.dot(areas[lo : lo + chunk], np.linalg.norm(nodes, axis=2).mean(axis=1)))
    return total


def _subtriangle_centroids(n):
    """Barycentric coordinates of the centroids of the n*n sub-triangles: (n*n, 3) float."""
    out = []
    for i in range(n):
        for j in range(n - i):
            out.append((i + 1 / 3, j + 1 / 3))  # upright
            if i + j < n - 1:
                out.append((i + 2 / 3, j + 2 / 3))  # inverted
    uv = np.array(out) / n
    return np.column_stack([1.0 - uv.sum(axis=1), uv[:, 0], uv[:, 1]])


def unit_cube(mesh_or_points):
    """Largest extent of the axis-aligned bounding box (the scale that fits a unit cube).

    Returns extent : float
    """
    vertices, _ = split_geometry(mesh_or_points)
    return float(np.max(vertices.max(axis=0) - vertices.min(axis=0)))


def unit_sphere(mesh_or_points, center=None):
    """Largest distance of a vertex from `center` (the scale that fits a unit sphere).

    center : (3,) float or None (surface centroid)
    Returns radius : float
    """
    vertices, _ = split_geometry(mesh_or_points)
    c = _coerce_center(mesh_or_points, center)
    return float(np.max(np.linalg.norm(vertices - c, axis=1)))


# --------------------------------------------------------------------------- dispatch
def center(mesh_or_points, method="surface_centroid"):
    """Center by name, one of :data:`CENTERS`.  Returns center : (3,) float64."""
    if method not in CENTERS:
        raise InvalidInputError(f"unknown center method {method!r}; valid: {', '.join(CENTERS)}")
    if method == "min_ball":
        return min_ball(mesh_or_points)[0]
    return globals()[method](mesh_or_points)


def scale(mesh_or_points, method="mean_distance", center=None):
    """Scale by name, one of :data:`SCALES`, measured about `center` where it matters.

    center : (3,) float or None (surface centroid; ignored by ``unit_cube``)
    Returns scale : float
    """
    if method not in SCALES:
        raise InvalidInputError(f"unknown scale method {method!r}; valid: {', '.join(SCALES)}")
    if method == "unit_cube":
        return unit_cube(mesh_or_points)
    return globals()[method](mesh_or_points, center)
