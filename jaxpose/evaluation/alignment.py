"""Rigid-core alignment of a class of meshes that share their vertex order (registrations)."""
from __future__ import annotations

import numpy as np

from .._validate import InvalidInputError, check_array, check_int, check_real, is_real_dtype

__all__ = ["align_core", "align_classes", "kabsch", "CORE_WEIGHTS", "check_core_weight", "vertex_weights"]

#: What a vertex's share of the body is when the stable core is chosen (:func:`align_core`).
CORE_WEIGHTS = ("vertices", "area")

def kabsch(x, y, w=None):
    """Rotation r (3, 3) and translation t (3,) minimising sum_i w_i |r x_i + t - y_i|^2.

    x, y : (n, 3) float; w : optional (n,) non-negative weights (default: all 1) of a positive
    sum. InvalidInputError otherwise.
    """
    x = np.asarray(check_array(x, "x", 1), np.float64)
    y = np.asarray(check_array(y, "y", 1), np.float64)
    if len(x) != len(y):
        raise InvalidInputError(f"x and y must have as many points, got {len(x)} and {len(y)}")
    if w is not None:
        try:
            given = np.asarray(w)
        except (TypeError, ValueError):  # ragged and the like
            given = None
        if (given is None or not is_real_dtype(given.dtype) or given.shape != (len(x),)
                or not np.all(np.isfinite(given)) or np.any(given < 0) or not np.sum(given) > 0):
            raise InvalidInputError(f"w must be ({len(x)},) finite weights >= 0 of a positive sum, got {w!r:.80}")
    if w is None:
        mx, my = x.mean(axis=0), y.mean(axis=0)
        u, _, vt = np.linalg.svd((x - mx).T @ (y - my))
    else:
        w = np.asarray(w, dtype=np.float64) / np.sum(w)
        mx, my = w @ x, w @ y
        u, _, vt = np.linalg.svd((x - mx).T @ ((y - my) * w[:, None]))
    d = np.sign(np.linalg.det(vt.T @ u.T)) or 1.0
    r = vt.T @ np.diag([1.0, 1.0, d]) @ u.T
    return r, my - r @ mx


def check_core_weight(weight):
    """Raise InvalidInputError unless ``weight`` is one of :data:`CORE_WEIGHTS`."""
    if weight not in CORE_WEIGHTS:
        raise InvalidInputError(f"unknown core weight {weight!r}; choose one of {', '.join(CORE_WEIGHTS)}")


def vertex_weights(meshes, weight="vertices"):
    """(n,) float: each shared vertex's share of the body, summing to 1.

    ``"vertices"``: 1/n each. ``"area"``: a third of the area of the faces around the vertex,
    averaged over the meshes (each with its own faces): the share of the surface the vertex
    stands for, the same for a region whatever its meshing density. A vertex in no face weighs 0.

    meshes : sequence of Trimesh (or (n, 3) arrays for ``"vertices"``) with the same n
    """
    check_core_weight(weight)
    meshes = _mesh_list(meshes, "vertex_weights")
    n = len(np.asarray(getattr(meshes[0], "vertices", meshes[0])))
    if weight == "vertices":
        return np.full(n, 1.0 / n)
    total = np.zeros(n)
    for m in meshes:
        faces = getattr(m, "faces", None)
        if faces is None or len(faces) == 0:
            raise InvalidInputError("core weight 'area' needs meshes with faces (got a point set); use 'vertices'")
        v = np.asarray(m.vertices, dtype=np.float64)
        f = np.asarray(faces, dtype=np.int64)
        area = 0.5 * np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), axis=1)
        np.add.at(total, f.ravel(), np.repeat(area / 3.0, 3))
    if not total.sum() > 0:
        raise InvalidInputError("core weight 'area' needs meshes with a surface area; use 'vertices'")
    return total / total.sum()


def _mesh_list(meshes, what: str) -> list:
    """``meshes`` as a non-empty list (a string, a dict or a mesh in its place refused by name)."""
    if isinstance(meshes, (str, bytes, dict)) or hasattr(meshes, "vertices") or not hasattr(meshes, "__iter__"):
        raise InvalidInputError(f"{what} needs a list of meshes, got {type(meshes).__name__}")
    meshes = list(meshes)
    if len(meshes) == 0:
        raise InvalidInputError(f"{what} needs at least one mesh")
    return meshes


def _named(meshes, i: int) -> str:
    """'mesh i' and its file's name where it was read from one (``metadata["file_name"]``)."""
    name = getattr(meshes[i], "metadata", {}).get("file_name")
    return f"mesh {i} ({name})" if name else f"mesh {i}"


