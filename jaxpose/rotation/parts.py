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
head (a child's head is as deep as its trunk).

:func:`find_head` asks, besides, that the head end the body. An animal's head is thinner than
half its trunk and its neck no more constricted than its waist, so the most constricted thick
saddle may cut off its rump (its legs and tail beyond). A head does not branch: cut off across its
saddle (:func:`part_across`), the geodesic distance from the saddle has one far end in it
(:func:`ends`), where a rump has legs and a tail, a chest arms; and it is a small end, at most
:data:`SHARE` of the solid (the dev bodies' heads: 4-20 %; a dog's rump 27-29 %, a horse's half
trunk 31-35 %). :func:`find_parts`' head, beyond a strongly constricted neck, is allowed a second
end (a hand resting on it). And a neck is thin against the trunk, not only against the head: the
body's deepest part is at least :data:`TRUNK` times as deep as it (:func:`waist`). A saddle
deeper than that is a waist between two halves of a trunk (a chest and a pelvis, a chest and a
rump; on a point solid, whose closing fills in the flanks between the legs, also a rump that
ends in one blob), whatever it carries. Where :func:`find_parts`' head lies beyond a waist, is
cut off and branches, or where it finds none, the head is the thickest part beyond any saddle
(at least :data:`SADDLE` times as deep as it, and no waist) that is cut off and ends the body
(:func:`terminal_part`). The allowance of a second end is the distinct neck's: where find_parts'
neck is hardly more constricted than the runner-up (their relative gap below
:data:`jaxpose.orientation.GAP_MIN`, which the frame's ambiguity already calls undetermined), its
part must end the body as any other (one far end: a rump a hole took the tail from has two). A
part that no disk at its saddle cuts off may be cut where its neck is narrowest, beyond the saddle
toward its peak (:func:`_terminal`'s ``slide``: a notch beside the neck filled by a hole's cap
widens the section through the saddle). How it does on real bodies: docs/rotation.md.

Example::

    sol = jaxpose.rotation.core.frame_solid(vertices, faces)
    parts = find_parts(sol)            # None when no saddle joins two thick parts
    parts.head, parts.neck, parts.constriction
    head = find_head(sol)              # the same where that head ends the body; else a part that does
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy import ndimage, sparse
from scipy.sparse import csgraph

from .._validate import InvalidInputError, check_real
from ..occupancy import solid
from ..orientation import GAP_MIN

__all__ = ["THICK", "NECK", "TRUNK", "SADDLE", "DISK", "WIDER", "BRANCH", "SHARE", "LOWEST", "Parts", "merge_tree", "find_parts", "find_head",
           "part_across", "geodesic", "ends", "waist", "terminal_part", "check_solid"]

THICK = 0.5  # a head is at least half as deep as the deepest part of the body (its trunk)
NECK = 1.1  # a neck is at least 10 % thinner than the shallower of the two parts it joins
TRUNK = 1.5  # find_head: a neck is thin against the trunk too: the deepest part at least this many times its depth
SADDLE = 1.05  # find_head: a part beyond a saddle at least 5 % thinner than the part
DISK = 3.0  # a part is cut off across its saddle by a disk of this many saddle depths in radius
WIDER = 4.0  # terminal_part: where DISK leaves a part joined, a disk this wide (an oblique neck) is tried
BRANCH = 2.0  # a part ends the body when no two of its far ends stand apart by this many part depths
SHARE = 0.25  # a head holds at most this share of the solid beyond its saddle (a rump, a half trunk: more)
LOWEST = 0.1  # find_head: parts thinner than this share of the deepest are not heads (fingers, toes)
_CUBE = np.ones((3, 3, 3), bool)
_NEIGHBOURS = np.array([(a, b, c) for a in (-1, 0, 1) for b in (-1, 0, 1) for c in (-1, 0, 1) if (a, b, c) != (0, 0, 0)])


class Parts(NamedTuple):
    """The head and the trunk of a solid, on its grid.

    Attributes:
      head, trunk: (nx, ny, nz) bool, the two components of {D > neck depth} that meet at the neck.
      neck: (3,) the saddle voxel's center, in the grid's frame (``solid.origin + pitch (i + 0.5)``).
      head_depth: depth of the head's deepest voxel (units); neck_depth: the saddle's depth.
      constriction: birth / death of the shallower of the two maxima the neck joins (>= 1).
      runner_up: the largest birth / death of any other thick maximum (1 when there is none; 0
        for a head found only as the thickest part that ends the body, :func:`terminal_part`).
      terminal: True where the head was found to end the body (:func:`find_head`: cut off across its
        saddle and not branching), False where that was not checked or could not be told.
      beyond: (nx, ny, nz) bool, the part beyond the neck as cut off there (:func:`part_across`),
        where ``terminal``; else None.
    """

    head: np.ndarray
    trunk: np.ndarray
    neck: np.ndarray
    head_depth: float
    neck_depth: float
    constriction: float
    runner_up: float
    terminal: bool = False
    beyond: np.ndarray | None = None

    @property
    def neck_gap(self) -> float:
        """How distinct the neck is: (constriction - runner_up) / constriction, in [0, 1]."""
        return (self.constriction - self.runner_up) / self.constriction

    @property
    def end_only(self) -> bool:
        """True where the head was found only as the thickest part that ends the body
        (:func:`terminal_part`: no thick neck vouches for it; ``runner_up`` 0)."""
        return self.runner_up == 0.0


def merge_tree(inside, depth):
    """The merge tree of the superlevel sets of ``depth`` on the ``inside`` voxels (26-connected).

    The voxels enter one by one in decreasing depth (equal depths in flat-index order); a voxel
    with no neighbour in yet is born as a maximum, one whose neighbours in yet lie in two or more
    components joins them: the component of the deepest peak lives on, the others die there. Peaks
    tied in depth rank in the iteration order of a Python set of the peaks' flat indices (in the
    grid padded by one voxel) filled in neighbour order (offsets a, b, c in -1, 0, 1, row-major).

    Args:
      inside: (nx, ny, nz) bool; depth: (nx, ny, nz) float (only ``inside`` voxels are read);
        another shape, or two shapes: InvalidInputError (NumPy's broadcast error).

    Returns:
      (m, 5) float64 rows (birth, death, peak, saddle, joins), one per local maximum, most
      persistent (birth - death) first: birth its depth, death the depth at which it joins a deeper
      maximum (0 for the deepest), and as flat voxel indices its peak, the saddle and the peak of
      the component it joins (-1 for the deepest). Maxima of other connected components than the
      deepest voxel's that never join it have no row. Empty (0, 5) for an empty solid.

    Example::

        tree = merge_tree(sol.inside, sol.depth)
        birth, death, peak, saddle, joins = tree[1]   # the most persistent maximum but the deepest
    """
    if np.ndim(inside) != 3 or np.shape(depth) != np.shape(inside):
        raise InvalidInputError(f"inside and depth must be one 3-D grid (nx, ny, nz), got shapes {np.shape(inside)} and "
                                f"{np.shape(depth)}")
    inside = np.pad(np.asarray(inside, bool), 1)  # a border of outside voxels: no bounds checks
    shape = inside.shape
    d = np.where(inside, np.pad(np.asarray(depth, np.float64), 1), -np.inf).ravel()
    flat = np.flatnonzero(inside.ravel())
    n = flat.size
    if n == 0:
        return np.zeros((0, 5))
    order = flat[np.argsort(-d[flat], kind="stable")]  # the voxels by the rank at which they enter
    rank = np.full(d.size, -1, np.int64)
    rank[order] = np.arange(n)
    offsets = _NEIGHBOURS @ np.array([shape[1] * shape[2], shape[2], 1])
    around = rank[order[:, None] + offsets]  # (n, 26) the neighbours' ranks, in offset order (-1: outside)
    # Kruskal on the 26-neighbour pairs, each weighted by the rank at which its later voxel enters
    # (row: the later voxel, so that the weights come sorted): a voxel's edges in the spanning
    # forest are the components it joins (0: a maximum is born; 1: a component grows; 2 or more:
    # a saddle, where all but one die)
    earlier = (around >= 0) & (around < np.arange(n)[:, None])
    count = earlier.sum(axis=1)
    pairs = sparse.csr_matrix((np.repeat(np.arange(1.0, n + 1), count), around[earlier], np.concatenate([[0], np.cumsum(count)])),
                              shape=(n, n))
    forest = csgraph.minimum_spanning_tree(pairs).tocoo()  # row: the later voxel
    joins = np.bincount(forest.row, minlength=n)
    grow = joins[forest.row] == 1
    # segments: a maximum or a saddle and the voxels that grow from it; union-find on segments,
    # in the order of the saddles, each component's label that of its peak's segment
    _, seg = csgraph.connected_components(
        sparse.csr_matrix((np.ones(grow.sum()), (forest.row[grow], forest.col[grow])), shape=(n, n)), directed=False)
    head = order[np.unique(seg, return_index=True)[1]].tolist()  # each segment's first voxel
    parent = list(range(len(head)))

    def find(x):
        root = x
        while parent[root] != root:
            root = parent[root]
        while parent[x] != root:
            parent[x], x = root, parent[x]
        return root

    saddles = np.flatnonzero(joins >= 2)
    seg_of = seg.tolist()
    rows = []
    for s, near in zip(saddles.tolist(), around[saddles].tolist()):
        v = int(order[s])
        roots = {head[find(seg_of[r])] for r in near if 0 <= r < s}  # the peaks of the components met
        roots = sorted(roots, key=lambda r: -d[r])
        keep = seg_of[rank[roots[0]]]
        for r in roots[1:]:  # the shallower maxima die here
            rows.append((d[r], d[v], r, v, roots[0]))
            parent[seg_of[rank[r]]] = keep
        parent[seg_of[s]] = keep
    top = head[find(seg_of[0])]
    rows.append((d[top], 0.0, top, -1, -1))
    rows = np.array(rows, np.float64)
    for col in (2, 3, 4):  # flat indices of the padded grid -> of the input grid
        ok = rows[:, col] >= 0
        idx = np.array(np.unravel_index(rows[ok, col].astype(np.int64), shape)) - 1
        rows[ok, col] = np.ravel_multi_index(idx, tuple(k - 2 for k in shape))
    return rows[np.argsort(-(rows[:, 0] - rows[:, 1]), kind="stable")]


def check_solid(sol):
    """:func:`jaxpose.occupancy.solid.check_solid` with its depth: a :class:`Solid` the parts and
    frames can read (InvalidInputError otherwise)."""
    solid.check_solid(sol, depth=True)


def find_parts(sol, thick=THICK, tree=None):
    """The head, trunk and neck of a solid (module docs), or None when no saddle joins two parts
    at least ``thick`` times as deep as the deepest with a saddle at least :data:`NECK` times
    thinner than the shallower of them (a ball, a box, a capsule: nothing to call a head; voxels
    of nearly equal depth that meet on a plateau are no neck).

    Args:
      sol: :class:`jaxpose.occupancy.solid.Solid` (``inside``, ``depth``, ``origin``, ``pitch``).
      thick: the share of the deepest a head needs; tree: the solid's :func:`merge_tree` to reuse.

    Returns:
      :class:`Parts` in the grid's frame, or None.
    """
    check_solid(sol)
    return _find_parts(sol, thick, tree, _Levels(sol))


def _find_parts(sol, thick, tree, levels):
    """:func:`find_parts` with the solid's :class:`_Levels` (shared with the caller's other readers)."""
    tree = merge_tree(sol.inside, sol.depth) if tree is None else tree
    if len(tree) < 2:
        return None
    thick_joins = tree[(tree[:, 1] > 0) & (tree[:, 0] >= NECK * tree[:, 1]) & (tree[:, 0] >= thick * tree[:, 0].max())]
    if len(thick_joins) == 0:
        return None
    ratio = thick_joins[:, 0] / thick_joins[:, 1]
    best = int(np.argmax(ratio))
    birth, death, peak, saddle, joins = thick_joins[best]
    runner_up = float(np.max(np.delete(ratio, best))) if len(ratio) > 1 else 1.0
    return _split(sol, thick_joins[best], None, runner_up, levels=levels)


class _Levels:
    """The 26-connected components of a solid's superlevel sets {depth > t}, labelled: ``levels(t)``
    gives (nx * ny * nz,) int labels (flat; 0 outside the set). The last level asked for is kept, so
    that a saddle's level is labelled once for its several readers (its sides' sizes, the part beyond
    it, its split), and the same labels are read as from ``ndimage.label`` each time."""

    def __init__(self, sol):
        self.depth, self.t, self.labels = sol.depth, None, None

    def __call__(self, t):
        t = float(t)
        if t != self.t:
            self.t, self.labels = t, ndimage.label(self.depth > t, structure=_CUBE)[0].ravel()
        return self.labels


def _split(sol, row, head_peak, runner_up, beyond=None, levels=None):
    """:class:`Parts` at one merge-tree row's saddle: the head the smaller side (``head_peak`` None)
    or the side of that peak (a flat index: the row's peak or the one it joins); ``levels``: the
    solid's :class:`_Levels` to reuse."""
    birth, death, peak, saddle, joins = row
    labels = (_Levels(sol) if levels is None else levels)(death)
    a, b = labels == labels[int(joins)], labels == labels[int(peak)]
    if head_peak is None:
        head_peak = peak if b.sum() <= a.sum() else joins
    head, trunk = (b, a) if head_peak == peak else (a, b)
    neck = np.asarray(sol.origin, np.float64) + sol.pitch * (_index(sol, saddle) + 0.5)
    shape = sol.inside.shape
    return Parts(head.reshape(shape), trunk.reshape(shape), neck, float(sol.depth.ravel()[int(head_peak)]),
                 float(death), float(birth / death), runner_up, beyond is not None, beyond)


def _index(sol, flat):
    return np.array(np.unravel_index(int(flat), sol.inside.shape))


def part_across(sol, blob, saddle, depth, other=None, disk=DISK, thin=0.0, shift=0.0):
    """The part beyond a saddle, cut off by a disk, or None where the disk does not cut it off.

    The disk lies through ``saddle`` ((3,) voxel index) normal to the direction from it to the
    centroid of ``blob`` ((nx, ny, nz) bool, the part's thick core), ``disk`` times ``depth`` (the
    saddle's depth, units) in radius and two voxels thick, so that no 26-connected path crosses it.

    Returns:
      (nx, ny, nz) bool, the component holding ``blob`` of the solid less the disk; None where it
      holds the voxel ``other`` ((3,) index: the maximum on the saddle's other side; None: not
      checked) too: the part is joined to the rest beyond the disk (a head resting on the knees, a
      limb on the trunk).

    With ``thin`` > 0 (units) the solid is cut without its voxels at most that deep (``blob`` is
    always kept), and each of them then goes with the part of its nearest deeper voxel: a point
    solid's closing bridges gaps between parts up to about its closing radius wide (a muzzle
    over a foreleg, a tail on a thigh) that the input does not join (:func:`terminal_part`).

    With ``shift`` > 0 (voxels) the disk lies that far beyond the saddle toward the blob's
    centroid, ``disk`` times the depth at its center (at least ``depth``) in radius, and only the
    blob's voxels beyond it are kept (:func:`_terminal`: a neck cut where it is narrowest); None
    also where no voxel of the blob lies beyond it.
    """
    idx = np.argwhere(sol.inside)
    u = np.argwhere(blob).mean(axis=0) - saddle
    u /= np.linalg.norm(u)
    center = saddle + shift * u
    if shift > 0.0:
        inner = np.clip(np.rint(center).astype(np.int64), 0, np.array(sol.inside.shape) - 1)
        depth = max(float(depth), float(sol.depth[tuple(inner)]))
    rel = idx - center
    h = rel @ u
    cut = (np.abs(h) <= 1.0) & (np.linalg.norm(rel - h[:, None] * u, axis=1) * sol.pitch <= disk * depth)
    keep = np.zeros(sol.inside.shape, bool)
    keep[tuple(idx[~cut].T)] = True
    if shift > 0.0:
        cells = np.argwhere(blob & keep)
        seed = np.zeros(blob.shape, bool)
        seed[tuple(cells[(cells - center) @ u > 1.0].T)] = True  # the blob beyond the disk
        if not seed.any():
            return None
    else:
        keep |= blob
        seed = blob
    deep = keep & ((sol.depth > thin) | seed)  # the solid without its bridges
    labels, _ = ndimage.label(deep, _CUBE)
    first = np.argwhere(seed)[np.argmax(sol.depth[seed])] if shift > 0.0 else np.argwhere(seed)[0]  # shifted: the deepest
    part = labels == labels[tuple(first)]
    if other is not None and part[tuple(other)]:
        return None
    if thin > 0.0:  # each shallow voxel goes with its nearest deep voxel
        part = keep & part[tuple(ndimage.distance_transform_edt(~deep, return_distances=False, return_indices=True))]
    return part


def geodesic(mask, source, pitch):
    """(nx, ny, nz) float: the length (units) of the shortest 26-connected path inside ``mask``
    from the voxel ``source`` ((3,) index) to each voxel (inf where none; 0 outside the mask)."""
    vox = np.argwhere(mask)
    index = -np.ones(mask.shape, np.int64)
    index[tuple(vox.T)] = np.arange(len(vox))
    padded = np.pad(index, 1, constant_values=-1)
    rows, cols, lengths = [], [], []
    for step in _NEIGHBOURS[:13]:  # each of the 26 neighbours once, up to sign
        other = padded[tuple((vox + 1 + step).T)]
        ok = other >= 0
        rows.append(np.flatnonzero(ok))
        cols.append(other[ok])
        lengths.append(np.full(ok.sum(), np.linalg.norm(step) * pitch))
    graph = sparse.coo_matrix((np.concatenate(lengths), (np.concatenate(rows), np.concatenate(cols))),
                              shape=(len(vox), len(vox))).tocsr()
    out = np.zeros(mask.shape)
    out[tuple(vox.T)] = csgraph.dijkstra(graph, directed=False, indices=int(index[tuple(source)]))
    return out


def ends(sol, part, saddle, depth, scale=BRANCH):
    """How many far ends a part has at the scale of its depth.

    The maxima of the geodesic distance g from the saddle (the part's voxel nearest ``saddle``,
    (3,) voxel index) inside ``part``: a part's tips. Each maximum's persistence (birth - death in
    the :func:`merge_tree` of g's superlevel sets: how far the tip stands out beyond where its
    branch joins a farther one) against ``scale`` times ``depth`` (the part's depth, units): a
    bump of the surface does not count, a limb or a tail does; the farthest end counts where it
    lies that far from the saddle. 0 or 1: the part does not branch (a head, a hand without
    fingers at that scale); 2 or more: it does (a rump with its legs and tail, a chest with arms).
    """
    vox = np.argwhere(part)
    g = geodesic(part, vox[np.argmin(np.linalg.norm(vox - saddle, axis=1))], sol.pitch)
    reach = part & np.isfinite(g)
    tree = merge_tree(reach, np.where(reach, g + sol.pitch, 0.0))
    return int(np.sum(tree[:, 0] - tree[:, 1] >= scale * depth))


def waist(death, top, trunk=TRUNK):
    """Whether a saddle ``death`` deep (units) on a body whose deepest part is ``top`` deep is a
    waist, not a neck: deeper than ``top / trunk``. A neck carries a head on a trunk at least
    ``trunk`` times as deep as the neck (a child's head is as deep as its trunk, but its neck is
    thin); a waist joins two parts of a trunk of nearly its depth.

    Example::

        waist(0.36, 0.45)   # True: 0.45 < 1.5 x 0.36, a waist between a chest and a rump
        waist(0.25, 0.45)   # False: a neck

    ``death``, ``top``: numbers >= 0 (depths), ``trunk`` > 0; InvalidInputError otherwise (float()'s
    TypeError for an array).
    """
    return check_real(death, "death", 0) * check_real(trunk, "trunk", 0, strict=True) > check_real(top, "top", 0)


def _terminal(sol, row, head_peak, disks=(DISK,), most=1, thin=0.0, slide=False, levels=None):
    """Whether the side of ``head_peak`` at one merge-tree row's saddle is a head that ends the
    body: (True, the part) where it is cut off (:func:`part_across`, by the first of ``disks`` that
    cuts it off), holds at most :data:`SHARE` of the solid and has at most ``most`` far ends
    (:func:`ends`); (False, None) where it is cut off and is larger or branches more; (None, None)
    where it cannot be cut off. With ``slide``, on a mesh solid (``sol.radius`` None), where no disk at the
    saddle cuts the part off, a disk of :data:`DISK` local depths is tried one voxel after another
    beyond the saddle toward the part's peak (up to a voxel short of it): a neck is cut where it
    is narrowest, which a filled notch beside it (a hole's cap across a throat and a jaw) moves
    beyond the saddle of the depth field. ``levels``: the solid's :class:`_Levels` to reuse."""
    birth, death, peak, saddle, joins = row
    labels = (_Levels(sol) if levels is None else levels)(death)
    blob = (labels == labels[int(head_peak)]).reshape(sol.inside.shape)
    other = _index(sol, joins if head_peak == peak else peak)
    part = None
    for disk in disks:
        part = part_across(sol, blob, _index(sol, saddle), death, other, disk, thin)
        if part is not None:
            break
    if part is None and slide and sol.radius is None:  # a mesh solid
        at = _index(sol, saddle)
        u = np.argwhere(blob).mean(axis=0) - at
        span = float((_index(sol, head_peak) - at) @ u / max(float(np.linalg.norm(u)), 1e-12))
        for shift in np.arange(1.0, span - 1.0 + 1e-9):
            part = part_across(sol, blob, at, death, other, DISK, shift=float(shift))
            if part is not None:
                break
    if part is None:
        return None, None
    if part.sum() > SHARE * sol.inside.sum():  # half a trunk (a rump, a chest with arms), not an end
        return False, None
    if ends(sol, part, _index(sol, saddle), float(sol.depth.ravel()[int(head_peak)])) > most:
        return False, None
    return True, part


def terminal_part(sol, tree=None):
    """The thickest part that ends the body: of the sides of the saddles of the depth field (each
    merge-tree row whose maximum is at least :data:`SADDLE` times as deep as its saddle and
    :data:`LOWEST` times as deep as the deepest; the side whose component at the saddle's depth
    is the smaller), those cut off across the saddle (by a disk of :data:`DISK` saddle depths, or
    of :data:`WIDER` where that leaves the part joined: a neck met at a slant) and not branching
    (:func:`_terminal`), the deepest; None where there is none. A saddle that is a :func:`waist`
    is no neck: the sides of its row are not taken. Where no disk at the saddle cuts a side off,
    on a mesh solid a disk slid beyond the saddle toward its peak may (:func:`_terminal`).
    (:func:`find_head` checks :func:`find_parts`' head beyond a distinct neck with :data:`DISK`
    only: a head it cannot cut off is kept.)

    Returns:
      :class:`Parts` (``constriction`` the saddle's row's birth / death; ``runner_up`` 0: no neck
      was compared;
      ``terminal`` True, ``beyond`` the part as cut off).
    """
    check_solid(sol)
    return _terminal_part(sol, tree, _Levels(sol))


def _terminal_part(sol, tree, levels):
    """:func:`terminal_part` with the solid's :class:`_Levels` (shared with the caller's other readers)."""
    tree = merge_tree(sol.inside, sol.depth) if tree is None else tree
    if len(tree) < 2:
        return None
    top = tree[:, 0].max()
    flat_depth = sol.depth.ravel()
    rows = []
    for row in tree:
        birth, death, peak, saddle, joins = row
        if death <= 0 or birth < SADDLE * death or birth < LOWEST * top or waist(death, top):
            continue
        rows.append(row)
    small = {}
    for i in sorted(range(len(rows)), key=lambda i: rows[i][1]):  # rows of one depth: their level labelled once
        birth, death, peak, saddle, joins = rows[i]
        labels = levels(death)
        small[i] = peak if np.sum(labels == labels[int(peak)]) <= np.sum(labels == labels[int(joins)]) else joins
    sides = [(flat_depth[int(small[i])], row, small[i]) for i, row in enumerate(rows)]
    thin = 0.0 if sol.radius is None else sol.radius * sol.pitch  # a point solid: without its closing's bridges
    for _, row, small in sorted(sides, key=lambda s: -s[0]):
        verdict, part = _terminal(sol, row, small, (DISK, WIDER), thin=thin, slide=True, levels=levels)
        if verdict:
            return _split(sol, row, small, 0.0, part, levels=levels)
    return None


def find_head(sol, tree=None):
    """The head of a body (module docs): :func:`find_parts`' head where its neck is no
    :func:`waist` and it ends the body (``terminal`` True) or cannot be cut off to tell
    (``terminal`` False); else (it lies beyond a waist, is half a trunk, more than :data:`SHARE`
    of the solid, or carries limbs: three or more far ends, a rump's two legs and tail; two are
    allowed it, a hand resting on a head, where its neck is distinct: (constriction - runner-up) /
    constriction at least :data:`jaxpose.orientation.GAP_MIN`; else one, and it may be cut off
    beyond its saddle as :func:`terminal_part`'s parts), or where there is no thick neck,
    :func:`terminal_part`.

    Args:
      sol: :class:`jaxpose.occupancy.solid.Solid`; tree: its :func:`merge_tree` to reuse.

    Returns:
      :class:`Parts` in the grid's frame, or None (no saddle beyond which a part ends the body:
      a ball, a box, a capsule).
    """
    check_solid(sol)
    tree = merge_tree(sol.inside, sol.depth) if tree is None else tree
    levels = _Levels(sol)
    found = _find_parts(sol, THICK, tree, levels)
    if found is not None and not waist(found.neck_depth, tree[:, 0].max()):
        thick = tree[(tree[:, 1] > 0) & (tree[:, 0] >= NECK * tree[:, 1]) & (tree[:, 0] >= THICK * tree[:, 0].max())]
        row = thick[np.argmax(thick[:, 0] / thick[:, 1])]
        head_peak = row[2] if found.head.ravel()[int(row[2])] else row[4]
        if found.neck_gap >= GAP_MIN:  # a distinct neck
            verdict, part = _terminal(sol, row, head_peak, most=2, levels=levels)  # a hand resting on the head: two ends
        else:  # a neck no more constricted than another saddle vouches for nothing: an end of the body
            verdict, part = _terminal(sol, row, head_peak, slide=True, levels=levels)
        if verdict is not False:
            return found._replace(terminal=bool(verdict), beyond=part)
    return _terminal_part(sol, tree, levels)
