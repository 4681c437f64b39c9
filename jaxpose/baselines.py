"""Classical centers and scales of 3D shapes, one interface.

Every function accepts a :class:`trimesh.Trimesh`, a :class:`trimesh.PointCloud`
or an ``(n, 3)`` array of points. Surface-based quantities (``surface_centroid``,
``mean_distance``) integrate over the triangles of a mesh and fall back to the
points of a point cloud (or of a mesh without faces).

These are the references the OCSVM normalization is compared against (paper,
section 2); they are plain NumPy and are not differentiated.

Centers : ``surface_centroid``, ``vertex_mean``, ``bbox_center``, ``min_ball``,
          ``solid_centroid`` (closed form, closed meshes), ``depth_weighted_solid``
          (voxels, :mod:`jaxpose.occupancy.voxels`).
Scales  : ``mean_distance``, ``unit_cube``, ``unit_sphere``, ``gyration_radius`` (closed form,
          closed meshes), ``sqrt_area`` (meshes).
Frames  : ``pca_vertices``, ``pca_surface``, ``inertia`` (trimesh's principal axes): the usual
          canonical orientations, as :class:`jaxpose.orientation.Frame` (see :func:`frame`).
Dispatch: ``center(mesh, method)``, ``scale(mesh, method, center=None)``, ``frame(mesh, method)``.

The solid quantities need a closed surface: on an open mesh they warn (:class:`OpenMeshWarning`)
and, with ``strict=True``, raise; on a point cloud they raise.
"""
from __future__ import annotations

import numpy as np

from . import sample
from ._validate import InvalidInputError, JaxposeError, check_concrete, is_name, is_real_dtype
from .geometry import is_closed, require_faces, split_geometry, triangle_areas, warn_if_open
from .host import anchor
from .orientation import SIGN_MIN, Frame, ambiguity, complete_signs, proper, relative_gaps, third_moments
from .occupancy.voxels import depth_weighted_solid, filled_voxels, weighted_centroid

__all__ = [
    "CENTERS",
    "SCALES",
    "FRAMES",
    "center",
    "scale",
    "frame",
    "pca_vertices_frame",
    "pca_surface_frame",
    "inertia_frame",
    "surface_centroid",
    "vertex_mean",
    "bbox_center",
    "min_ball",
    "mean_distance",
    "unit_cube",
    "unit_sphere",
    "solid_moments",
    "solid_centroid",
    "gyration_radius",
    "sqrt_area",
    "depth_weighted_solid",
    "filled_voxels",
    "weighted_centroid",
    "is_closed",
    "split_geometry",
    "triangle_areas",
]

FRAME_SAMPLES = 20000  # pca_surface: even surface samples (seed 0)

# mean_distance splits each triangle into k*k congruent sub-triangles (k from
# _SUBDIVISIONS) whose centroids, weighted by area, form a deterministic quadrature.
_SUBDIVISIONS = np.array([1, 2, 4, 8, 16, 32, 64])
_RELATIVE_STEP = 0.03  # sub-triangle size / distance from the center
_CHUNK_NODES = 1 << 22  # quadrature nodes per block (bounds memory)


# --------------------------------------------------------------------------- coercion
def _coerce_center(mesh_or_points, center_point):
    if center_point is None:
        return surface_centroid(mesh_or_points)
    check_concrete("center", center_point)
    try:
        given = np.asarray(center_point)
    except (TypeError, ValueError):  # ragged and the like
        given = None
    if given is None or given.shape != (3,) or not is_real_dtype(given.dtype) or not np.all(np.isfinite(given)):
        raise InvalidInputError(f"center must be 3 finite numbers, got {center_point!r}")
    c = given.astype(np.float64)
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
        return _mean_about_anchor(vertices)
    origin = anchor(vertices)  # sums about one of the mesh's own vertices: no digits lost far from the origin
    triangles = vertices[faces] - origin
    areas = triangle_areas(triangles)
    return origin + (areas[:, None] * triangles.mean(axis=1)).sum(axis=0) / areas.sum()


def vertex_mean(mesh_or_points):
    """Mean of the vertices (or points), summed about one of them.  Returns center : (3,) float64."""
    return _mean_about_anchor(split_geometry(mesh_or_points)[0])


def _mean_about_anchor(vertices):
    origin = anchor(vertices)
    return origin + (vertices - origin).mean(axis=0)


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
        nodes = np.matmul(bary, triangles[lo : lo + chunk])  # (b, k, 3): BLAS, where einsum loops
        total += float(np.dot(areas[lo : lo + chunk], _norms(nodes).mean(axis=1)))
    return total


def _norms(x):
    """|x| over the last axis (of 3), as np.linalg.norm(x, axis=-1) (the same values), without its
    reduction over a short axis."""
    return np.sqrt(x[..., 0] ** 2 + x[..., 1] ** 2 + x[..., 2] ** 2)


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


