"""The five input variants of the consistency protocol (seeded, exactly defined).

Every variant is made after the rigid-core alignment of the class (:func:`align_core`), from the
aligned meshes.
One generator per instance: ``rng = np.random.default_rng([seed, class_index, instance_index])``;
which half of a class gets a stray part comes from ``np.random.default_rng([seed, class_index])``
(see :func:`stray_mask`). Units are the meshes'. The up axis (for the stray part's height) is the
axis of the largest extent of the class's first mesh unless given.

Variants
--------
plain         the mesh as given.
outliers      on half of the instances (stray_mask), one separate closed part is added: an
              icosphere (3 subdivisions, 1280 faces) whose surface area is a fraction
              a ~ U(0.02, 0.05) of the mesh's area (radius r = sqrt(a A / 4 pi), scaled so the
              polyhedron's area is exactly a A).  Placement: a horizontal unit direction
              u = cos(t) e1 + sin(t) e2 (t ~ U(0, 2 pi), e1, e2 the two non-up axes); the center
              is c_box + s u with s chosen (bisection) so the horizontal distance from the
              center to the mesh's axis-aligned bounding box is exactly 2 r: the sphere is a gap
              of r away from the box (never touches the mesh).  Its height along the up axis is
              ~ U(box min, box max).  The other half are returned unchanged.
big_outliers  the same with a ~ U(0.08, 0.15).
points        the mesh's vertices only (trimesh.PointCloud, no faces).
holes         ~10 % of the faces removed in 5 connected patches: 5 seed faces drawn from the
              faces not yet removed; each patch grows by breadth-first search over face
              adjacency (shared edges), over faces not yet removed, until it holds
              round(0.02 F) faces (or its front is exhausted).  Unreferenced vertices dropped.
"""
from __future__ import annotations

from collections import deque
from collections.abc import Mapping

import numpy as np

from .._validate import InvalidInputError, check_int, is_name

VARIANTS = ("plain", "outliers", "big_outliers", "points", "holes")
STRAY_FRACTIONS = {"outliers": (0.02, 0.05), "big_outliers": (0.08, 0.15)}


