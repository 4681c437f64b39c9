"""Grids that provably cover the SVDD region {f >= 0}, and f evaluated on them.

Bound: sum(alpha) = 1 and k <= 1, so 2 k(x)^T alpha <= 2 max_{i: alpha_i > 0} k(x, x_i)
= 2 exp(-gamma d(x)^2), d the distance to the nearest support vector. Hence
f(x) >= 0 implies d(x) <= r = sqrt(ln(2 / mu) / gamma): the region lies in the
bounding box of the support vectors grown by r on every side.

That box moves continuously with gamma and nu (r depends on both), and with it every
cell of the grid: the discretization error would then vary with gamma at the scale of a
cell shift, and derivatives that hold the grid fixed would not be the derivatives of the
computed moments. ``domain`` therefore snaps the box outwards to a lattice of spacing
q = 2^floor(log2 extent) / 64 (at most 1/64 of the extent): the grid is piecewise constant in
(gamma, nu), moving only when a face crosses a lattice line, and the moments are
differentiable with the grid held fixed in between. The lattice is symmetric about the origin, so the box is
equivariant under the axis flips and permutations of the principal frame.
"""
from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .kernels import map_blocks
from .runs import running_sum

__all__ = ["region_radius", "domain", "snap", "cell_centers", "morton_order", "morton_codes", "evaluate_on_grid",
           "evaluate_on_grid_jvp", "evaluate_subgrids", "evaluate_children", "evaluate_grid", "first_true"]


def region_radius(svdd):
    """r such that {f >= 0} lies within distance r of the support vectors. () float."""
    mu = jnp.maximum(svdd.offset, jnp.finfo(svdd.alpha.dtype).tiny)
    return jnp.sqrt(jnp.maximum(jnp.log(2.0 / mu), 0.0) / svdd.gamma)


LATTICE = 64  # the box snaps to a lattice of spacing (power of 2) in (extent / 128, extent / 64]


def snap(lo, hi, lattice=LATTICE):
    """(lo, hi) grown outwards to multiples of q = 2^floor(log2 max(hi - lo)) / lattice."""
    ext = jnp.max(hi - lo)
    ok = jnp.isfinite(ext) & (ext > 0)
    q = jnp.exp2(jnp.floor(jnp.log2(jnp.where(ok, ext, 1.0)))) / lattice
    return jnp.where(ok, jnp.floor(lo / q) * q, lo), jnp.where(ok, jnp.ceil(hi / q) * q, hi)


def domain(svdd):
    """(lo, hi) : (3,), (3,) box containing {f >= 0}, snapped to a lattice (module docs);
    piecewise constant in gamma and nu, not differentiated."""
    svdd = jax.lax.stop_gradient(svdd)
    sv = (svdd.alpha > 0)[:, None]
    inf = jnp.asarray(jnp.inf, svdd.points.dtype)
    lo = jnp.min(jnp.where(sv, svdd.points, inf), axis=0)
    hi = jnp.max(jnp.where(sv, svdd.points, -inf), axis=0)
    r = region_radius(svdd)
    return snap(lo - r, hi + r)