# --------------------------------------------------------------------------- solids
def solid_moments(mesh, strict=False):
    """Volume, centroid and second moment of the solid a closed mesh bounds, in closed form.

    Each face (a, b, c) and a reference point o span a signed tetrahedron of volume
    V_t = (a - o).((b - o) x (c - o)) / 6; by the divergence theorem V = sum V_t,
    V c = sum V_t (o + a + b + c) / 4 and int (x - o)(x - o)^T dV = sum V_t / 20 (A A^T + B B^T +
    C C^T + S S^T) with A = a - o, ..., S = A + B + C (o: the vertex mean, for accuracy).
    Outward faces give V > 0; inverted meshes are turned over (V < 0 -> -V, same centroid).

    Args:
      mesh: Trimesh (or anything with vertices and faces); strict: raise on an open mesh.

    Returns:
      volume () float, centroid (3,) float64, second (3, 3) float64 = (1/V) int (x - c)(x - c)^T dV.

    Raises:
      InvalidInputError: points only, zero volume, or (strict) an open mesh. Warns
      :class:`OpenMeshWarning` on an open mesh otherwise.
    """
    vertices, faces = require_faces(mesh, "a solid")
    warn_if_open(faces, "solid moments", strict)
    o = vertices.mean(axis=0)
    t = vertices[faces] - o  # (f, 3, 3): A, B, C
    vt = np.einsum("fi,fi->f", t[:, 0], np.cross(t[:, 1], t[:, 2])) / 6.0
    volume = float(vt.sum())
    if not abs(volume) > 0:
        raise InvalidInputError("the mesh encloses no volume")
    s = t.sum(axis=1)
    first = (vt @ s) / 4.0 / volume
    m2 = np.einsum("f,fki,fkj->ij", vt, t, t) + np.einsum("f,fi,fj->ij", vt, s, s)
    second = m2 / 20.0 / volume - np.outer(first, first)
    return abs(volume), o + first, second


def solid_centroid(mesh_or_points, strict=False):
    """Closed-form centroid of the solid a closed mesh bounds (:func:`solid_moments`).

    For a closed mesh, the same as ``trimesh.triangles.mass_properties(mesh.triangles)["center_mass"]``.
    An open mesh bounds no solid (it warns, or raises with ``strict``): there the two differ, as
    each sums the faces' tetrahedra to its own reference point (here the vertex mean, so the
    result moves with the mesh; trimesh's the origin, so its result does not).
    Returns center : (3,) float64. Raises on points.
    """
    return solid_moments(mesh_or_points, strict)[1]


def gyration_radius(mesh_or_points, center=None, strict=False):
    """Radius of gyration of the solid: sqrt((1/V) int |x - center|^2 dV) (closed form).

    center : (3,) or None (the solid centroid). Returns radius : float.
    Raises on points; warns (or raises, strict) on an open mesh.
    """
    _, c, second = solid_moments(mesh_or_points, strict)
    shift = 0.0 if center is None else float(np.sum((_coerce_center(mesh_or_points, center) - c) ** 2))
    return float(np.sqrt(np.trace(second) + shift))


def sqrt_area(mesh_or_points):
    """sqrt of the surface area (nearly invariant under articulation, which preserves area).

    Returns scale : float. Raises InvalidInputError on points (they have no area) and on a mesh
    of zero area.
    """
    vertices, faces = require_faces(mesh_or_points, "sqrt_area")
    area = float(triangle_areas(vertices[faces]).sum())
    return float(np.sqrt(area))


# --------------------------------------------------------------------------- dispatch
def center(mesh_or_points, method="surface_centroid"):
    """Center by name, one of :data:`CENTERS`.  Returns center : (3,) float64."""
    if not is_name(method, CENTERS):  # (an array: NumPy's "truth value ... ambiguous")
        raise InvalidInputError(f"unknown center method {method!r}; valid: {', '.join(CENTERS)}")
    return _CENTERS[method](mesh_or_points)  # solid ones: defaults (warn on open meshes)


def scale(mesh_or_points, method="mean_distance", center=None):
    """Scale by name, one of :data:`SCALES`, measured about `center` where it matters.

    center : (3,) float or None (surface centroid; ignored by ``unit_cube``)
    Returns scale : float
    """
    if not is_name(method, SCALES):
        raise InvalidInputError(f"unknown scale method {method!r}; valid: {', '.join(SCALES)}")
    return _SCALES[method](mesh_or_points, center)


# --------------------------------------------------------------------------- frames
def _skew_frame(x):
    """PCA frame of points x (n, 3): covariance eigenvectors (largest first), each pointing to its
    positive third moment on the two most skewed axes, the least skewed completed by det = +1."""
    d = x - x.mean(axis=0)
    lam, vec = np.linalg.eigh(d.T @ d / len(x))
    lam, axes = lam[::-1], vec[:, ::-1].T
    z = d @ axes.T
    stat = third_moments(z) / SIGN_MIN  # (scale-free: cubes beyond 1e102 or below 1e-103 were inf or 0 / 0)
    rot, margins, k = complete_signs(axes, stat)
    gaps = relative_gaps(lam)
    return Frame(rot, ambiguity(gaps, np.min(np.delete(margins, k))), lam, gaps, margins, k, np.full(3, np.nan))