def align_classes(classes: dict, weight: str = "vertices") -> dict:
    """:func:`align_core` on each class of ``{name: meshes}``; an error names the class.

    >>> aligned = align_classes({"dog": dogs, "horse": horses}, weight="area")  # doctest: +SKIP
    """
    if not isinstance(classes, dict):  # (a list of meshes: 'list' object has no attribute 'items')
        raise InvalidInputError(f"classes must be a dict {{class name: [meshes]}}, got {type(classes).__name__}"
                                + (": pass {'name': [...]}" if isinstance(classes, (list, tuple)) else ""))
    out = {}
    for name, meshes in classes.items():
        try:
            out[name] = align_core(meshes, weight=weight)
        except InvalidInputError as e:
            raise InvalidInputError(f"class {name!r}: {e}") from None
    return out


def align_core(meshes, keep: float = 0.3, iterations: int = 5, weight: str = "vertices"):
    """Rigidly align meshes sharing a vertex order onto the first one, on their stable part.

    Each mesh is Kabsch-aligned (rotation + translation, no scale) to the first on all vertices;
    then, ``iterations`` times, the vertices closest to the class's mean aligned shape (smallest
    RMS residual over the meshes) are kept until they hold the ``keep`` share of the body, and
    every mesh is re-aligned on those only. A vertex's share and its weight in the Kabsch fit are
    :func:`vertex_weights`: with ``weight="vertices"`` every vertex counts one (the stable part is
    a share of the vertices, so a densely meshed region counts more); with ``"area"`` a vertex
    stands for its share of the surface (the stable part is a share of the surface, the same
    whatever the meshing). The first mesh is returned unchanged; the 4x4 transform applied to
    each mesh is in ``metadata["core_transform"]``.

    meshes : sequence of Trimesh (or (n, 3) arrays, ``weight="vertices"`` only) with the same n
    Returns list of Trimesh (new objects, ``process=False``)

    >>> aligned = align_core(meshes, weight="area")  # doctest: +SKIP
    """
    import trimesh

    meshes = _mesh_list(meshes, "align_core")
    if not 0.0 < check_real(keep, "keep", 0.0, strict=True) <= 1.0:  # a string, None: by name, not '<'s TypeError
        raise InvalidInputError(f"keep must be in (0, 1], got {keep}")
    iterations = check_int(iterations, "iterations", 0)
    vs = []
    for i, m in enumerate(meshes):
        try:
            vs.append(np.asarray(getattr(m, "vertices", m), dtype=np.float64))
        except (TypeError, ValueError):  # a path, a ragged list: float()'s error
            raise InvalidInputError(f"align_core needs meshes or (n, 3) arrays, got {m!r:.60} for mesh {i}") from None
    if vs[0].ndim != 2 or vs[0].shape[1] != 3:
        raise InvalidInputError(f"align_core needs (n, 3) vertices, got shape {vs[0].shape} for {_named(meshes, 0)}")
    for i, v in enumerate(vs):
        if v.shape != vs[0].shape:  # the one that differs, by file name where it was read from one
            raise InvalidInputError(
                f"align_core needs meshes with the same vertex count (one vertex order), got shape {v.shape} "
                f"for {_named(meshes, i)} and {vs[0].shape} for {_named(meshes, 0)}")
    w = vertex_weights(meshes, weight)
    n = len(vs[0])
    target, subset = vs[0], np.flatnonzero(w > 0)
    transforms = [(np.eye(3), np.zeros(3))] * len(vs)
    for _ in range(int(iterations) + 1):  # the first pass uses every vertex
        transforms = [kabsch(v[subset], target[subset], None if weight == "vertices" else w[subset]) for v in vs]
        aligned = np.stack([v @ r.T + t for v, (r, t) in zip(vs, transforms)])
        residual = np.sqrt(np.mean(np.sum((aligned - aligned.mean(axis=0)) ** 2, axis=2), axis=0))
        order = np.argsort(residual, kind="stable")
        if weight == "vertices":
            count = int(np.ceil(keep * n))
        else:  # the most stable vertices that hold the keep share of the surface
            order = order[w[order] > 0]
            count = int(np.searchsorted(np.cumsum(w[order]), keep * (1 - 1e-12))) + 1
        subset = order[: max(3, count)]
    out = []
    for k, (m, v, (r, t)) in enumerate(zip(meshes, vs, transforms)):
        if k == 0:
            r, t = np.eye(3), np.zeros(3)
        matrix = np.eye(4)
        matrix[:3, :3], matrix[:3, 3] = r, t
        faces = getattr(m, "faces", None)
        new = trimesh.Trimesh(v @ r.T + t, faces if faces is not None else np.zeros((0, 3), int), process=False)
        new.metadata.update(getattr(m, "metadata", {}))
        new.metadata["core_transform"] = matrix
        out.append(new)
    return out
