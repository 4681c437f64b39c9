"""A robust voxel solid of a mesh (closed, open, with stray parts) or of a point cloud, and its depth.

The solid is the set of voxel centers inside the shape, on a grid of pitch h = (largest extent of
the main body) / ``resolution``; every length is in the input's units, computed in float64,
deterministic (no random numbers).

Inside test. Meshes: every boundary loop gets a fan cap (:func:`cap_holes`); every voxel center
gets 6 one-sided winding numbers, one per half-line along +-x, +-y, +-z, from the signed ray
crossings of the uncapped faces (:func:`ray_vote_solid`). For a closed surface all 6 agree; a hole
corrupts only the half-lines through it, so a voxel is inside when at least 3 of its 6 counts are
non-zero (ties inside: a false "outside" voxel deep inside would lower the depth of its whole
neighbourhood, a false "inside" voxel next to the surface adds a shallow, low-weight voxel), or when
the capped surface winds around it. The non-zero rule makes overlapping or inverted closed parts a
union. Point clouds: a morphological closing of the voxels holding points (:func:`point_solid`),
with a radius from the points' own spacing (above ``SPACING_SAMPLES`` points, measured from a seeded
uniform subset of them to all the others). Enclosed cavities are filled (:func:`exterior_fill`);
for meshes, so is what a ball of one voxel's radius (:data:`MESH_REACH`) cannot reach from the
outside: a pocket or a slit whose mouth is narrower than the grid resolves (a mouth behind nearly
closed lips, limbs a voxel apart). The grid cannot tell such a mouth open or shut, so without the
rule where the voxel centers happen to fall decides, from one pitch or placement to the next,
whether the pocket's neighbourhood is deep or shallow. A point solid's closing (radius >= 1 voxel)
applies the same rule at its own radius.

Stray parts. 26-connected components of the solid are sized by their boundary voxels (a surface
area proxy); the largest is the main body and another component is kept only when it is at least
``keep_ratio`` of its size (:func:`keep_main`). Parts that overlap or touch the main volume belong to
its component and are always kept. A first pass at ``coarse`` voxels over everything finds the main
body, so that stray parts neither coarsen the grid nor enter it. Where that pass finds the main body
in under 1 / :data:`ZOOM` of its grid, or none (a speck of a mesh far away: the body a few coarse
voxels, its thin parts between their centers), it is repeated over the main surface's box
(:func:`surface_box`, the surface's own voxel components weighed by area); where no part lies apart
there (a needle or a floor beside the body), the box of the coarse body takes in the surfaces that
lie on it (:func:`whole_surfaces`). A mesh's thin tip (a finger, a fin, a spike) can lie more than a
coarse voxel off the coarse solid and so out of the box, while the fine grid resolves it: where the
fine solid then reaches the edge of its grid (cut off), the box takes in the surfaces lying mostly
on the fine solid (:func:`whole_surfaces` again) and the fine pass is repeated, at most
:data:`WIDEN` times.

Memory. A grid of ``resolution`` voxels along the largest extent holds at most about
(resolution + 31)^3 voxels (a cube, with the widest margins) of ``VOXEL_BYTES`` each at the peak;
:func:`check_resolution` refuses a resolution whose worst case exceeds
:data:`jaxpose.config.MEMORY_BUDGET`.

Depth. The Euclidean distance of each kept voxel to the outside (:func:`depth`, scipy's exact
transform, which :mod:`jaxpose.depth` equals in JAX), minus ``Solid.bias`` voxels: half a voxel for mesh solids (their outer
voxel centers lie inside the surface) and one voxel for point solids (their outer voxels straddle
it).
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy import ndimage
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from .._validate import InvalidInputError, check_array, check_bool, check_concrete, check_faces, check_int, check_real
from ..config import MEMORY_BUDGET, RobustConfig
from ..geometry import surface_labels
from ..sample import lattice_points

__all__ = ["Solid", "check_solid", "robust_solid", "cap_holes", "ray_vote_solid", "point_solid", "exterior_fill", "keep_main", "MESH_REACH",
           "depth", "make_grid", "closing_radius", "linked_parts", "LINK", "neighbour_distances", "check_resolution", "RESOLUTION", "COARSE",
           "KEEP_RATIO", "ZOOM", "WIDEN", "surface_box", "whole_surfaces", "reaches_edge", "SPACING_SAMPLES", "VOXEL_BYTES", "MESH_BIAS", "POINT_BIAS", "GRID_OFFSET"]

_DEFAULTS = RobustConfig()  # the defaults are written once, in jaxpose.config.RobustConfig
RESOLUTION = _DEFAULTS.resolution  # voxels along the main body's largest extent
COARSE = _DEFAULTS.coarse  # the same for the first pass over everything
KEEP_RATIO = _DEFAULTS.keep_ratio  # a separate component is kept when at least this share of the main body's boundary
MAX_CLOSING = _DEFAULTS.max_closing  # point clouds: the pitch is coarsened so that the closing radius stays within this
SPACING_SAMPLES = _DEFAULTS.spacing_samples  # point clouds: the spacing is measured from at most this many points
VOXEL_BYTES = 64  # peak memory per voxel of the fine grid (measured 50-58 bytes)
MESH_BIAS = 0.5  # voxels between a mesh solid's outer voxel centers and its surface (depth offset)
POINT_BIAS = 1.0  # the same for a point solid (its outer voxels straddle the surface)
MESH_REACH = 1  # meshes: the outside is what a ball of this many voxels' radius reaches (exterior_fill)
LINK = 2  # point clouds: separate parts are told apart at a dilation of this many closing radii (linked_parts)
_MAX_MARGIN = 3 * MAX_CLOSING + 3  # voxels around the box (point clouds; meshes: 3)
GRID_OFFSET = 1e-3 * np.sqrt(2.0)  # grid offset in pitches: grid lines miss the vertices of axis-aligned models (and points)
_AXES = ((0, 1, 2), (1, 2, 0), (2, 0, 1))  # ray axis a, then (b, c) with (a, b, c) cyclic


class Solid(NamedTuple):
    """The kept solid of a shape on a voxel grid.

    Attributes:
      inside: (nx, ny, nz) bool, the kept voxels (main body and parts kept with it).
      depth: (nx, ny, nz) float64, distance to the outside in units (0 outside), or None when
        :func:`robust_solid` was asked not to compute it.
      origin: (3,) lower corner of voxel (0, 0, 0), in the grid's frame.
      pitch: voxel edge length, in units.
      occupied: (nx, ny, nz) bool for point solids (voxels holding a point), None for meshes.
      frame: (3, 3) rotation whose rows are the grid axes in world coordinates (identity by default):
        a voxel center y in the grid frame is the world point ``frame.T @ y``.
      components: number of components found; dropped: how many were dropped as stray parts.
      bias: voxels subtracted from the distance transform in ``depth`` (:data:`MESH_BIAS`,
        :data:`POINT_BIAS`).
      radius: point solids: the closing radius the points' spacing gives at ``pitch`` (voxels,
        before any growth; :func:`linked_parts` links at ``LINK`` times it); None for meshes.
    """

    inside: np.ndarray
    depth: np.ndarray
    origin: np.ndarray
    pitch: float
    occupied: np.ndarray | None
    frame: np.ndarray
    components: int
    dropped: int
    bias: float = MESH_BIAS
    radius: int | None = None

    def centers(self):
        """(n, 3) world coordinates of the kept voxel centers, in ``np.nonzero(inside)`` order."""
        idx = np.stack(np.nonzero(self.inside), axis=1) + 0.5
        return (self.origin + self.pitch * idx) @ self.frame

    def volume(self):
        """Volume of the kept solid in units^3: h^3 (voxels - occupied / 2).

        Mesh solids are voxel centers inside the surface (the count is unbiased); point solids
        contain the voxels holding points, which straddle the surface, so half of them are left out.
        """
        n = float(self.inside.sum())
        if self.occupied is not None:
            n -= 0.5 * float((self.occupied & self.inside).sum())
        return n * self.pitch ** 3


def check_solid(sol, depth=False):
    """Refuse a ``sol`` that is no :class:`Solid` (points, an array: was an AttributeError "... has
    no attribute 'inside'"), or, with ``depth``, one built without its depth (``with_depth=False``;
    the frames read the depth field: was a TypeError): InvalidInputError naming how to build one."""
    if not isinstance(sol, Solid):
        raise InvalidInputError(f"sol must be a Solid (jaxpose.occupancy.solid.robust_solid, "
                                f"jaxpose.rotation.core.frame_solid), got {type(sol).__name__}")
    if depth and sol.depth is None:
        raise InvalidInputError("sol has no depth (built with with_depth=False): the frames read the depth field; "
                                "build it with jaxpose.rotation.core.frame_solid(vertices, faces)")


# ------------------------------------------------------------------ grids
def make_grid(lo, hi, pitch, margin=3):
    """Grid covering the box [lo, hi] (3,) with ``margin`` voxels on each side.

    Returns origin (3,) (the lower corner of voxel 0) and shape (3,) ints.
    """
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    origin = lo - (margin + GRID_OFFSET) * pitch
    shape = np.ceil((hi - origin) / pitch).astype(int) + margin
    return origin, shape


# ------------------------------------------------------------------ mesh solid
def cap_holes(vertices, faces):
    """Close every boundary loop of a mesh by a fan around the loop's centroid.

    Boundary edges are the directed face edges that occur once; their connected components are the
    loops; each edge (e0 -> e1) gets the cap triangle (e1, e0, centroid), oriented like its face, so
    faces + caps is a closed 2-cycle (winding numbers are defined) whatever the loops' shapes.

    Args:
      vertices: (n, 3) float; faces: (f, 3) int.

    Returns:
      vertices (n + loops, 3) with the loop centroids appended, caps (boundary edges, 3) int.
    """
    n = len(vertices)
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    key = np.minimum(e[:, 0], e[:, 1]) * n + np.maximum(e[:, 0], e[:, 1])
    order = np.argsort(key, kind="stable")
    k = key[order]
    single = np.ones(len(k), bool)
    same = k[1:] == k[:-1]
    single[1:] &= ~same
    single[:-1] &= ~same
    be = e[order[single]]
    if len(be) == 0:
        return vertices, np.zeros((0, 3), np.int64)
    nodes, local = np.unique(be, return_inverse=True)
    local = local.reshape(-1, 2)
    g = coo_matrix((np.ones(len(be)), (local[:, 0], local[:, 1])), shape=(len(nodes),) * 2)
    nl, lab = connected_components(g, directed=False)
    cen = np.stack([np.bincount(lab, vertices[nodes, k], minlength=nl) for k in range(3)], 1)
    cen /= np.bincount(lab, minlength=nl)[:, None]
    loop = lab[local[:, 0]]
    caps = np.stack([be[:, 1], be[:, 0], n + loop], axis=1)
    return np.vstack([vertices, cen]), caps


def _prepare(g, faces):
    """The triangles in grid units, per corner and axis as contiguous (f,) arrays:
    corners[v][axis], and their bounds lo[axis], hi[axis]."""
    corners = [[np.ascontiguousarray(g[faces[:, v], axis]) for axis in range(3)] for v in range(3)]
    lo = [np.minimum(np.minimum(corners[0][x], corners[1][x]), corners[2][x]) for x in range(3)]
    hi = [np.maximum(np.maximum(corners[0][x], corners[1][x]), corners[2][x]) for x in range(3)]
    return corners, lo, hi


def _crossings(prep, shape, a, b, c):
    """Signed crossings of the grid lines along axis a by the prepared triangles (grid units):
    (start index along a, j, k, sign); line (j, k) passes through voxel centers i = 0..n_a - 1."""
    (p0, p1, p2), lo, hi = prep
    j0 = np.maximum(np.ceil(lo[b]), 0).astype(np.int64)
    j1 = np.minimum(np.floor(hi[b]), shape[b] - 1).astype(np.int64)
    k0 = np.maximum(np.ceil(lo[c]), 0).astype(np.int64)
    k1 = np.minimum(np.floor(hi[c]), shape[c] - 1).astype(np.int64)
    nj, nk = j1 - j0 + 1, k1 - k0 + 1
    hit = np.flatnonzero((nj > 0) & (nk > 0))
    count = nj[hit] * nk[hit]
    rep = np.repeat(hit, count)
    local = np.arange(len(rep)) - np.repeat(np.cumsum(count) - count, count)
    nkr = nk[rep]
    jj = j0[rep] + local // nkr
    kk = k0[rep] + local % nkr
    u0, u1, u2 = p0[b][rep], p1[b][rep], p2[b][rep]
    w0, w1, w2 = p0[c][rep], p1[c][rep], p2[c][rep]
    d = (u1 - u0) * (w2 - w0) - (u2 - u0) * (w1 - w0)  # twice the signed projected area
    ok = d != 0
    d = np.where(ok, d, 1.0)
    l1 = ((jj - u0) * (w2 - w0) - (u2 - u0) * (kk - w0)) / d
    l2 = ((u1 - u0) * (kk - w0) - (jj - u0) * (w1 - w0)) / d
    l0 = 1.0 - l1 - l2
    ok &= (l0 >= 0) & (l1 >= 0) & (l2 >= 0)
    tt = l0 * p0[a][rep] + l1 * p1[a][rep] + l2 * p2[a][rep]
    start = np.clip(np.floor(tt[ok]).astype(np.int64) + 1, 0, shape[a])
    return start, jj[ok], kk[ok], np.where(d[ok] > 0, -1, 1)


def _add_crossings(delta, a, b, c, found):
    """Add the signs of crossings (start, j, k, sign) of lines along axis a into ``delta`` (the
    grid's own axis order, axis a one longer: the start index n_a is past the last voxel)."""
    start, jj, kk, sign = found
    strides = (delta.shape[1] * delta.shape[2], delta.shape[2], 1)
    np.add.at(delta.reshape(-1), start * strides[a] + jj * strides[b] + kk * strides[c], sign.astype(delta.dtype))


def _add_votes(delta, a, votes):
    """Add the non-zero one-sided windings (0..2) per voxel of a crossing ``delta`` along axis a
    into ``votes``: W_f, the running sum before each voxel center, and W_f - T (T the line's sum)."""
    wf = np.cumsum(delta, axis=a, dtype=delta.dtype)
    n = wf.shape[a] - 1
    before = (slice(None),) * a
    total = wf[before + (slice(n, n + 1),)]
    wf = wf[before + (slice(0, n),)]
    votes += wf != 0
    votes += wf != total


def ray_vote_solid(vertices, faces, origin, pitch, shape, min_votes=3, caps=None):
    """Inside test of voxel centers by signed ray crossings along the 3 axes, counted from both ends.

    For a grid line along axis a, every triangle it crosses contributes s = -sign(n_a) (+1 entering
    a closed, outward-oriented surface). W_f(i) is the sum of s over the crossings before voxel
    center i, W_b(i) = W_f(i) - T (T the sum over the whole line, 0 for a closed surface); votes
    counts the non-zero values among {W_f, W_b} x 3 axes.

    Args:
      vertices: (n, 3), faces: (f, 3), origin: (3,), pitch: float, shape: (3,) ints.
      min_votes: inside iff votes >= min_votes.
      caps: optional (q, 3) extra faces (:func:`cap_holes`); voxels around which faces + caps
        wind are inside too.

    Returns:
      solid (shape) bool and votes (shape) uint8 in 0..6 (of the uncapped faces).
    """
    shape = tuple(int(s) for s in shape)
    g = (vertices - origin) / pitch - 0.5  # grid units: voxel center i at g = i
    votes = np.zeros(shape, np.uint8)
    tri = _prepare(g, faces)
    tcap = _prepare(g, caps) if caps is not None and len(caps) else None
    capped = None if tcap is None else np.zeros(shape, np.uint8)
    for a, b, c in _AXES:
        found = _crossings(tri, shape, a, b, c)
        more = None if tcap is None else _crossings(tcap, shape, a, b, c)
        # windings are sums of at most this many signs: int16 holds them when there are fewer than 2^15
        signs = len(found[0]) + (0 if more is None else len(more[0]))
        delta = np.zeros([n + (axis == a) for axis, n in enumerate(shape)], np.int16 if signs < 2**15 else np.int32)
        _add_crossings(delta, a, b, c, found)
        _add_votes(delta, a, votes)
        if more is not None:
            _add_crossings(delta, a, b, c, more)
            _add_votes(delta, a, capped)
    solid = votes >= min_votes
    if capped is not None:
        solid |= capped >= 4  # closed: all 6 agree up to ties
    return solid, votes


# ------------------------------------------------------------------ point-cloud solid
def neighbour_distances(points, k=4, samples=None, seed=0):
    """Distances from points to their k nearest other points (scipy's cKDTree over all of them).

    Args:
      points: (n, 3) float; k: neighbours.
      samples: None (every point), or at most this many points, a uniform random subset without
        replacement (``numpy.random.default_rng(seed)``), queried against all the points.

    Returns:
      (q, k) float, q = n or min(n, samples), rows ascending; with fewer than k other points, the
      columns past them hold the farthest of them (as :mod:`jaxpose.occupancy.points`' spacing), inf
      only for a single point.

    Raises:
      InvalidInputError: seed not an int >= 0 (:func:`jaxpose._validate.check_int`).
    """
    from scipy.spatial import cKDTree

    seed = check_int(seed, "seed", 0)

    queries = points
    if samples is not None and len(points) > samples:
        queries = points[np.random.default_rng(seed).choice(len(points), size=int(samples), replace=False)]
    tree = cKDTree(points, balanced_tree=False, compact_nodes=False)  # the faster build for one query
    dist, _ = tree.query(queries, k=k + 1, workers=1)
    dist = dist[:, 1:]
    if 1 < len(points) <= k:  # cKDTree pads the missing neighbours with inf
        dist[:, len(points) - 1:] = dist[:, len(points) - 2:len(points) - 1]
    return dist


def check_resolution(resolution, budget=MEMORY_BUDGET, name="resolution"):
    """Validate a voxel resolution (an int >= 8 whose worst-case grid fits ``budget`` bytes);
    messages call it ``name`` (robust_solid's ``coarse`` is one too).

    The worst case is a cube: (resolution + 2 * margin + 1)^3 voxels of ``VOXEL_BYTES``.

    Returns:
      resolution as an int.

    Raises:
      InvalidInputError: naming the range, and the memory the grid would need.
    """
    resolution = check_int(resolution, name, 8)  # the library's int rule, its messages
    side = lambda r: r + 2 * _MAX_MARGIN + 1
    largest = int(np.floor((budget / VOXEL_BYTES) ** (1.0 / 3.0))) - 2 * _MAX_MARGIN - 1
    while VOXEL_BYTES * side(largest + 1) ** 3 <= budget:
        largest += 1
    while VOXEL_BYTES * side(largest) ** 3 > budget:
        largest -= 1
    need = VOXEL_BYTES * float(side(int(resolution))) ** 3
    if need > budget:
        raise InvalidInputError(
            f"{name}={int(resolution)} needs up to {need / 2**30:.2f} GiB for the voxel grid "
            f"({side(int(resolution)) ** 3:.2g} voxels at {VOXEL_BYTES} bytes); the limit is "
            f"{budget / 2**30:g} GiB: use a {name} in [8, {largest}]"
        )
    return int(resolution)


def closing_radius(r_k, pitch):
    """Closing radius in voxels (int >= 1) of a point cloud: the 90th percentile of the 4-NN
    distances r_k (the distance across the largest typical gap between samples) over the pitch,
    rounded up."""
    return int(max(1, np.ceil(np.quantile(r_k, 0.9) / pitch)))


def point_solid(points, origin, pitch, shape, radius, max_radius=None):
    """Closing of the voxels holding points: dilate by ``radius`` voxels, fill cavities, erode back.

    When the samples have gaps wider than the dilation, the fill finds no cavity (it leaks); then
    the radius grows by max(1, radius // 4) voxels, up to ``max_radius`` (default 3 radius). A
    closing is accepted when the filled closing holds >= 1.2 x the voxels of the closed shell alone.

    Returns:
      solid (shape) bool, occupied (shape) bool (voxels holding a point), the radius used.
    """
    shape = tuple(int(s) for s in shape)
    idx = np.floor((points - origin) / pitch).astype(np.int64)
    inside = np.all((idx >= 0) & (idx < np.array(shape)), axis=1)
    occ = np.zeros(shape, bool)
    occ[tuple(idx[inside].T)] = True
    out_dist = ndimage.distance_transform_edt(~occ)
    max_radius = 3 * radius if max_radius is None else max_radius
    while True:
        dil = out_dist <= radius
        closed = ndimage.distance_transform_edt(exterior_fill(dil)) > radius
        if radius >= max_radius or closed.sum() >= 1.2 * (ndimage.distance_transform_edt(dil) > radius).sum():
            return closed | occ, occ, radius
        radius = min(radius + max(1, radius // 4), max_radius)


def linked_parts(occupied, radius, link=None):
    """Sizes of the separate parts of a point cloud: the 26-connected components of its occupied
    voxels dilated by ``link`` voxels (default ``LINK`` x ``radius``, the closing radius: points up to
    about 2 link voxels apart are linked), each sized by the occupied voxels it holds.

    A dilation of the scattered points, not the closing: a closing erodes back and can cut a thin
    limb into pieces, a dilation only joins.

    Args:
      occupied: (nx, ny, nz) bool, voxels holding a point; radius: int >= 1, voxels.

    Returns:
      (k,) int64, the parts' sizes in descending order (k = 0 for an empty grid).
    """
    link = LINK * int(radius) if link is None else int(link)
    if not occupied.any():
        return np.zeros(0, np.int64)
    near = ndimage.distance_transform_edt(~occupied) <= link
    labels, _ = ndimage.label(near, structure=np.ones((3, 3, 3), bool))
    sizes = np.bincount(labels[occupied])[1:]
    return np.sort(sizes[sizes > 0])[::-1].astype(np.int64)


# ------------------------------------------------------------------ components, depth
def exterior_fill(solid, reach=0):
    """The solid with every voxel the outside does not reach filled.

    ``reach`` 0: the outside is the complement components that touch the grid border (enclosed
    cavities are filled, as ``scipy.ndimage.binary_fill_holes`` does), by one labelling. ``reach``
    1: the outside is what a ball of one voxel's radius reaches from the border: the free voxels
    whose six face neighbours are all free (a ball's centers; beyond the grid counts as free),
    those connected to the border (6-connected), and the free voxels next to them. A pocket or a
    slit whose mouth is less than about two voxels wide is filled with the cavities.

    Args:
      solid: (nx, ny, nz) bool. reach: 0 or 1 (voxels).

    Returns:
      (nx, ny, nz) bool, a superset of ``solid``.

    Example:
      >>> cup = np.ones((5, 5, 5), bool); cup[1:4, 1:4, 1:] = False; cup[2, 2, 4] = True
      >>> int(exterior_fill(cup).sum()), int(exterior_fill(cup, reach=1).sum())  # reach 1: the mouth's 8 stay out
      (90, 117)
    """
    if reach not in (0, 1):
        raise InvalidInputError(f"reach must be 0 or 1 voxels, got {reach!r}")
    free = np.pad(~solid, 1, constant_values=True) if reach else ~solid  # reach: one free layer beyond the grid
    core = ndimage.binary_erosion(free, border_value=1) if reach else free
    lab, n = ndimage.label(core)
    if n == 0:
        return solid
    border = np.zeros(n + 1, bool)
    for face in (lab[0], lab[-1], lab[:, 0], lab[:, -1], lab[:, :, 0], lab[:, :, -1]):
        border[np.unique(face)] = True
    border[0] = False
    outside = border[lab]
    if reach:
        outside = (ndimage.binary_dilation(outside) & free)[1:-1, 1:-1, 1:-1]
    return ~outside


def keep_main(solid, keep_ratio=KEEP_RATIO):
    """The 26-connected components of ``solid`` that are the main body or at least ``keep_ratio``
    of its size (boundary voxel count). Returns kept (shape) bool, components, dropped."""
    lab, n = ndimage.label(solid, structure=np.ones((3, 3, 3), bool))
    if n == 0:
        return solid, 0, 0
    boundary = solid & ~ndimage.binary_erosion(solid)
    size = np.bincount(lab[boundary], minlength=n + 1)[1:]
    keep = size >= keep_ratio * size.max()
    return np.concatenate([[False], keep])[lab], int(n), int((~keep).sum())


def depth(kept, pitch, bias=MESH_BIAS):
    """Euclidean distance to the outside in units: the exact distance transform
    (``scipy.ndimage.distance_transform_edt``, which :func:`jaxpose.depth.distance` equals) minus
    ``bias`` voxels (the mean offset of the true surface from the solid's outermost voxel centers),
    at least 0. (shape) float64 NumPy."""
    return np.maximum(ndimage.distance_transform_edt(kept) - bias, 0.0) * pitch


def reaches_edge(inside):
    """Whether a grid's True cells reach one of its six faces (a solid cut off by its grid)."""
    return any(np.take(inside, i, axis=a).any() for a in range(inside.ndim) for i in (0, -1))


def near_solid(x, kept, origin, pitch, grow=1):
    """(m,) bool: the voxel of each point x (m, 3) (the grid's frame, units) lies within ``grow``
    voxels of ``kept`` ((nx, ny, nz) bool; lower corner ``origin`` (3,), edge ``pitch`` > 0;
    ``grow`` an int >= 0). InvalidInputError for other shapes or values (one point (3,) was an
    IndexError; a NaN point or a pitch 0 read as off the solid; grow=-1 dilated until nothing changed)."""
    check_concrete("x, kept, origin and pitch", x, kept, origin, pitch)
    x = np.asarray(check_array(x, "x"), np.float64)
    if np.ndim(kept) != 3:
        raise InvalidInputError(f"kept must be a 3-D grid (nx, ny, nz), got shape {np.shape(kept)}")
    origin = np.asarray(origin, np.float64)
    if origin.shape != (3,) or not np.all(np.isfinite(origin)):
        raise InvalidInputError(f"origin must be 3 finite numbers, got {origin!r:.80}")
    pitch = check_real(pitch, "pitch", 0, strict=True)
    grow = check_int(grow, "grow", 0)
    near = ndimage.binary_dilation(kept, structure=np.ones((3, 3, 3), bool), iterations=grow) if grow else kept
    idx = np.floor((x - origin) / pitch).astype(np.int64)
    np.clip(idx, -1, np.array(kept.shape), out=idx)
    padded = np.pad(near, 1)
    return padded[idx[:, 0] + 1, idx[:, 1] + 1, idx[:, 2] + 1]


def _centroids(vertices, faces):
    """(f, 3) the centroids of the faces."""
    return vertices[faces].mean(axis=1)


def whole_surfaces(vertices, faces, on, near):
    """The vertices on the main body, ``on`` (n,) bool, with the whole of every face-connected
    surface most of whose area lies on it, and of the surface with the most area on it (the
    body's own): ``near`` (f,) bool, the faces whose centroids lie on the main body.

    Where the body is a few voxels of the first pass's coarse grid, its thin limbs (arms, legs)
    fall between the voxel centers and their vertices lie off the coarse solid, so the fine grid,
    laid over the vertices found, would cut them off; a limb's surface is connected to the
    torso's, which lies on the solid. Any other surface of which less than half the area lies on
    it (a thin needle beside the body, a floor under it) stays as found. Returns (n,) bool, a
    superset of ``on``.
    """
    faces = np.asarray(faces, np.int64)
    k, lab = surface_labels(len(vertices), faces)
    t = vertices[faces]
    area = 0.5 * np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1)
    total = np.bincount(lab[faces[:, 0]], weights=area, minlength=k)
    held = np.bincount(lab[faces[:, 0]], weights=np.where(near, area, 0.0), minlength=k)
    whole = held >= 0.5 * total
    whole[np.argmax(held)] |= held.max() > 0  # the surface with the most area on it: the body's own
    whole &= np.bincount(lab, weights=on, minlength=k) > 0  # (a surface with no vertex found stays off)
    return on | whole[lab]


WIDEN = 3  # meshes: at most this many wider boxes for a fine solid cut at its grid's edge
ZOOM = 4  # meshes: the first pass's grid is laid over the main surface once it spans under 1 / ZOOM of it


def _check_keep_ratio(keep_ratio):
    if not check_real(keep_ratio, "keep_ratio", 0) <= 1:  # above 1 every part was dropped: an empty solid
        raise InvalidInputError(f"keep_ratio must be in [0, 1], got {keep_ratio!r}")


def surface_box(vertices, faces, lo, hi, coarse=COARSE, keep_ratio=KEEP_RATIO):
    """The box of a mesh's main surface, found before any solid, for the first pass's grid.

    A stray part far from the body (a speck of a scan metres away) makes the box of everything
    so large that at ``coarse`` voxels across it the body is a few voxels or less: the first pass
    cannot find it (its thin parts fall between voxel centers) and the fine grid then misses part
    of the body, or holds the stray part. Here the surface itself is voxelized at ``coarse``
    voxels along the box's largest extent: the vertices and, on every face longer than a voxel,
    the points of :func:`jaxpose.sample.lattice_points` at one voxel's spacing, so that a
    connected surface occupies 26-connected voxels. Each occupied component weighs the area of
    its faces; components of at least ``keep_ratio`` of the heaviest
    are kept (:func:`keep_main`'s rule, by area). While the kept points' box spans under
    1 / :data:`ZOOM` of the grid's extent, the grid is laid over that box and the step repeats
    (each step narrows the box at least ZOOM-fold). A body that spans a quarter of the box
    already, as the outliers of :mod:`jaxpose.evaluation.variants` leave it, keeps ``(lo, hi)``
    as given.

    Args:
      vertices: (n, 3) float64; faces: (f, 3) int (the input's, without hole caps).
      lo, hi: (3,) the box of everything.
      coarse, keep_ratio: as :func:`robust_solid`'s.

    Returns:
      (lo, hi): the box to lay the first pass over, (3,) float64 each.

    Raises:
      InvalidInputError: traced arrays, faces that are not (f, 3) indices of the vertices, coarse
        not a resolution (:func:`check_resolution`), keep_ratio outside [0, 1]; named.

    Example::

        lo, hi = surface_box(v, f, v.min(0), v.max(0))  # a body and a speck 100 body lengths away: the body's box
    """
    check_concrete("vertices and faces", vertices, faces)
    coarse = check_resolution(coarse, name="coarse")
    _check_keep_ratio(keep_ratio)
    v = np.asarray(vertices, np.float64)
    faces = np.asarray(check_faces(faces, len(v)) if len(faces) else faces, np.int64)
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    for _ in range(64):  # (4^64: beyond any float64 box a body could be found in)
        extent = float((hi - lo).max())
        pitch = extent / coarse
        if not pitch > 0:
            break
        shape = np.floor((hi - lo) / pitch).astype(np.int64) + 3  # one voxel of margin each side
        cell = lambda x: np.floor((x - lo) / pitch).astype(np.int64) + 1
        near = np.all((v >= lo - pitch) & (v <= hi + pitch), axis=1)
        c = cell(v)
        occupied = np.zeros(shape, bool)
        occupied[tuple(np.clip(c[near], 0, shape - 1).T)] = True
        lab, n = ndimage.label(occupied, structure=np.ones((3, 3, 3), bool))
        if n <= 1:  # one connected set of vertex voxels: no part lies apart (the usual case, decided here)
            break
        held = faces[np.all(near[faces], axis=1)]  # the faces in this grid
        long = np.abs(np.diff(c[held], axis=1, append=c[held][:, :1])).max(axis=(1, 2)) > 1
        if long.any():  # faces longer than a voxel: their lattice joins the voxels between their corners
            try:
                extra = lattice_points(v, held[long], pitch)[len(v):]
            except InvalidInputError:  # too large a lattice for the memory budget: stop zooming
                break
            extra = extra[np.all((extra >= lo - pitch) & (extra <= hi + pitch), axis=1)]
            occupied[tuple(np.clip(cell(extra), 0, shape - 1).T)] = True
            lab, n = ndimage.label(occupied, structure=np.ones((3, 3, 3), bool))
            if n <= 1:
                break
        else:
            extra = np.zeros((0, 3))
        t = v[held]
        area = 0.5 * np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1)
        corner = np.clip(c[held[:, 0]], 0, shape - 1)  # a face's corners share its component (joined above)
        weight = np.bincount(lab[tuple(corner.T)], weights=area, minlength=n + 1)[1:]
        if not weight.max() > 0:
            break
        keep = np.concatenate([[False], weight >= keep_ratio * weight.max()])
        points = np.concatenate([v[near], extra])
        main = points[keep[lab[tuple(np.clip(cell(points), 0, shape - 1).T)]]]
        b_lo, b_hi = main.min(axis=0), main.max(axis=0)
        if not float((b_hi - b_lo).max()) * ZOOM < extent:
            break
        lo, hi = b_lo, b_hi
    return lo, hi


# ------------------------------------------------------------------ driver
def robust_solid(vertices, faces=None, *, resolution=RESOLUTION, coarse=COARSE, keep_ratio=KEEP_RATIO,
                 min_votes=3, frame=None, with_depth=True, capped=None, reach=MESH_REACH) -> Solid:
    """The kept solid of a mesh or a point cloud (module docs).

    Args:
      vertices: (n, 3) float, in any units.
      faces: (f, 3) int, or None for a point cloud.
      resolution: voxels along the main body's largest extent (>= 8); coarse: the same for the
        first pass over everything. For point clouds the pitch is at least the 90th percentile of
        the 4-NN spacing / ``MAX_CLOSING`` (sparser samples carry no finer detail).
      keep_ratio: separate components smaller than this share of the main body are dropped.
      min_votes: of the 6 one-sided windings, how many make a voxel inside (meshes).
      frame: optional (3, 3) rotation (rows = grid axes in world coordinates); the grid is laid out
        along them (for rotation-equivariant results, e.g. along the shape's principal axes).
      with_depth: compute ``Solid.depth`` on the host (False: None, for callers that take the
        depth from ``inside`` and ``bias`` themselves).
      capped: meshes: ``cap_holes(vertices, faces)`` when the caller has computed it already (it
        is not computed again; with a ``frame``, its vertices are turned like the input's).
      reach: meshes: the outside is what a ball of this many voxels' radius reaches
        (:func:`exterior_fill`; 0: every complement component that touches the border). Point
        clouds: ignored (their closing's radius is at least one voxel).

    Returns:
      :class:`Solid`; its ``inside`` is empty when the shape encloses no volume (a flat or open
      sheet, a point cloud of one side).

    Raises:
      InvalidInputError: a bad argument, named (vertices not finite (n, 3) reals, faces that are
        not (f, 3) indices of them, keep_ratio outside [0, 1], min_votes outside 1 ... 6, a frame
        that is not a (3, 3) rotation, a with_depth that is not a bool, a bad resolution, coarse or
        reach); vertices that all coincide.
    """
    resolution, coarse = check_resolution(resolution), check_resolution(coarse, name="coarse")
    check_concrete("vertices and faces", vertices, faces)
    v = np.asarray(check_array(vertices, "vertices", 1), np.float64)  # a NaN read 'the shape has no extent'
    if faces is not None and len(faces):
        faces = check_faces(faces, len(v))
    _check_keep_ratio(keep_ratio)
    if check_int(min_votes, "min_votes", 1) > 6:  # 0: the whole grid inside; above 6: nothing
        raise InvalidInputError(f"min_votes must be in 1 ... 6 (of the 6 one-sided windings), got {min_votes!r}")
    with_depth = check_bool(with_depth, "with_depth")
    if frame is not None:
        try:
            given = np.asarray(frame, np.float64)
        except (TypeError, ValueError):
            given = None
        if (given is None or given.shape != (3, 3) or not np.all(np.isfinite(given))
                or np.abs(given @ given.T - np.eye(3)).max() > 1e-5):  # a scaled or skewed grid: a wrong solid
            raise InvalidInputError(f"frame must be a (3, 3) rotation (orthonormal rows: the grid's axes), got {frame!r:.80}")
    frame = frame_given = None if frame is None else np.asarray(frame, np.float64)
    v = v if frame is None else v @ frame.T
    frame = np.eye(3) if frame is None else frame
    n_input = len(v)
    lo, hi = v.min(0), v.max(0)
    if not float((hi - lo).max()) > 0:
        raise InvalidInputError("the shape has no extent: all its points coincide")
    if faces is None:
        r_gap = neighbour_distances(v, 4, samples=SPACING_SAMPLES)[:, 3]
        caps = None
    else:
        if capped is None:
            v, caps = cap_holes(v, np.asarray(faces, np.int64))
        else:
            v = np.asarray(capped[0], np.float64) if frame_given is None else np.asarray(capped[0], np.float64) @ frame_given.T
            caps = capped[1]

    def solid_at(origin, pitch, shape):
        if faces is None:
            return point_solid(v, origin, pitch, shape, closing_radius(r_gap, pitch))[:2]
        return ray_vote_solid(v, faces, origin, pitch, shape, min_votes=min_votes, caps=caps)[0], None

    def margin(pitch):
        return 3 * closing_radius(r_gap, pitch) + 3 if faces is None else 3

    def coarsest(pitch):  # a point cloud's spacing limits its detail: closing radius <= MAX_CLOSING voxels
        return max(pitch, float(np.quantile(r_gap, 0.9)) / MAX_CLOSING) if faces is None else pitch

    def first_pass(lo, hi, whole=False):  # pass 1: the main body at a coarse pitch over the box (stray parts included)
        pitch1 = coarsest(float((hi - lo).max()) / coarse)
        origin1, shape1 = make_grid(lo, hi, pitch1, margin(pitch1))
        kept1 = keep_main(solid_at(origin1, pitch1, shape1)[0], keep_ratio)[0]
        on1 = near_solid(v[:n_input], kept1, origin1, pitch1, grow=1) if kept1.any() else None
        if on1 is None or not on1.any():
            return None
        if whole:  # the body a few coarse voxels: its thin limbs lie off them, their surface joins the torso's
            on1 = whole_surfaces(v[:n_input], faces, on1, near_solid(_centroids(v, faces), kept1, origin1, pitch1, grow=1))
        b_lo, b_hi = v[:n_input][on1].min(0), v[:n_input][on1].max(0)  # the exact box of the input on the main body
        # a mesh's sharp tip (a tetrahedron's corner, a cone's apex) lies more than a voxel from
        # the coarse solid; where the box then misses some of the solid's voxel centers (inside
        # the surface, so within its vertices' box), it takes in their voxels, so that the fine
        # grid still holds the whole main body. (A point cloud's points seed its solid: each lies
        # in it, and its closed voxels reach past the points' box by design.)
        if faces is not None:
            centers = origin1 + (np.argwhere(kept1) + 0.5) * pitch1
            c_lo, c_hi = centers.min(0), centers.max(0)
            if np.any(c_lo < b_lo) or np.any(c_hi > b_hi):
                b_lo, b_hi = np.minimum(b_lo, c_lo - pitch1 / 2), np.maximum(b_hi, c_hi + pitch1 / 2)
        return b_lo, b_hi

    box = first_pass(lo, hi)
    if faces is not None and (box is None or float((box[1] - box[0]).max()) * ZOOM < float((hi - lo).max())):
        # the main body in under 1 / ZOOM of the first grid, or none: the grid was set by a part far
        # from the body, at whose pitch the body's thin parts fall between voxel centers; the first
        # pass again, over the main surface's box (surface_box)
        s_lo, s_hi = surface_box(v[:n_input], faces, lo, hi, coarse, keep_ratio)
        if not (np.array_equal(s_lo, lo) and np.array_equal(s_hi, hi)):
            box = first_pass(s_lo, s_hi) or box
        elif box is not None:  # no part lies apart at that pitch (a needle or a floor beside the body): the
            # coarse body's box, taking in the surfaces that mostly lie on it (whole_surfaces)
            box = first_pass(lo, hi, whole=True)

    def fine(box):  # pass 2: the fine grid on the main body's box
        b_lo, b_hi = box if box is not None else (lo, hi)
        pitch = coarsest(float((b_hi - b_lo).max()) / resolution)
        origin, shape = make_grid(b_lo, b_hi, pitch, margin(pitch))
        solid, occupied = solid_at(origin, pitch, shape)
        return (origin, pitch, occupied, *keep_main(exterior_fill(solid, reach if faces is not None else 0), keep_ratio))

    origin, pitch, occupied, kept, components, dropped = fine(box)
    for _ in range(WIDEN if faces is not None and box is not None else 0):
        # a thin tip (a finger, a fin) lay more than a coarse voxel off the coarse body, out of the
        # box, and the fine solid is cut at its grid's edge: the box takes in the surfaces lying
        # mostly on the fine solid (whole_surfaces), which hold the tip's
        if not reaches_edge(kept):
            break
        u = v[:n_input]
        on = whole_surfaces(u, faces, near_solid(u, kept, origin, pitch, grow=1),
                            near_solid(_centroids(v, faces), kept, origin, pitch, grow=1))
        wider = np.minimum(box[0], u[on].min(0)), np.maximum(box[1], u[on].max(0))
        if not (np.any(wider[0] < box[0]) or np.any(wider[1] > box[1])):
            break
        box = wider
        origin, pitch, occupied, kept, components, dropped = fine(box)
    bias = MESH_BIAS if faces is not None else POINT_BIAS
    dep = depth(kept, pitch, bias=bias) if with_depth else None
    radius = closing_radius(r_gap, pitch) if faces is None else None
    return Solid(kept, dep, origin, pitch, occupied, frame, components, dropped, bias, radius)
