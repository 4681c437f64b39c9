"""Points on a surface: area-weighted, stratified or random, deterministic per seed."""
from __future__ import annotations

import numpy as np

from ._validate import InvalidInputError, check_int
from .geometry import split_geometry, triangle_areas

__all__ = ["SAMPLING", "sample_surface"]

SAMPLING = ("even", "random")


def sample_surface(geometry, count, seed=0, method="even"):
    """Area-weighted points on the surface, deterministic per seed.

    method "random": each point picks a face with probability proportional to area.
    method "even": stratified; face f gets floor or ceil of count * area_f / area
    points (systematic rounding with one random offset), which removes the
    multinomial noise in the per-face counts.
    Point clouds (and meshes without faces): `count` of the points, drawn without
    replacement when there are enough.

    geometry : Trimesh | PointCloud | (n, 3) array (loaded: for paths, :func:`jaxpose.mesh.sample_surface`),
    count : int >= 4, seed : int
    Returns samples : (count, 3) float64, in the units of the geometry

    Example::

        points = sample_surface(trimesh.creation.icosphere(), 2000, seed=0)   # (2000, 3) on the sphere
    """
    count = check_int(count, "count", minimum=4)
    seed = check_int(seed, "seed", minimum=0)
    if method not in SAMPLING:
        raise InvalidInputError(f"unknown sampling {method!r}; valid: {', '.join(SAMPLING)}")
    rng = np.random.default_rng(seed)
    vertices, faces = split_geometry(geometry)
    if faces is None:
        index = rng.choice(len(vertices), size=count, replace=len(vertices) < count)
        return vertices[index].copy()
    triangles = vertices[faces]  # (f, 3, 3)
    areas = triangle_areas(triangles)
    if method == "random":
        face = rng.choice(len(faces), size=count, p=areas / areas.sum())
    else:
        expected = np.minimum(np.cumsum(areas) * (count / areas.sum()), count)
        expected[-1] = count  # exact total despite round-off
        edges = np.floor(np.concatenate([[0.0], expected]) + rng.uniform())
        per_face = np.diff(edges).astype(np.int64)  # sums to count exactly
        face = np.repeat(np.arange(len(faces)), per_face)
    uv = rng.uniform(size=(count, 2))
    flip = uv.sum(axis=1) > 1.0
    uv[flip] = 1.0 - uv[flip]
    tri = triangles[face]
    return tri[:, 0] + uv[:, :1] * (tri[:, 1] - tri[:, 0]) + uv[:, 1:] * (tri[:, 2] - tri[:, 0])
