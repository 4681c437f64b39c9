"""The robust voxel solid of a point cloud, in JAX: jittable, vmappable, no host step.

The algorithm of :func:`jaxpose.occupancy.solid.robust_solid` for points, on a static grid (cell count
static, pitch and origin traced):

1. Spacing: r_4, the distance of each point of a seeded uniform subset (at most
   ``spacing_samples``; indices from :func:`spacing_subset`, fixed by the point count) to its 4th
   nearest other point (blocked brute force; candidates from a matrix product, distances then
   recomputed exactly); q = its 90th percentile (linear interpolation, as ``numpy.quantile``).
2. Pitch h = max(extent / resolution, q / ``max_closing``); closing radius r = max(1, ceil(q / h))
   voxels; a margin of 3 r + 3 voxels around the box; grid origin lo - (margin + 1e-3 sqrt 2) h.
3. Occupied voxels: each point's voxel (scatter). Closing: dilate by r (squared distance to the
   occupied voxels <= r^2, :func:`.bits.dilate_ball` on the grid packed 32 voxels to a word), fill
   enclosed cavities (:func:`exterior_fill`), erode by r. A closing
   is accepted when it holds >= 1.2 x the voxels of the eroded shell alone (no cavity: the fill
   leaked through a gap wider than the dilation); otherwise r grows by max(1, r // 4) up to 3 r
   (``lax.while_loop``). The solid is the closing or the occupied voxels.
4. Stray parts (:func:`keep_main`): 26-connected components (labelled by runs of voxels,
   :mod:`jaxpose.occupancy.runs`; voxel by voxel, min-label propagation and pointer jumping in a
   ``lax.while_loop``, when the solid has more runs than the run arrays hold), sized by their boundary voxels (6-neighbour erosion); the
   largest and those at least ``keep_ratio`` of it are kept.
5. Two passes: a coarse one (``coarse`` voxels along the largest extent) over every point finds
   the main body; the points within one voxel of it give the box of the fine pass
   (``resolution``), whose solid is filled and kept again.
   Separate bodies (:func:`linked_parts`): the fine pass's occupied voxels dilated by ``LINK``
   closing radii (the radius the spacing gives, before growth), 26-connected components sized by
   the occupied voxels they hold; ``PointSolid.second_part`` is the second largest over the largest.
6. What :func:`jaxpose.pose.pose.robust_pipeline` takes from it: the depth of each kept voxel, its exact
   distance to the outside minus ``POINT_BIAS`` = one voxel (occupied voxels straddle the surface)
   (:func:`jaxpose.depth.depth_weights`), and the volume h^3 (kept voxels - kept occupied voxels / 2)
   (:func:`jaxpose.moments.grid_moments`).

Grids: ``resolution + 2 (3 max_closing + 3) + 1`` cells per axis (127 at the default 96), enough
for the widest margin whatever the shape, so the cell count never depends on the points.

Differentiation: the occupancy, the depth and the radius are piecewise constant in the points
(no derivative flows through them); the grid's origin and pitch follow the points' box and
spacing, so centers and scales move with a translation or a scaling of the points exactly.

Example::

    sol = point_solid(points, None, spacing_subset(len(points), 10_000), RobustConfig())
    sol.inside.sum(), sol.pitch
"""
from __future__ import annotations

from functools import partial
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax

from .._validate import check_int
from ..config import RobustConfig
from . import bits, runs
from .runs import run_labels
from .solid import GRID_OFFSET, LINK, POINT_BIAS

__all__ = ["PointSolid", "point_solid", "spacing_subset", "spacing_quantile", "grid_cells", "exterior_fill",
           "components", "keep_main", "linked_parts", "erode6", "POINT_BIAS", "LINK"]

_BIG = np.int32(2**30)  # "no label" for components
_CANDIDATES = 8  # nearest-neighbour candidates per query from the matrix product, then exact