def pca_vertices_frame(mesh_or_points):
    """PCA of the vertices, signs by third moments (two most skewed axes; the third by det = +1).

    Returns :class:`jaxpose.orientation.Frame`.
    """
    vertices, _ = split_geometry(mesh_or_points)
    return _skew_frame(vertices)


def pca_surface_frame(mesh_or_points, count=FRAME_SAMPLES):
    """PCA of ``count`` even area-weighted surface samples (seed 0: a rotated copy gets the rotated
    samples), signs as :func:`pca_vertices_frame`. Point clouds: their points.

    Returns :class:`jaxpose.orientation.Frame`.
    """
    vertices, faces = split_geometry(mesh_or_points)
    if faces is None:
        return _skew_frame(vertices)
    return _skew_frame(np.asarray(sample.sample_surface(mesh_or_points, count, seed=0), np.float64))


def inertia_frame(mesh_or_points):
    """trimesh's principal inertia axes (``principal_inertia_transform``), in the order of every
    frame: the smallest moment of inertia first (the axis of most spread, the largest second
    moment, as the PCA frames' rows). Rows 1 and 2, the axes of the two largest moments, have
    trimesh's signs; row 0's sign completes det = +1 (``mirror`` 0). Meshes only.

    Returns :class:`jaxpose.orientation.Frame`: ``eigenvalues`` the solid's second moments along
    its rows (largest first), ``gaps`` their relative gaps, and ``ambiguity`` 1 (``flag`` True):
    the signs come from no cue of the shape (a rotated copy may get any proper flip), the sign cue
    the PCA frames measure is 0 here (:func:`jaxpose.orientation.ambiguity`); ``margins`` NaN.
    Raises JaxposeError on a mesh of zero volume (no inertia axes).
    """
    import trimesh

    vertices, faces = require_faces(mesh_or_points, "inertia")
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    with np.errstate(divide="ignore", invalid="ignore"):  # trimesh divides by the volume (0: NaN inertia, then
        volume = mesh.volume                              # NumPy's LinAlgError)
    if not volume:
        raise JaxposeError("the mesh encloses no volume: the inertia frame is undefined; use rotation='pca_surface' "
                           "or 'ocsvm'")
    if volume < 0:  # faces wound inward: the same solid (trimesh would sort its negated moments the other way)
        mesh = trimesh.Trimesh(vertices, np.asarray(faces)[:, ::-1], process=False)
    # trimesh's rows: the largest moment of inertia, the middle one (its signs), their cross product
    largest, middle, least = proper(np.asarray(mesh.principal_inertia_transform[:3, :3], np.float64))
    rot = np.stack([-least, middle, largest])  # reversed, row 0 negated: det +1 (a fixed proper turn of trimesh's)
    inertia = np.asarray(mesh.moment_inertia, np.float64)  # about the centroid, of mass = volume (density 1)
    second = (0.5 * np.trace(inertia) * np.eye(3) - inertia) / float(mesh.mass)  # the solid's second moments
    lam = np.einsum("ij,jk,ik->i", rot, second, rot)
    gaps = relative_gaps(lam)
    return Frame(rot, ambiguity(gaps, 0.0), lam, gaps, np.full(3, np.nan), 0, np.full(3, np.nan))


def frame(mesh_or_points, method="pca_surface"):
    """Frame by name, one of :data:`FRAMES`.  Returns :class:`jaxpose.orientation.Frame`."""
    if not is_name(method, FRAMES):
        raise InvalidInputError(f"unknown frame method {method!r}; valid: {', '.join(FRAMES)}")
    return _FRAMES[method](mesh_or_points)


# --------------------------------------------------------------------------- registries: name -> function
_CENTERS = {  # (mesh_or_points) -> (3,)
    "surface_centroid": surface_centroid,
    "vertex_mean": vertex_mean,
    "bbox_center": bbox_center,
    "min_ball": lambda mesh_or_points: min_ball(mesh_or_points)[0],
    "solid_centroid": solid_centroid,
    "depth_weighted_solid": depth_weighted_solid,
}
_SCALES = {  # (mesh_or_points, center) -> float; the center is ignored where it does not matter
    "mean_distance": mean_distance,
    "unit_cube": lambda mesh_or_points, center: unit_cube(mesh_or_points),
    "unit_sphere": unit_sphere,
    "gyration_radius": gyration_radius,
    "sqrt_area": lambda mesh_or_points, center: sqrt_area(mesh_or_points),
}
_FRAMES = {"pca_vertices": pca_vertices_frame, "pca_surface": pca_surface_frame, "inertia": inertia_frame}
CENTERS = tuple(_CENTERS)
SCALES = tuple(_SCALES)
FRAMES = tuple(_FRAMES)
