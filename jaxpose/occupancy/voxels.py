"""The filled voxel solid of a closed mesh: its voxels, their depths, the depth-weighted centroid.

The baseline ``depth_weighted_solid`` of :mod:`jaxpose.baselines` (and the ``depth_weighted_solid``
estimator): the mesh is voxelized and filled as trimesh's ``mesh.voxelized(pitch).fill()`` does,
each voxel weighted by its Euclidean depth to the power p. Plain NumPy and SciPy on concrete
meshes; the fill needs a closed surface (it warns on an open one, raises with ``strict=True``).
For a solid that tolerates holes and stray parts, see :mod:`jaxpose.occupancy.solid`.

Example::

    import trimesh
    c = depth_weighted_solid(trimesh.creation.box((2.0, 1.0, 1.0)), power=4.0)  # (0, 0, 0) within a voxel
"""
from __future__ import annotations

import numpy as np

from .._validate import check_concrete, check_int, check_real
from ..geometry import require_faces, warn_if_open
from ..host import anchor

__all__ = ["DEPTH_VOXELS", "DEPTH_POWER", "GRID_SHIFT", "depth_weighted_solid", "filled_voxels", "weighted_centroid"]

DEPTH_VOXELS = 96  # depth_weighted_solid: voxels along the largest extent
DEPTH_POWER = 2.0  # depth_weighted_solid: the depth exponent p (the baseline and the estimator of that name)
# The voxel grid starts this fraction of a pitch below the lowest vertex, an irrational fraction
# ((sqrt 5 - 1) / 4), so the vertices of regular meshes (boxes, capsules: a whole number of pitches
# apart) do not lie on voxel faces, where rounding would decide their voxel.
GRID_SHIFT = 0.25 * (5.0 ** 0.5 - 1.0)


def depth_weighted_solid(mesh_or_points, power=DEPTH_POWER, voxels=DEPTH_VOXELS, strict=False):
    """Centroid of the voxelized, filled solid, each voxel weighted by its depth to the power p.

    The mesh is voxelized at pitch = largest extent / ``voxels`` and filled (the construction of
    trimesh's ``mesh.voxelized(pitch).fill()``, :func:`filled_voxels`); each voxel's depth is its
    Euclidean distance to the outside (``scipy.ndimage.distance_transform_edt``);
    c = sum d^p x / sum d^p. The deep part of a
    body (the torso) moves least when it articulates. The fill needs a closed surface: with holes it
    leaks (the solid is then the surface shell only).

    Args:
      power: p >= 0; voxels: int >= 8; strict: raise on an open mesh (warns otherwise).

    Returns:
      center : (3,) float64.
    """
    power = check_real(power, "power", 0)
    x, d = filled_voxels(mesh_or_points, voxels, strict)
    return weighted_centroid(x, d ** power)


def weighted_centroid(x, w):
    """sum w x / sum w of points x (n, 3) with weights w (n,) >= 0, in float64, by two passes.

    The second pass adds the weighted mean of the residuals x - c, so points far from the origin
    (scanner coordinates) lose no digits to the first sum's rounding. Returns (3,) float64.
    """
    check_concrete("x and w", x, w)
    x, w = np.asarray(x, np.float64), np.asarray(w, np.float64)
    total = w.sum()
    c = (w @ x) / total
    return c + (w @ (x - c)) / total


def filled_voxels(mesh_or_points, voxels=DEPTH_VOXELS, strict=False):
    """The voxels of the filled mesh and their depths, as :func:`depth_weighted_solid` uses them.

    The construction of ``mesh.voxelized(pitch).fill()``: the voxels (pitch = largest extent /
    ``voxels``) that the surface passes through are marked from a lattice of points on every
    triangle at most half a pitch apart, then every voxel enclosed by them is filled
    (``scipy.ndimage.binary_fill_holes``). The grid is laid out about the vertex nearest the
    middle of the bounding box and starts ``GRID_SHIFT`` of a pitch below the lowest vertex, so a
    translated mesh gives the same voxels, translated.

    Returns:
      centers (n, 3) float64 of the filled voxels and their depths (n,) in voxels (the Euclidean
      distance to the nearest outside voxel).
    """
    from scipy import ndimage

    vertices, faces = require_faces(mesh_or_points, "depth_weighted_solid")
    voxels = check_int(voxels, "voxels", 8)
    warn_if_open(faces, "depth_weighted_solid", strict)
    origin = anchor(vertices)  # voxelize about one of the mesh's own vertices: exact far from the origin
    vertices = vertices - origin
    pitch = float(np.max(vertices.max(axis=0) - vertices.min(axis=0))) / int(voxels)
    lo = vertices.min(axis=0) - GRID_SHIFT * pitch
    shape = np.floor((vertices.max(axis=0) - lo) / pitch).astype(int) + 3
    occupied = np.zeros(shape, bool)
    for points in _surface_lattice(vertices[faces], 0.5 * pitch):
        idx = np.floor((points - lo) / pitch).astype(np.int64) + 1
        occupied[idx[:, 0], idx[:, 1], idx[:, 2]] = True
    filled = ndimage.binary_fill_holes(occupied)
    edt = ndimage.distance_transform_edt(filled)
    idx = np.argwhere(filled)
    return origin + (lo + (idx - 1 + 0.5) * pitch), edt[tuple(idx.T)]


def _surface_lattice(triangles, step, chunk=1 << 21):
    """Points on every triangle (f, 3, 3) of a barycentric lattice with k subdivisions, k = the
    smallest with edges / k <= step; yields (n, 3) blocks."""
    edge = np.linalg.norm(triangles - np.roll(triangles, 1, axis=1), axis=2).max(axis=1)
    k = np.maximum(1, np.ceil(edge / step)).astype(np.int64)
    for level in np.unique(k):
        i, j = np.meshgrid(np.arange(level + 1), np.arange(level + 1), indexing="ij")
        keep = i + j <= level
        bary = np.column_stack([level - i[keep] - j[keep], i[keep], j[keep]]) / level
        tri = triangles[k == level]
        per = max(1, chunk // len(bary))
        for start in range(0, len(tri), per):
            yield np.matmul(bary, tri[start:start + per]).reshape(-1, 3)  # (b, k, 3): BLAS, where einsum loops