class PointSolid(NamedTuple):
    """The kept solid of a point cloud on a static grid (a pytree).

    Attributes:
      inside: (g, g, g) bool, kept voxels.
      occupied: (g, g, g) bool, voxels holding a point.
      origin: (3,) lower corner of voxel (0, 0, 0); pitch: () voxel edge, in units.
      radius: () int32, the closing radius used (voxels).
      components: () int32, components found; dropped: () int32, dropped as stray parts.
      second_part: () float, the second largest separate part of the points over the largest
        (:func:`linked_parts`; 0 when they are one part).
    """

    inside: jax.Array
    occupied: jax.Array
    origin: jax.Array
    pitch: jax.Array
    radius: jax.Array
    components: jax.Array
    dropped: jax.Array
    second_part: jax.Array


def grid_cells(resolution: int, max_closing: int) -> int:
    """Cells per axis of the static grid of a pass at ``resolution`` (module docs)."""
    return int(resolution) + 2 * (3 * int(max_closing) + 3) + 1


# ------------------------------------------------------------------ spacing
def spacing_subset(n: int, samples: int, seed: int = 0) -> np.ndarray:
    """Indices (q,) of the points whose neighbour distances are measured: every point when
    n <= samples, else ``numpy.random.default_rng(seed).choice(n, samples, replace=False)`` (the
    subset of :func:`jaxpose.occupancy.solid.neighbour_distances`). Depends on (n, samples, seed) only.

    Raises:
      InvalidInputError: seed not an int >= 0 (:func:`jaxpose._validate.check_int`).
    """
    seed = check_int(seed, "seed", 0)
    if n <= samples:
        return np.arange(n)
    return np.random.default_rng(seed).choice(n, size=int(samples), replace=False)


def _masked_quantile(values, mask, q):
    """numpy.quantile(values[mask], q) (linear interpolation); values (n,), mask (n,) bool."""
    n = jnp.sum(mask)
    s = jnp.sort(jnp.where(mask, values, jnp.inf))
    pos = q * (jnp.maximum(n, 1) - 1).astype(values.dtype)
    lo = jnp.floor(pos).astype(jnp.int32)
    hi = jnp.minimum(lo + 1, jnp.maximum(n - 1, 0))
    frac = pos - lo.astype(values.dtype)
    return s[lo] + frac * (s[hi] - s[lo])


def _nearest(d2, k):
    """Indices (rows, k) of the k smallest entries of each row of ``d2``, smallest first, the
    lower index first among equal values: ``lax.top_k(-d2, k)[1]``, the same indices. float64
    takes k argmin passes over an order-preserving int64 key instead (XLA:CPU has no fast
    float64 top_k: it sorts each row); other dtypes take top_k itself."""
    if d2.dtype != jnp.float64:
        return lax.top_k(-d2, k)[1]
    bits = lax.bitcast_convert_type(d2, jnp.int64)
    key = jnp.where(bits < 0, bits ^ jnp.int64(0x7FFFFFFFFFFFFFFF), bits)  # IEEE total order
    taken = jnp.iinfo(jnp.int64).max  # above every key but all-ones NaN: a taken entry is never chosen again
    col = lax.broadcasted_iota(jnp.int32, d2.shape, 1)
    out = []
    for _ in range(k):
        i = jnp.argmin(key, axis=1).astype(jnp.int32)
        out.append(i)
        key = jnp.where(col == i[:, None], taken, key)
    return jnp.stack(out, 1)