def stray_mask(n: int, seed: int, class_index: int) -> np.ndarray:
    """(n,) bool: which instances of a class get a stray part (first n // 2 of a permutation);
    n, seed and class_index ints >= 0 (InvalidInputError otherwise)."""
    n = check_int(n, "n", 0)  # (-1 was NumPy's "negative dimensions", 1.5 an AxisError)
    seed, class_index = check_int(seed, "seed", 0), check_int(class_index, "class_index", 0)
    perm = np.random.default_rng([seed, class_index]).permutation(n)
    mask = np.zeros(n, bool)
    mask[perm[: n // 2]] = True
    return mask


def _box_distance_2d(p, half):
    """Distance of 2D points p (..., 2) from the centred rectangle with half-sizes half (2,)."""
    d = np.maximum(np.abs(p) - half, 0.0)
    return np.sqrt(np.sum(d * d, axis=-1))


def add_stray_part(mesh, fraction_range, rng, up: int):
    """The mesh (Trimesh) plus one separate icosphere (module docs); ``up`` is the up axis (0, 1, 2)."""
    import trimesh

    a = rng.uniform(*fraction_range)
    theta = rng.uniform(0.0, 2.0 * np.pi)
    t_height = rng.uniform()
    area = a * mesh.area
    sphere = trimesh.creation.icosphere(subdivisions=3)
    sphere.vertices *= np.sqrt(area / sphere.area)  # exact polyhedron area a * A
    r = np.sqrt(area / (4.0 * np.pi))
    lo, hi = mesh.bounds
    box_c, half = (lo + hi) / 2.0, (hi - lo) / 2.0
    horiz = [k for k in range(3) if k != up]
    u = np.array([np.cos(theta), np.sin(theta)])
    # smallest s with horizontal distance 2 r from the box (monotone in s): bisection
    s_lo, s_hi = 0.0, float(np.linalg.norm(half[horiz])) + 2.0 * r + 1.0
    for _ in range(80):
        s = 0.5 * (s_lo + s_hi)
        if _box_distance_2d(s * u, half[horiz]) < 2.0 * r:
            s_lo = s
        else:
            s_hi = s
    center = box_c.copy()
    center[horiz] = box_c[horiz] + s_hi * u
    center[up] = lo[up] + t_height * (hi[up] - lo[up])
    sphere.vertices += center
    out = trimesh.Trimesh(np.vstack([mesh.vertices, sphere.vertices]),
                          np.vstack([mesh.faces, sphere.faces + len(mesh.vertices)]), process=False)
    out.metadata["stray"] = {"fraction": float(a), "radius": float(r), "center": center.tolist()}
    return out


def punch_holes(mesh, rng, patches: int = 5, patch_fraction: float = 0.02):
    """The mesh (Trimesh) without ``patches`` BFS-grown connected face patches of
    round(patch_fraction F) faces each."""
    import trimesh

    f = len(mesh.faces)
    adj = mesh.face_adjacency  # (e, 2) faces sharing an edge
    a0 = np.concatenate([adj[:, 0], adj[:, 1]])
    a1 = np.concatenate([adj[:, 1], adj[:, 0]])
    order = np.lexsort((a1, a0))
    a0, a1 = a0[order], a1[order]
    start = np.searchsorted(a0, np.arange(f + 1))
    removed = np.zeros(f, bool)
    target = int(round(patch_fraction * f))
    for _ in range(patches):
        candidates = np.flatnonzero(~removed)
        seed_face = int(candidates[rng.integers(len(candidates))])
        queue, count = deque([seed_face]), 1
        removed[seed_face] = True
        while queue and count < target:
            g = queue.popleft()
            for h in a1[start[g]:start[g + 1]]:
                if not removed[h] and count < target:
                    removed[h] = True
                    count += 1
                    queue.append(int(h))
    out = trimesh.Trimesh(mesh.vertices.copy(), mesh.faces[~removed], process=False)
    out.remove_unreferenced_vertices()
    out.metadata["holes"] = {"removed_faces": int(removed.sum()),
                             "removed_area": float(mesh.area_faces[removed].sum())}
    return out


def _check_up(up):
    """``up`` as an axis index 0, 1 or 2 (an int by :func:`jaxpose._validate.check_int`'s rule);
    InvalidInputError otherwise."""
    number = check_int(up, "up", float("-inf"))  # an int; its range below, in one message
    if not 0 <= number <= 2:
        raise InvalidInputError(f"up must be 0, 1 or 2 (an axis), got {number}")
    return number


def make_variant(mesh, variant: str, rng, *, up: int = 2, stray: bool = True):
    """One instance of ``variant`` (module docs) from an aligned mesh.

    Args:
      mesh: Trimesh (aligned); variant: one of :data:`VARIANTS`;
      rng: ``np.random.default_rng([seed, class_index, instance_index])`` (a Generator; an int is
        refused);
      up: index of the up axis (0, 1 or 2; InvalidInputError otherwise); stray: for outliers /
        big_outliers, whether this instance gets the part (:func:`stray_mask`).

    Returns:
      a new Trimesh (a PointCloud for ``points``).
    """
    import trimesh

    if not is_name(variant, VARIANTS):
        raise InvalidInputError(f"unknown variant {variant!r}; valid: {', '.join(VARIANTS)}")
    if not isinstance(rng, np.random.Generator):
        raise InvalidInputError(f"rng must be a numpy.random.Generator (np.random.default_rng([seed, class_index, "
                                f"instance_index])), got {rng!r:.80}")
    up = _check_up(up)
    if variant != "points" and len(getattr(mesh, "faces", ())) == 0:
        raise InvalidInputError(f"variant {variant!r} needs meshes with faces")
    if variant == "plain":
        return mesh.copy()
    if variant in STRAY_FRACTIONS:
        return add_stray_part(mesh, STRAY_FRACTIONS[variant], rng, up) if stray else mesh.copy()
    if variant == "points":
        return trimesh.PointCloud(np.asarray(mesh.vertices, np.float64).copy())
    if variant == "holes":
        return punch_holes(mesh, rng)


def up_axis(mesh) -> int:
    """The axis (0, 1, 2) of the largest extent of a mesh's bounding box."""
    v = np.asarray(mesh.vertices, np.float64)
    return int(np.argmax(v.max(axis=0) - v.min(axis=0)))


def make_class(meshes, variant: str, seed: int, class_index: int, up: int | None = None):
    """All instances of one aligned class for ``variant`` (the seeding rule of the module docs);
    ``up`` None: :func:`up_axis` of the first mesh, else an axis 0, 1 or 2; seed and class_index
    ints >= 0, ``meshes`` a non-empty list (a sequence) of meshes (InvalidInputError otherwise)."""
    seed, class_index = check_int(seed, "seed", 0), check_int(class_index, "class_index", 0)
    if isinstance(meshes, Mapping):  # load_folder's {class: meshes}
        raise InvalidInputError("meshes must be one class's list of meshes, got a mapping (of classes?): pass "
                                "classes[name]")
    if isinstance(meshes, (str, bytes)) or not hasattr(meshes, "__len__") or not hasattr(meshes, "__getitem__"):
        raise InvalidInputError(f"meshes must be a list of meshes, got {meshes!r:.80}")
    if len(meshes) == 0:
        raise InvalidInputError("meshes is empty: a class needs at least one mesh")
    up = up_axis(meshes[0]) if up is None else _check_up(up)
    mask = stray_mask(len(meshes), seed, class_index)
    return [make_variant(m, variant, np.random.default_rng([seed, class_index, k]), up=up, stray=bool(mask[k]))
            for k, m in enumerate(meshes)]