def cell_centers(lo, hi, resolution):
    """Centers of a resolution^3 grid of equal boxes tiling [lo, hi].

    -> x : (resolution^3, 3), h : (3,) cell edge lengths
    """
    h = (hi - lo) / resolution
    i = jnp.arange(resolution, dtype=lo.dtype) + 0.5
    axes = [lo[k] + h[k] * i for k in range(3)]
    x = jnp.stack(jnp.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    return x, h


def first_true(mask, size, fill_value=0):
    """The indices of the first ``size`` True entries of mask (n,) bool, in index order, then
    ``fill_value``: (size,) int32, ``jnp.nonzero(mask, size=size, fill_value=fill_value)[0]``
    from one running count (:func:`jaxpose.occupancy.runs.running_sum`) and a scatter.

    Example::

        >>> first_true(jnp.array([False, True, True, False, True]), 4, fill_value=9)
        Array([1, 2, 4, 9], dtype=int32)
    """
    dest = jnp.where(mask, running_sum(mask.astype(jnp.int32)) - 1, size)  # the rank of each True entry; others dropped
    return jnp.full((size,), fill_value, jnp.int32).at[dest].set(jnp.arange(mask.shape[0], dtype=jnp.int32),
                                                                  mode="drop")


SV_CHUNK = 256
MORTON_BITS = 10  # per axis: 30-bit codes fit int32


def _spread_bits(v):
    """Insert two zero bits between the low 10 bits of v (int array, jnp or numpy): 0b1011 -> 0b001000001001."""
    v = v & 0x3FF
    v = (v | (v << 16)) & 0x030000FF
    v = (v | (v << 8)) & 0x0300F00F
    v = (v | (v << 4)) & 0x030C30C3
    return (v | (v << 2)) & 0x09249249


def _interleave(q):
    """Morton code of integer lattice coordinates q : (n, 3) (x bits highest)."""
    return _spread_bits(q[:, 0]) << 2 | _spread_bits(q[:, 1]) << 1 | _spread_bits(q[:, 2])


def morton_codes(x, lo, hi):
    """Z-order codes of x : (n, 3) on a 2^10 lattice over the box [lo, hi] (points outside are
    clamped). -> (n,) int32; sorting by them keeps nearby points together."""
    ext = jnp.maximum(jnp.max(hi - lo), jnp.finfo(x.dtype).tiny)
    q = jnp.clip(jnp.floor((x - lo) / ext * (2**MORTON_BITS)), 0, 2**MORTON_BITS - 1).astype(jnp.int32)
    return _interleave(q)


def morton_order(resolution):
    """Static permutation (numpy) of the rows of ``cell_centers(.., resolution)`` into Z-order,
    so that consecutive blocks of cells are compact in space."""
    i = np.arange(resolution)
    ijk = np.stack(np.meshgrid(i, i, i, indexing="ij"), axis=-1).reshape(-1, 3)
    return np.argsort(_interleave(ijk), kind="stable")


def _cutoff(mu, dtype):
    """gamma d^2 beyond which a chunk of points is dropped: 2 sum(a) exp(-gamma d^2) <= 2 exp(-cut)
    is below eps * mu / 16, a sixteenth of f's own rounding at the boundary (f + mu = 2 k^T a)."""
    eps = jnp.finfo(dtype).eps
    return jnp.log(32.0 / (eps * jnp.maximum(mu, jnp.finfo(dtype).tiny)))


class _Chunks(NamedTuple):
    """The support points in chunks of nearby points (Z-order), shifted by ``shift``."""

    shift: jax.Array  # (3,)
    p: jax.Array  # (k, chunk, 3)
    w: jax.Array  # (k, chunk, 4) (alpha, alpha p), alpha 0 off the support: f and grad f are w-sums
    c: jax.Array  # (k, chunk) bool, on the support
    lo: jax.Array  # (k, 3) bounding box of each chunk's support points (no derivatives)
    hi: jax.Array
    cut: jax.Array  # () squared distance beyond which a chunk's terms are dropped
    dw: jax.Array | None = None  # (k, chunk, 4) (dalpha, dalpha p) in the same order, if asked for


def _chunks(svdd, support=None, dalpha=None):
    shift = jax.lax.stop_gradient(jnp.mean(svdd.points, axis=0))
    m = svdd.points.shape[0]
    chunk = min(SV_CHUNK, m)
    pad = (-m) % chunk
    sup = jax.lax.stop_gradient(svdd.alpha != 0 if support is None else support)
    p0 = jax.lax.stop_gradient(svdd.points - shift)
    code = morton_codes(p0, jnp.min(p0, axis=0), jnp.max(p0, axis=0))
    order = jnp.argsort(jnp.where(sup, code, jnp.iinfo(jnp.int32).max))
    p = jnp.concatenate([(svdd.points - shift)[order], jnp.zeros((pad, 3), svdd.points.dtype)])
    c = jnp.concatenate([sup[order], jnp.zeros((pad,), bool)])
    p, c = p.reshape(-1, chunk, 3), c.reshape(-1, chunk)

    def weights(alpha):  # (alpha, alpha p) per chunk; terms off the support are dropped (their tangents too)
        a = jnp.concatenate([alpha[order], jnp.zeros((pad,), alpha.dtype)]).reshape(-1, chunk)
        a = jnp.where(c, a, 0.0)
        return jnp.concatenate([a[..., None], a[..., None] * p], axis=-1)

    w, dw = weights(svdd.alpha), None if dalpha is None else weights(dalpha)
    ps = jax.lax.stop_gradient(p)
    inf = jnp.asarray(jnp.inf, p.dtype)
    lo = jnp.min(jnp.where(c[..., None], ps, inf), axis=1)
    hi = jnp.max(jnp.where(c[..., None], ps, -inf), axis=1)
    cut = jax.lax.stop_gradient(_cutoff(svdd.offset, p.dtype) / svdd.gamma)
    return _Chunks(shift, p, w, c, lo, hi, cut, dw)


def _sum_near(ch, blo, bhi, terms, init, table=None):
    """Sum terms(p, w) (a pytree like init) over the chunks not too far from the box [blo, bhi];
    terms(p, w, table[i]) with a per-chunk table."""
    gap = jnp.maximum(0.0, jnp.maximum(ch.lo - bhi, blo - ch.hi))
    near = jnp.any(ch.c, axis=1) & (jnp.sum(gap * gap, axis=-1) <= ch.cut)

    def add_chunk(acc, chunk_):
        keep, args = chunk_[0], chunk_[1:]
        zero = lambda _: jax.tree_util.tree_map(jnp.zeros_like, init)
        t = jax.lax.cond(keep, lambda _: terms(*args), zero, None)
        return jax.tree_util.tree_map(jnp.add, acc, t), None

    acc, _ = jax.lax.scan(add_chunk, init, (near, ch.p, ch.w) + (() if table is None else (table,)))
    return acc


def evaluate_on_grid(svdd, x, block=2048, count=None, support=None):
    """f and grad f at x : (n, 3), in blocks of rows. -> (n,), (n, 3).

    count : optional () int: only the blocks holding rows < count are evaluated (``lax.cond``),
    the others give f = 0, grad f = 0 (used to differentiate at a compacted set of cells).
    support : optional (m,) bool, the points whose terms are summed (default alpha != 0); the
    others' terms are dropped, with their tangents (``moments`` adds those separately).

    grad f = -4 gamma sum_i alpha_i k(x, x_i) (x - x_i). Distances come from one
    matrix product, |x|^2 + |p|^2 - 2 x.p; both sides are shifted by the points' mean first so
    the expansion loses little accuracy.
    The support is taken in chunks of nearby points (Z-order). A chunk is skipped (``lax.cond``)
    when it holds no support point, or when its bounding box lies so far from the block's that
    its terms sum to less than eps * mu / 16 (``_cutoff``; Sum a = 1): below f's rounding, in
    float32 and float64 alike. Blocks of nearby cells (``morton_order``) make that common.
    """
    ch = _chunks(svdd, support)
    g, mu = svdd.gamma, svdd.offset

    def one_block(xb):
        xb = xb - ch.shift
        xn = jnp.sum(xb * xb, axis=-1)[:, None]
        xs = jax.lax.stop_gradient(xb)

        def terms(pc, wc):  # one (n, chunk) @ (chunk, 4) product gives f and grad f
            d2 = jnp.maximum(xn + jnp.sum(pc * pc, axis=-1)[None, :] - 2.0 * xb @ pc.T, 0.0)
            return jnp.exp(-g * d2) @ wc

        r = _sum_near(ch, jnp.min(xs, axis=0), jnp.max(xs, axis=0), terms, jnp.zeros((xb.shape[0], 4), xb.dtype))
        s, ep = r[:, 0], r[:, 1:]
        return 2.0 * s - mu, -4.0 * g * (xb * s[:, None] - ep)

    return map_blocks(one_block, x, block, count=count)


def evaluate_on_grid_jvp(svdd, tangent, x, block=2048, count=None, support=None):
    """f, grad f at x : (n, 3) and their tangents along ``tangent`` = (dalpha (m,), dgamma (),
    doffset ()), the points held fixed: -> f (n,), grad (n, 3), df (n,), dgrad (n, 3).

    With e_i = exp(-gamma d_i^2), s = sum a_i e_i and u = x s - sum a_i e_i p_i
    (f = 2 s - mu, grad f = -4 gamma u):

        ds = sum da_i e_i - dgamma sum a_i d_i^2 e_i,   du = x ds - (the same sums with p_i),
        df = 2 ds - dmu,   dgrad = -4 dgamma u - 4 gamma du,

    the derivatives :func:`evaluate_on_grid` has, from one pass over the chunks: each kernel block
    e is computed once and multiplied by (a, a p), (da, da p) and, as e * d^2, by (a, a p). Under
    ``vmap`` over tangents only the (da, da p) product is batched. Same chunks, cutoff, ``count``
    and ``support`` (the points whose terms are summed, with their tangents) as
    :func:`evaluate_on_grid`.
    """
    dalpha, dgamma, doffset = tangent
    ch = _chunks(svdd, support, dalpha)
    g, mu = svdd.gamma, svdd.offset

    def one_block(xb):
        xb = xb - ch.shift
        xn = jnp.sum(xb * xb, axis=-1)[:, None]

        def terms(pc, wc, dwc):
            d2 = jnp.maximum(xn + jnp.sum(pc * pc, axis=-1)[None, :] - 2.0 * xb @ pc.T, 0.0)
            e = jnp.exp(-g * d2)
            return e @ wc, e @ dwc, (e * d2) @ wc

        zero = jnp.zeros((xb.shape[0], 4), xb.dtype)
        r, dr, r2 = _sum_near(ch, jnp.min(xb, axis=0), jnp.max(xb, axis=0), terms, (zero, zero, zero), ch.dw)
        ds = dr - dgamma * r2  # (n, 4): ds and sum (da_i e_i - dgamma a_i d_i^2 e_i) p_i
        u = xb * r[:, :1] - r[:, 1:]
        du = xb * ds[:, :1] - ds[:, 1:]
        return 2.0 * r[:, 0] - mu, -4.0 * g * u, 2.0 * ds[:, 0] - doffset, -4.0 * dgamma * u - 4.0 * g * du

    return map_blocks(one_block, x, block, count=count)


def evaluate_subgrids(svdd, corners, h, n, block=2048, count=None):
    """f and grad f at the centers of n x n x n cells of size h : (3,) tiling a box from each
    lower corner in corners : (b, 3). -> f (b, n^3), grad (b, n^3, 3); cell (i, j, k) of a box
    is row (i n + j) n + k, centered at corner + (i + 1/2, j + 1/2, k + 1/2) h.

    Separable (the grids are tensor products): exp(-gamma |x - p|^2) is the product of one
    factor per axis, so each box and support point costs 3 n exponentials and a batched matrix
    product instead of n^3 exponentials. Same chunks, cutoff and ``count`` as
    ``evaluate_on_grid``; no derivatives (used under ``stop_gradient``).
    """
    svdd = jax.lax.stop_gradient(svdd)
    ch = _chunks(svdd)
    g, mu = svdd.gamma, svdd.offset
    off = (jnp.arange(n, dtype=corners.dtype) + 0.5)[None, :, None] * h  # (1, n, 3)

    def one_block(cb):
        X = (cb - ch.shift)[:, None, :] + off  # (bb, n, 3): the cells' coordinates per axis
        bb = X.shape[0]

        def terms(pc, wc):
            e = jnp.exp(-g * (X[:, :, None, :] - pc) ** 2)  # (bb, n, chunk, 3)
            exy = (e[:, :, None, :, 0] * e[:, None, :, :, 1]).reshape(bb, n * n, -1)
            ez = (e[..., 2][..., None] * wc).transpose(0, 2, 1, 3).reshape(bb, -1, n * 4)
            return jnp.einsum("bap,bpq->baq", exy, ez)

        r = _sum_near(ch, jnp.min(X[:, 0], axis=0), jnp.max(X[:, -1], axis=0), terms,
                      jnp.zeros((bb, n * n, n * 4), X.dtype)).reshape(bb, n, n, n, 4)
        s, ep = r[..., 0], r[..., 1:]
        x = jnp.stack(jnp.broadcast_arrays(X[:, :, None, None, 0], X[:, None, :, None, 1], X[:, None, None, :, 2]), -1)
        grad = -4.0 * g * (x * s[..., None] - ep)
        return (2.0 * s - mu).reshape(bb, n**3), grad.reshape(bb, n**3, 3)

    return map_blocks(one_block, corners, max(1, block // n**3), count=count)


# bytes of the per-axis factor tables of ``evaluate_children`` beyond which it evaluates directly
TABLE_BYTES = 1 << 28

# the 8 children of a cell, offsets from its center in units of its size; child 4 a + 2 b + c
CHILD_OFFSETS = np.stack(np.meshgrid(*[np.array([-0.25, 0.25])] * 3, indexing="ij"), axis=-1).reshape(8, 3)


def evaluate_children(svdd, lo, h, cells, n, block=512, count=None):
    """f and grad f at the 8 children of cells : (k, 3), centers of cells of size h : (3,) on the
    lattice lo + (i + 1/2) h (i integer), on a box of n / 2 of them per axis (n static).
    -> f (k, 8), grad (k, 8, 3); child i is at the cell's center + CHILD_OFFSETS[i] h.

    The children lie on a lattice of n points per axis, where exp(-gamma |x - p|^2) factors per
    axis: the factors of every lattice line and support point are tabulated once (3 n m
    exponentials), and each cell's 8 children cost 12 products and a (8, chunk) @ (chunk, 4)
    product per chunk, no exponential; products of tabulated factors also keep more digits in
    float32 than the expanded distances. Same chunks, cutoff and ``count`` (in cells) as
    ``evaluate_on_grid``; no derivatives.
    Tables over ``TABLE_BYTES`` (n m > ~2e7 in float32): the children are evaluated directly.
    """
    svdd = jax.lax.stop_gradient(svdd)
    dtype = svdd.points.dtype
    if 3 * n * svdd.points.shape[0] * jnp.dtype(dtype).itemsize > TABLE_BYTES:
        x = (cells[:, None, :] + jnp.asarray(CHILD_OFFSETS, dtype) * h).reshape(-1, 3)
        c8 = None if count is None else 8 * count
        f, grad = evaluate_on_grid(svdd, x, 4 * block, c8)
        return f.reshape(-1, 8), grad.reshape(-1, 8, 3)
    ch = _chunks(svdd)
    g, mu = svdd.gamma, svdd.offset
    hc = h / 2
    t = lo - ch.shift + (jnp.arange(n, dtype=dtype)[:, None] + 0.5) * hc  # (n, 3) lattice lines per axis
    table = jnp.exp(-g * (t.T[None, :, :, None] - jnp.swapaxes(ch.p, 1, 2)[:, :, None, :]) ** 2)  # (chunks, 3, n, chunk)
    two = jnp.arange(2)[None, :, None]
    ijk = jnp.round((cells - lo) / h - 0.5).astype(jnp.int32)

    def one_block(ib):
        b = ib.shape[0]
        rows = 2 * ib[:, None, :] + two  # (b, 2, 3): the children's lattice lines
        xc = lo - ch.shift + (rows + 0.5) * hc

        def terms(pc, wc, e):
            ex, ey, ez = (e[a][rows[:, :, a]] for a in range(3))  # (b, 2, chunk)
            exy = (ex[:, :, None] * ey[:, None]).reshape(b, 4, -1)
            return (exy[:, :, None] * ez[:, None]).reshape(8 * b, -1) @ wc

        r = _sum_near(ch, jnp.min(xc[:, 0], axis=0), jnp.max(xc[:, 1], axis=0), terms, jnp.zeros((8 * b, 4), dtype), table)
        s, ep = r[:, 0], r[:, 1:]
        x = jnp.stack(jnp.broadcast_arrays(xc[:, :, None, None, 0], xc[:, None, :, None, 1], xc[:, None, None, :, 2]), -1)
        grad = -4.0 * g * (x.reshape(-1, 3) * s[:, None] - ep)
        return (2.0 * s - mu).reshape(b, 8), grad.reshape(b, 8, 3)

    return map_blocks(one_block, ijk, block, count=count)


SUBGRID = 32  # cells per axis of the boxes the coarse grid is evaluated in


def _coarse_layout(resolution):
    """Static (numpy): the grid of resolution^3 cells split into k^3 boxes of n^3 cells
    (k n >= resolution; cells past the grid are evaluated and dropped). -> k, n, and for each
    cell in ``morton_order`` (also returned) its row in the flattened (k^3 n^3) output of
    ``evaluate_subgrids``."""
    k = -(-resolution // SUBGRID)
    n = -(-resolution // k)
    order = morton_order(resolution)
    ijk = np.stack(np.unravel_index(order, (resolution,) * 3), axis=-1)
    b, s = ijk // n, ijk % n
    rows = ((b[:, 0] * k + b[:, 1]) * k + b[:, 2]) * n**3 + (s[:, 0] * n + s[:, 1]) * n + s[:, 2]
    return k, n, order, rows


def evaluate_grid(svdd, lo, hi, resolution, block=2048):
    """The cells of ``cell_centers(lo, hi, resolution)`` in ``morton_order`` with f and grad f
    there (separable, ``evaluate_subgrids``; no derivatives).
    -> x (resolution^3, 3), h (3,), f (resolution^3,), grad (resolution^3, 3)."""
    x, h = cell_centers(lo, hi, resolution)
    k, n, order, rows = _coarse_layout(resolution)
    b = np.stack(np.unravel_index(np.arange(k**3), (k,) * 3), axis=-1)
    f, grad = evaluate_subgrids(svdd, lo + jnp.asarray(b * n, lo.dtype) * h, h, n, block)
    return x[order], h, f.reshape(-1)[rows], grad.reshape(-1, 3)[rows]