def spacing_quantile(points, mask, queries, query_mask, k=4, q=0.9, block=256):
    """The ``q`` quantile of the distances from points[queries] to their k-th nearest other point
    (the farthest other point in a set of k points or fewer, padded or not).

    Args:
      points: (n, 3) float; mask: (n,) bool (False rows are padding, never neighbours).
      queries: (m,) int indices into points; query_mask: (m,) bool (False: not counted).
      k: neighbour rank (4); q: quantile (0.9); block: queries per block (memory O(block n)).

    Returns:
      () float, in the units of ``points``; differentiable in them through the distances of the
      chosen neighbours (which neighbours and which quantile rank are piecewise constant).
    """
    pts = lax.stop_gradient(points)
    center = jnp.sum(jnp.where(mask[:, None], pts, 0), 0) / jnp.maximum(jnp.sum(mask), 1)
    dp = points - center  # differentiable: the distances of the chosen neighbours carry derivatives
    p = lax.stop_gradient(dp)  # the choice of neighbours does not
    pn = jnp.where(mask, jnp.sum(p * p, axis=1), jnp.inf)
    m = queries.shape[0]
    pad = (-m) % block
    qi = jnp.concatenate([queries, jnp.zeros((pad,), queries.dtype)]).reshape(-1, block)
    cand = min(_CANDIDATES, p.shape[0])
    # fewer than k other points: the farthest of them (padding never counts as a neighbour)
    rank = jnp.clip(jnp.sum(mask) - 1, 1, min(k, cand - 1))

    def kth(rows):
        x = p[rows]
        d2 = jnp.sum(x * x, 1)[:, None] + pn[None, :] - 2.0 * x @ p.T  # +inf on padding
        idx = _nearest(d2, cand)
        exact = jnp.sum((dp[rows][:, None, :] - dp[idx]) ** 2, axis=-1)
        exact = jnp.where(mask[idx], exact, jnp.inf)
        d2 = jnp.sort(exact, axis=1)[:, rank]  # rank 0 is the point itself
        return jnp.where(d2 > 0, jnp.sqrt(jnp.where(d2 > 0, d2, 1.0)), 0.0)  # no NaN derivative at 0

    r = lax.map(kth, qi).reshape(-1)[:m]
    return _masked_quantile(r, query_mask & jnp.isfinite(r), q)


# ------------------------------------------------------------------ morphology
def _window(x, op, fill):
    """op over the 3 x 3 x 3 neighbourhood of each cell (cells beyond the border = fill)."""
    for axis in range(3):
        n = x.shape[axis]
        pad = [(0, 0)] * 3
        pad[axis] = (1, 1)
        p = jnp.pad(x, pad, constant_values=fill)
        x = op(op(lax.slice_in_dim(p, 0, n, axis=axis), lax.slice_in_dim(p, 1, n + 1, axis=axis)),
               lax.slice_in_dim(p, 2, n + 2, axis=axis))
    return x


def _cross(x, op, fill):
    """op over each cell and its 6 face neighbours (cells beyond the border = fill)."""
    out = x
    for axis in range(3):
        n = x.shape[axis]
        pad = [(0, 0)] * 3
        pad[axis] = (1, 1)
        p = jnp.pad(x, pad, constant_values=fill)
        out = op(op(out, lax.slice_in_dim(p, 0, n, axis=axis)), lax.slice_in_dim(p, 2, n + 2, axis=axis))
    return out


def erode6(solid):
    """6-neighbour erosion (scipy's binary_erosion with its default cross, border outside)."""
    return _cross(solid, jnp.logical_and, False)


def _label(cells, seed, corners, jumps=2):
    """Connected-component labels of ``cells`` (3-D bool): each cell's label is the smallest
    ``seed`` value in its component (_BIG outside ``cells``); ``seed`` is a distinct int32 per cell
    in [0, cells.size) (a flat index) or a shared smaller value. ``corners``: 26-connectivity
    (else 6).

    Rounds of (a) the smallest label among each cell and its neighbours, (b) hooking: that value
    also lowers the label of the cell the label names (a scatter-min), (c) ``jumps`` pointer jumps
    (a label names a cell of the same component, whose label is at most it); until nothing
    changes (FastSV, Zhang et al. 2020: O(log n) rounds on most grids).
    """
    size = cells.size
    neighbours = _window if corners else _cross
    labels = jnp.where(cells, seed, _BIG).reshape(-1)
    flat_cells = cells.reshape(-1)

    def cond(state):
        return state[1]

    def body(state):
        lab, _ = state
        low = jnp.where(flat_cells, neighbours(lab.reshape(cells.shape), jnp.minimum, _BIG).reshape(-1), _BIG)
        parent = jnp.where(flat_cells, jnp.minimum(lab, size - 1), size)  # size: dropped
        new = lab.at[parent].min(low, mode="drop")
        new = jnp.minimum(new, low)
        for _ in range(jumps):
            new = jnp.where(flat_cells, new[jnp.minimum(new, size - 1)], _BIG)
        return new, jnp.any(new != lab)

    labels, _ = lax.while_loop(cond, body, (labels, jnp.array(True)))
    return labels.reshape(cells.shape)


