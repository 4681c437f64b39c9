"""The head and the trunk of a solid: the two thick parts that meet at its narrowest neck.

The depth field D of a voxel solid (:class:`jaxpose.occupancy.solid.Solid`: distance to the outside) has a
local maximum in every thick part of a body. The merge tree of its superlevel sets {D > t}
(:func:`merge_tree`: 26-connected voxels taken in decreasing depth, union-find) gives each maximum
its birth (its depth) and its death (the depth of the saddle where its component joins that of a
deeper maximum). A neck is a saddle much thinner than the part it carries: :func:`find_parts`
takes the maximum with the largest birth / death among those at least :data:`THICK` times as
deep as the deepest (hands and feet are thinner; a waist between chest and pelvis, or a knee,
joins parts of nearly its own depth) and at least :data:`NECK` times as deep as its saddle. The
two components of {D > death} that meet there are the head and the trunk; the smaller one is the
head (a child's head is as deep as its trunk). How it does on real bodies: docs/rotation.md.

Example::

    sol = jaxpose.occupancy.solid.robust_solid(vertices, faces)
    parts = find_parts(sol)            # None when no saddle joins two thick parts
    parts.head, parts.neck, parts.constriction
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy import ndimage

__all__ = ["THICK", "NECK", "Parts", "merge_tree", "find_parts"]

THICK = 0.5  # a head is at least half as deep as the deepest part of the body (its trunk)
NECK = 1.1  # a neck is at least 10 % thinner than the shallower of the two parts it joins
_NEIGHBOURS = np.array([(a, b, c) for a in (-1, 0, 1) for b in (-1, 0, 1) for c in (-1, 0, 1) if (a, b, c) != (0, 0, 0)])


class Parts(NamedTuple):
    """The head and the trunk of a solid, on its grid.

    Attributes:
      head, trunk: (nx, ny, nz) bool, the two components of {D > neck depth} that meet at the neck.
      neck: (3,) the saddle voxel's center, in the grid's frame (``solid.origin + pitch (i + 0.5)``).
      head_depth: depth of the head's deepest voxel (units); neck_depth: the saddle's depth.
      constriction: birth / death of the shallower of the two maxima the neck joins (>= 1).
      runner_up: the largest birth / death of any other thick maximum (1 when there is none).
    """

    head: np.ndarray
    trunk: np.ndarray
    neck: np.ndarray
    head_depth: float
    neck_depth: float
    constriction: float
    runner_up: float


def merge_tree(inside, depth):
    """The merge tree of the superlevel sets of ``depth`` on the ``inside`` voxels (26-connected).

    Args:
      inside: (nx, ny, nz) bool; depth: (nx, ny, nz) float (only ``inside`` voxels are read).

    Returns:
      (m, 5) float64 rows (birth, death, peak, saddle, joins), one per local maximum, most
      persistent (birth - death) first: birth its depth, death the depth at which it joins a deeper
      maximum (0 for the deepest), and as flat voxel indices its peak, the saddle and the peak of
      the component it joins (-1 for the deepest). Empty (0, 5) for an empty solid.
    """
    inside = np.pad(np.asarray(inside, bool), 1)  # a border of outside voxels: no bounds checks
    shape = inside.shape
    d = np.where(inside, np.pad(np.asarray(depth, np.float64), 1), -np.inf).ravel()
    flat = np.flatnonzero(inside.ravel())
    if flat.size == 0:
        return np.zeros((0, 5))
    order = flat[np.argsort(-d[flat], kind="stable")].tolist()
    offsets = (_NEIGHBOURS @ np.array([shape[1] * shape[2], shape[2], 1])).tolist()
    parent = [-1] * d.size  # plain lists: this loop runs once per voxel
    depth_of = d.tolist()
    peak = {}

    def find(x):
        root = x
        while parent[root] != root:
            root = parent[root]
        while parent[x] != root:
            parent[x], x = root, parent[x]
        return root

    rows = []
    for v in order:
        roots = {find(v + o) for o in offsets if parent[v + o] >= 0}
        parent[v] = v
        if not roots:
            peak[v] = v
            continue
        roots = sorted(roots, key=lambda r: -depth_of[peak[r]])
        for r in roots[1:]:  # the shallower maxima die here
            rows.append((depth_of[peak[r]], depth_of[v], peak[r], v, peak[roots[0]]))
            parent[r] = roots[0]
        parent[v] = roots[0]
    top = find(order[0])
    rows.append((depth_of[peak[top]], 0.0, peak[top], -1, -1))
    rows = np.array(rows, np.float64)
    for col in (2, 3, 4):  # flat indices of the padded grid -> of the input grid
        ok = rows[:, col] >= 0
        idx = np.array(np.unravel_index(rows[ok, col].astype(np.int64), shape)) - 1
        rows[ok, col] = np.ravel_multi_index(idx, tuple(n - 2 for n in shape))
    return rows[np.argsort(-(rows[:, 0] - rows[:, 1]), kind="stable")]


def find_parts(sol, thick=THICK):
    """The head, trunk and neck of a solid (module docs), or None when no saddle joins two parts
    at least ``thick`` times as deep as the deepest with a saddle at least :data:`NECK` times
    thinner than the shallower of them (a ball, a box, a capsule: nothing to call a head; voxels
    of nearly equal depth that meet on a plateau are no neck).

    Args:
      sol: :class:`jaxpose.occupancy.solid.Solid` (``inside``, ``depth``, ``origin``, ``pitch``).

    Returns:
      :class:`Parts` in the grid's frame, or None.
    """
    tree = merge_tree(sol.inside, sol.depth)
    if len(tree) < 2:
        return None
    thick_joins = tree[(tree[:, 1] > 0) & (tree[:, 0] >= NECK * tree[:, 1]) & (tree[:, 0] >= thick * tree[:, 0].max())]
    if len(thick_joins) == 0:
        return None
    ratio = thick_joins[:, 0] / thick_joins[:, 1]
    best = int(np.argmax(ratio))
    birth, death, peak, saddle, joins = thick_joins[best]
    runner_up = float(np.max(np.delete(ratio, best))) if len(ratio) > 1 else 1.0
    labels, _ = ndimage.label(sol.depth > death, structure=np.ones((3, 3, 3), bool))
    labels = labels.ravel()
    a, b = labels == labels[int(joins)], labels == labels[int(peak)]
    head, trunk = (b, a) if b.sum() <= a.sum() else (a, b)
    head_depth = float(birth) if head is b else float(sol.depth.ravel()[int(joins)])
    neck = np.asarray(sol.origin, np.float64) + sol.pitch * (np.array(np.unravel_index(int(saddle), sol.inside.shape)) + 0.5)
    shape = sol.inside.shape
    return Parts(head.reshape(shape), trunk.reshape(shape), neck, head_depth, float(death), float(ratio[best]),
                 runner_up)
