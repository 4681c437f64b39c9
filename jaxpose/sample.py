"""Points on a surface: area-weighted, stratified or random, deterministic per seed."""
from __future__ import annotations

import numpy as np

from .config import MEMORY_BUDGET, SAMPLING
from ._validate import (InvalidInputError, check_array, check_concrete, check_faces, check_gamma, check_int, check_nu,
                        check_real, is_name as _is_name)
from .geometry import split_geometry, triangle_areas

__all__ = ["SAMPLING", "SAMPLE_BYTES", "check_count", "check_fit_values", "sample_surface", "lattice_points"]

SAMPLE_BYTES = 128  # peak bytes per sample: face index, barycentric pair, its triangle's corners, the point
LATTICE_BYTES = 64  # peak bytes per lattice point (lattice_points): the point, its copy in the result, the lattice


def check_count(count):
    """A sample count: an int >= 4 whose samples fit ``config.MEMORY_BUDGET`` at ``SAMPLE_BYTES``
    each (a larger count was a raw MemoryError, or swapping); InvalidInputError otherwise."""
    count = check_int(count, "count", minimum=4)
    if count * SAMPLE_BYTES > MEMORY_BUDGET:
        raise InvalidInputError(f"count={count} samples need about {count * SAMPLE_BYTES / 2**30:.3g} GiB; the limit is "
                                f"{MEMORY_BUDGET / 2**30:g} GiB: use at most {MEMORY_BUDGET // SAMPLE_BYTES}")
    return count


def check_fit_values(values):
    """Check, by their rules, those of the OCSVM's sampled-fit arguments that ``values`` (a mapping)
    holds: ``gamma``, ``nu``, ``count`` (:func:`check_count`), ``seed`` (an int >= 0), ``sampling``
    (one of :data:`SAMPLING`); InvalidInputError naming the first bad one. Other keys are not read."""
    checks = {"gamma": check_gamma, "nu": check_nu, "count": check_count, "seed": lambda v: check_int(v, "seed", 0)}
    for key, value in values.items():
        if key in checks:
            checks[key](value)
    if "sampling" in values and not _is_name(values["sampling"], SAMPLING):
        raise InvalidInputError(f"unknown sampling {values['sampling']!r}; valid: {', '.join(SAMPLING)}")


def sample_surface(geometry, count, seed=0, method="even"):
    """Area-weighted points on the surface, deterministic per seed.

    method "random": each point picks a face with probability proportional to area.
    method "even": stratified; face f gets floor or ceil of count * area_f / area
    points (systematic rounding with one random offset), which removes the
    multinomial noise in the per-face counts.
    Point clouds (and meshes without faces): `count` of the points, drawn without
    replacement when there are enough.

    geometry : Trimesh | PointCloud | Surface | (n, 3) array (loaded; a path is refused, naming :func:`jaxpose.mesh.load` and :func:`jaxpose.mesh.sample_surface`, which reads paths),
    count : int >= 4 (at most :func:`check_count`'s limit), seed : int
    Returns samples : (count, 3) float64, in the units of the geometry

    Example::

        points = sample_surface(trimesh.creation.icosphere(), 2000, seed=0)   # (2000, 3) on the sphere
    """
    count = check_count(count)
    seed = check_int(seed, "seed", minimum=0)
    if not _is_name(method, SAMPLING):
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


def lattice_points(vertices, faces, spacing):
    """A mesh's vertices and points on its faces no farther apart than ``spacing``, deterministic.

    Every face whose longest edge L exceeds ``spacing`` also gets the points of the barycentric
    lattice (i / n, j / n, 1 - (i + j) / n), i + j <= n, n = ceil(L / spacing), corners excepted
    (they are vertices). The points depend only on the faces' shapes, so a moved mesh gives the
    same points, moved. Neighbouring faces repeat the points of a shared edge.

    Args:
      vertices: (n, 3) finite floats; faces: (f, 3) int indices of them (None or empty: the
        vertices alone); other shapes, kinds or indices are :class:`InvalidInputError`.
      spacing: > 0, in the vertices' units, such that the points fit ``config.MEMORY_BUDGET`` at
        ``LATTICE_BYTES`` each (else :class:`InvalidInputError`, before anything is allocated).

    Returns:
      (m, 3) float64, the vertices first.

    Example::

        box = trimesh.creation.box()                  # 8 vertices, 12 faces, edges 1 and sqrt(2)
        lattice_points(box.vertices, box.faces, 0.5)  # (8 + 12 * 7, 3): n = 3 on every face
    """
    spacing = check_real(spacing, "spacing", 0, strict=True)  # (must be > 0: the message names it)
    check_concrete("vertices and faces", vertices, faces)
    # (NaN vertices gave NaN points; float faces were truncated, an index past the vertices an IndexError)
    v = np.asarray(check_array(vertices, "vertices"), np.float64)
    if faces is None or not len(faces):
        return v.copy()
    t = v[np.asarray(check_faces(faces, len(v)), np.int64)]
    longest = np.max(np.linalg.norm(t - np.roll(t, 1, axis=1), axis=2), axis=1)
    with np.errstate(over="ignore"):  # float64 (a tiny spacing's counts overflow an int): inf is too many
        steps = np.ceil(longest / spacing)
        many = steps[steps >= 2]
        points = float(np.sum((many + 1) * (many + 2) / 2 - 3))
    if points * LATTICE_BYTES > MEMORY_BUDGET:  # a tiny spacing filled the memory (the process was killed)
        least = np.sqrt(np.sum(longest**2) / 2 * LATTICE_BYTES / MEMORY_BUDGET)  # about n^2 / 2 points a face
        raise InvalidInputError(f"spacing={spacing:g} puts about {points:.3g} points on the faces; they need more than "
                                f"the limit of {MEMORY_BUDGET / 2**30:g} GiB: use a spacing of at least about {least:.3g}")
    n = steps.astype(np.int64)
    out = [v]
    for k in np.unique(n[n >= 2]):
        i, j = np.meshgrid(np.arange(k + 1), np.arange(k + 1), indexing="ij")
        keep = (i + j <= k) & ~(((i == k) | (j == k)) | ((i == 0) & (j == 0)))
        bary = np.stack([i[keep], j[keep], k - i[keep] - j[keep]], axis=1) / k
        out.append(np.einsum("mb,fbi->fmi", bary, t[n == k]).reshape(-1, 3))
    return np.concatenate(out)