def _border(shape):
    out = jnp.zeros(shape, bool)
    for a in range(3):
        idx = lax.broadcasted_iota(jnp.int32, shape, a)
        out = out | (idx == 0) | (idx == shape[a] - 1)
    return out


def exterior_fill(solid):
    """``solid`` with its enclosed cavities filled: the cells not 6-connected to the grid border
    through cells outside the solid (``scipy.ndimage.binary_fill_holes``). (a, b, c) bool.

    A flood from the free border cells on the grid packed 32 cells to a word (:func:`.bits.flood`)."""
    free = ~solid
    c = solid.shape[-1]
    outside = bits.flood(bits.pack(free & _border(solid.shape)), bits.pack(free), c)
    return solid | ~bits.unpack(outside, c)


def components(solid):
    """26-connected component labels of ``solid``: each cell's label is the smallest flat index
    of its component (_BIG outside). (g, g, g) int32."""
    return _label(solid, jnp.arange(solid.size, dtype=jnp.int32).reshape(solid.shape), corners=True)


def keep_main(solid, keep_ratio):
    """The components of ``solid`` that are the main body or at least ``keep_ratio`` of its size
    (boundary cells: ``solid`` minus its 6-neighbour erosion), as :func:`jaxpose.occupancy.solid.keep_main`.
    The components are labelled by runs (:mod:`.runs`); a grid with more runs than
    :func:`.runs.default_cap` is labelled cell by cell (:func:`components`).

    Returns:
      kept (g, g, g) bool, components () int32, dropped () int32.
    """
    c = solid.shape[-1]
    packed = bits.pack(solid)
    found = runs.find_runs(packed, c, runs.default_cap(solid.shape))
    return runs.either(~found.fits, partial(_keep_cells, keep_ratio=keep_ratio),
                       partial(_keep_runs, keep_ratio=keep_ratio), solid, packed, found)


def _keep_runs(solid, packed, found, keep_ratio):
    """:func:`keep_main` on the runs of ``solid`` (``found.fits``)."""
    c = solid.shape[-1]
    cap = found.first.shape[0]
    labels = run_labels(found, solid.shape)
    size = runs.run_counts(found, bits.erode6(packed) ^ packed, c)  # boundary cells per run
    total = jnp.zeros(cap, jnp.int32).at[labels].add(size, mode="drop")
    roots = found.valid & (labels == jnp.arange(cap, dtype=jnp.int32))
    big = jnp.max(total)
    keep_root = roots & (total.astype(jnp.float32) >= keep_ratio * big.astype(jnp.float32))
    kept = bits.unpack(runs.paint(found, keep_root[jnp.minimum(labels, cap - 1)], packed, c), c)
    return kept, jnp.sum(roots).astype(jnp.int32), jnp.sum(roots & ~keep_root).astype(jnp.int32)


def _keep_cells(solid, packed, found, keep_ratio):
    """:func:`keep_main` cell by cell (any grid)."""
    del packed, found
    labels = components(solid)
    boundary = solid & ~erode6(solid)
    safe = jnp.where(solid, labels, 0).reshape(-1)
    size = jnp.zeros(solid.size, jnp.int32).at[safe].add(boundary.reshape(-1).astype(jnp.int32))
    roots = (labels.reshape(-1) == jnp.arange(solid.size, dtype=jnp.int32))
    big = jnp.max(size)
    keep_root = roots & (size.astype(jnp.float32) >= keep_ratio * big.astype(jnp.float32))
    kept = solid & keep_root[safe].reshape(solid.shape)
    return kept, jnp.sum(roots).astype(jnp.int32), jnp.sum(roots & ~keep_root).astype(jnp.int32)


