"""Rigid-core alignment of a class of meshes that share their vertex order (registrations)."""
from __future__ import annotations

import numpy as np

from .._validate import InvalidInputError

__all__ = ["align_core", "kabsch"]

def kabsch(x, y):
    """Rotation r (3, 3) and translation t (3,) minimising sum |r x_i + t - y_i|^2."""
    mx, my = x.mean(axis=0), y.mean(axis=0)
    u, _, vt = np.linalg.svd((x - mx).T @ (y - my))
    d = np.sign(np.linalg.det(vt.T @ u.T)) or 1.0
    r = vt.T @ np.diag([1.0, 1.0, d]) @ u.T
    return r, my - r @ mx


def align_core(meshes, keep: float = 0.3, iterations: int = 5):
    """Rigidly align meshes sharing a vertex order onto the first one, on their stable part.

    Each mesh is Kabsch-aligned (rotation + translation, no scale) to the first on all vertices;
    then, ``iterations`` times, the ``keep`` fraction of vertices closest to the class's mean
    aligned shape (smallest RMS residual over the meshes) is kept and every mesh re-aligned on
    those only. The first mesh is returned unchanged; the 4x4 transform applied to each mesh is
    in ``metadata["core_transform"]``.

    meshes : sequence of Trimesh (or (n, 3) arrays) with the same n
    Returns list of Trimesh (new objects, ``process=False``)
    """
    import trimesh

    meshes = list(meshes)
    if len(meshes) == 0:
        raise InvalidInputError("align_core needs at least one mesh")
    if not 0.0 < keep <= 1.0:
        raise InvalidInputError(f"keep must be in (0, 1], got {keep}")
    if int(iterations) != iterations or iterations < 0:
        raise InvalidInputError(f"iterations must be an integer >= 0, got {iterations}")
    vs = [np.asarray(getattr(m, "vertices", m), dtype=np.float64) for m in meshes]
    counts = {v.shape for v in vs}
    if len(counts) != 1 or vs[0].ndim != 2 or vs[0].shape[1] != 3:
        raise InvalidInputError(f"align_core needs meshes with the same vertex count, got shapes {sorted(counts)}")
    n = len(vs[0])
    target, subset = vs[0], np.arange(n)
    transforms = [(np.eye(3), np.zeros(3))] * len(vs)
    for _ in range(int(iterations) + 1):  # the first pass uses every vertex
        transforms = [kabsch(v[subset], target[subset]) for v in vs]
        aligned = np.stack([v @ r.T + t for v, (r, t) in zip(vs, transforms)])
        residual = np.sqrt(np.mean(np.sum((aligned - aligned.mean(axis=0)) ** 2, axis=2), axis=0))
        subset = np.argsort(residual, kind="stable")[: max(3, int(np.ceil(keep * n)))]
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