def _blocks(x, op):
    """op over the 2 x 2 x 2 blocks of a (g, g, g) grid (padded with zeros to an even size)."""
    pad = x.shape[0] % 2
    x = jnp.pad(x, [(0, pad)] * 3)
    h = x.shape[0] // 2
    return op(x.reshape(h, 2, h, 2, h, 2), axis=(1, 3, 5))


def linked_parts(occupied, near):
    """The second largest separate part of a point cloud over the largest, as
    :func:`jaxpose.occupancy.solid.linked_parts`: the 26-connected components of ``near`` (the
    occupied voxels dilated by the linkage, at least 2 voxels; it holds ``occupied``), sized by the
    occupied voxels each holds. The components are taken on 2 x 2 x 2 blocks (a block is in
    ``near`` when any of its voxels is: 1/8 of the cells to label), which links parts at most 2
    voxels further apart than the linkage does. () float32, 0 when the points are one part (or none)."""
    cells = _blocks(near, jnp.any)
    count = _blocks(occupied.astype(jnp.int32), jnp.sum).astype(jnp.int32)  # int64 sums under x64
    packed = bits.pack(cells)
    found = runs.find_runs(packed, cells.shape[-1], runs.default_cap(cells.shape))
    return runs.either(~found.fits, _parts_cells, _parts_runs, cells, count, found)


def _parts_runs(cells, count, found):
    """:func:`linked_parts` on the runs of the blocks (``found.fits``)."""
    cap = found.first.shape[0]
    labels = run_labels(found, cells.shape)
    size = jnp.zeros(cap, jnp.int32).at[labels].add(runs.run_sums(found, count), mode="drop")
    return _second_over_largest(size)


def _parts_cells(cells, count, found):
    """:func:`linked_parts` block by block (any grid)."""
    del found
    labels = components(cells).reshape(-1)
    size = jnp.zeros(cells.size, jnp.int32).at[jnp.where(cells.reshape(-1), labels, 0)].add(count.reshape(-1))
    return _second_over_largest(size)


def _second_over_largest(size):
    largest = jnp.argmax(size)
    second = jnp.max(jnp.where(jnp.arange(size.shape[0]) == largest, 0, size))
    return second.astype(jnp.float32) / jnp.maximum(size[largest], 1).astype(jnp.float32)


# ------------------------------------------------------------------ one pass
def _occupied(points, mask, origin, pitch, cells):
    idx = jnp.floor((points - origin) / pitch).astype(jnp.int32)
    ok = mask & jnp.all((idx >= 0) & (idx < cells), axis=1)
    idx = jnp.where(ok[:, None], idx, cells)  # out of range: dropped
    occ = jnp.zeros((cells,) * 3, bool)
    return occ.at[idx[:, 0], idx[:, 1], idx[:, 2]].set(True, mode="drop")


def _closing(occ, radius, max_radius, rmax):
    """Closing of the occupied voxels with the adaptive radius (module docs, step 3), radii up to
    ``max_radius`` (traced) <= ``rmax`` (static); also the packed occupied voxels.

    One ``lax.while_loop`` whose body is one attempt (the first at ``radius``, each later one at a
    grown radius), so the attempt is compiled once; the two dilations of the complements (the
    closing's erosion and the shell's) are one vmapped :func:`.bits.dilate_ball`."""
    c = occ.shape[-1]
    packed = bits.pack(occ)

    def attempt(r):
        r2 = r * r
        dil = bits.unpack(bits.dilate_ball(packed, r2, rmax), c)
        filled = exterior_fill(dil)
        holes = bits.pack(jnp.stack([~filled, ~dil]))
        closed, shell = ~bits.unpack(jax.vmap(bits.dilate_ball, (0, None, None))(holes, r2, rmax), c)
        return closed, jnp.sum(closed) >= 1.2 * jnp.sum(shell)

    def cond(state):
        return ~state[2]

    def body(state):
        r, _, _, first = state
        r = jnp.where(first, r, jnp.minimum(r + jnp.maximum(1, r // 4), max_radius))
        closed, ok = attempt(r)
        return r, closed, ok | (r >= max_radius), jnp.array(False)

    start = (radius, jnp.zeros_like(occ), jnp.array(False), jnp.array(True))
    r, closed, _, _ = lax.while_loop(cond, body, start)
    return closed | occ, r, packed


def _pass(points, mask, lo, hi, q, resolution, config):
    """One grid on the box [lo, hi]: (solid, occupied, origin, pitch, radius used, the occupied
    voxels dilated by ``LINK`` times the starting radius)."""
    cells = grid_cells(resolution, config.max_closing)
    pitch = jnp.maximum(jnp.max(hi - lo) / resolution, q / config.max_closing)
    radius = jnp.clip(jnp.ceil(q / pitch), 1, config.max_closing).astype(jnp.int32)
    margin = 3 * radius + 3
    origin = lo - (margin.astype(pitch.dtype) + GRID_OFFSET) * pitch
    occ = _occupied(points, mask, origin, pitch, cells)
    rmax = max(3, LINK) * config.max_closing
    solid, r, packed = _closing(occ, radius, 3 * radius, rmax)
    near = bits.unpack(bits.dilate_ball(packed, (LINK * radius) ** 2, rmax), cells)
    return solid, occ, origin, pitch, r, near


def point_solid(points, mask, queries, config: RobustConfig, query_mask=None) -> PointSolid:
    """The kept solid of a point cloud (module docs); pure JAX, no input checks.

    Args:
      points: (n, 3) float, coordinates of order 1 are best (float32 resolves them to ~1e-7).
      mask: (n,) bool or None; False rows are padding.
      queries: (m,) int, the points whose spacing is measured (:func:`spacing_subset`);
        query_mask: (m,) bool or None (False: padding).
      config: :class:`jaxpose.config.RobustConfig` (static).

    Returns:
      :class:`PointSolid`; its ``inside`` is empty when the points enclose no volume.
    """
    n = points.shape[0]
    mask = jnp.ones((n,), bool) if mask is None else jnp.asarray(mask, bool)
    queries = jnp.asarray(queries, jnp.int32)
    query_mask = jnp.ones(queries.shape, bool) if query_mask is None else jnp.asarray(query_mask, bool)
    q = spacing_quantile(points, mask, queries, query_mask & mask[queries])
    big = jnp.asarray(jnp.finfo(points.dtype).max, points.dtype)
    lo = jnp.min(jnp.where(mask[:, None], points, big), axis=0)
    hi = jnp.max(jnp.where(mask[:, None], points, -big), axis=0)
    # pass 1: the main body over everything
    solid1, _, origin1, pitch1, _, _ = _pass(points, mask, lo, hi, q, config.coarse, config)
    kept1 = keep_main(solid1, config.keep_ratio)[0]
    near = _window(kept1, jnp.logical_or, False)
    cells1 = near.shape[0]
    idx = jnp.clip(jnp.floor((points - origin1) / pitch1).astype(jnp.int32), -1, cells1)
    inb = jnp.all((idx >= 0) & (idx < cells1), axis=1)
    cl = jnp.clip(idx, 0, cells1 - 1)
    on = mask & inb & near[cl[:, 0], cl[:, 1], cl[:, 2]]
    found = jnp.any(on)
    lo = jnp.where(found, jnp.min(jnp.where(on[:, None], points, big), axis=0), lo)
    hi = jnp.where(found, jnp.max(jnp.where(on[:, None], points, -big), axis=0), hi)
    # pass 2: the fine grid on the main body's box
    solid, occ, origin, pitch, r, near = _pass(points, mask, lo, hi, q, config.resolution, config)
    kept, count, dropped = keep_main(exterior_fill(solid), config.keep_ratio)
    return PointSolid(kept, occ, origin, pitch, r, count, dropped, linked_parts(occ, near))
