"""Boolean grids packed 32 cells to a word, and the flood fill that runs on them.

A (..., c) bool grid is packed along its last axis into (..., ceil(c / 32)) uint32 words: cell k
of a line is bit k % 32 of word k // 32 (the padding bits of the last word are 0). A bitwise
AND / OR over words then does 32 cells at once, and a shift along the packed axis moves every
cell of a line in a few word operations.

:func:`flood` spreads seed cells through the free cells of a 3-D grid, 6-connected: each round
spreads them along the packed axis through whole runs of free cells (log-step doubling,
Kogge-Stone) and one cell along the two other axes, until nothing changes. The rounds needed
follow the turns of the longest path, not its length.

:func:`dilate_ball` dilates by the Euclidean ball {dx^2 + dy^2 + dz^2 <= r^2} (r^2 traced): the
lines dilated along the packed axis by w = 0 .. rmax cells once, then for each (dy, dz) of the
disk the line dilated by w = floor(sqrt(r^2 - dy^2 - dz^2)), moved by (dy, dz), OR-ed in.

Example::

    reached = unpack(flood(pack(seeds & free), pack(free)), free.shape[-1])
"""
from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax

__all__ = ["pack", "unpack", "shift_bits", "spread_runs", "erode6", "flood", "dilate_ball"]

_WORD = 32
_BIT = np.arange(_WORD, dtype=np.uint32)


def pack(x) -> jax.Array:
    """(..., c) bool -> (..., ceil(c / 32)) uint32; cell k is bit k % 32 of word k // 32."""
    c = x.shape[-1]
    words = -(-c // _WORD)
    x = jnp.pad(jnp.asarray(x, bool), [(0, 0)] * (x.ndim - 1) + [(0, words * _WORD - c)])
    x = x.reshape(x.shape[:-1] + (words, _WORD)).astype(jnp.uint32)
    return jnp.sum(x << _BIT, axis=-1, dtype=jnp.uint32)  # distinct bits: the sum is their OR


def unpack(w, c: int) -> jax.Array:
    """(..., words) uint32 -> (..., c) bool, the inverse of :func:`pack`."""
    bits = (w[..., None] >> _BIT) & jnp.uint32(1)
    return bits.reshape(w.shape[:-1] + (-1,))[..., :c].astype(bool)


def _shift_words(w, k: int):
    """Words moved k places to higher (k > 0) or lower (k < 0) index along the last axis, zeros in."""
    n = w.shape[-1]
    if k == 0:
        return w
    if abs(k) >= n:
        return jnp.zeros_like(w)
    zeros = jnp.zeros(w.shape[:-1] + (abs(k),), w.dtype)
    return jnp.concatenate([zeros, w[..., : n - k]], -1) if k > 0 else jnp.concatenate([w[..., -k:], zeros], -1)


def shift_bits(w, s):
    """Packed lines with cell k moved to k + s, zeros shifted in. ``s``: a Python int (either
    sign; word moves and bit shifts by constants) or a traced int32 scalar (the same cells, from
    dynamic slices of the lines padded with zero words: one compiled shift for every amount, as
    in the rolled loops of :func:`spread_runs` and :func:`dilate_ball`)."""
    if not isinstance(s, (int, np.integer)):
        return _shift_traced(w, s)
    k, r = divmod(abs(s), _WORD)
    sign = 1 if s > 0 else -1
    w = _shift_words(w, sign * k)
    if r == 0:
        return w
    up, down = np.uint32(r), np.uint32(_WORD - r)
    if s > 0:
        return (w << up) | (_shift_words(w, 1) >> down)
    return (w >> up) | (_shift_words(w, -1) << down)


def _shift_traced(w, s):
    """:func:`shift_bits` by a traced amount ``s`` (int scalar, either sign)."""
    n = w.shape[-1]
    s = jnp.asarray(s, jnp.int32)
    k = jnp.minimum(jnp.abs(s) // _WORD, n + 1)  # whole words; n + 1 or more: nothing left
    r = (jnp.abs(s) % _WORD).astype(jnp.uint32)
    zeros = jnp.zeros(w.shape[:-1] + (n + 1,), w.dtype)
    padded = jnp.concatenate([zeros, w, zeros], -1)  # the line at words n + 1 .. 2 n
    up = s > 0
    start = jnp.where(up, n + 1 - k, n + 1 + k)
    main = lax.dynamic_slice_in_dim(padded, start, n, -1)  # words moved by k
    spill = lax.dynamic_slice_in_dim(padded, jnp.where(up, start - 1, start + 1), n, -1)  # by k + 1
    left = jnp.uint32(_WORD) - jnp.maximum(r, jnp.uint32(1))  # r = 0 takes ``main`` alone below
    moved = jnp.where(up, (main << r) | (spill >> left), (main >> r) | (spill << left))
    return jnp.where(r == 0, main, moved)


def _step(w, axis: int, d: int):
    """Words moved one place along an unpacked ``axis`` (d = +1 or -1), zeros in."""
    n = w.shape[axis]
    pad = [(0, 0)] * w.ndim
    pad[axis] = (1, 0) if d > 0 else (0, 1)
    p = jnp.pad(w, pad)
    return lax.slice_in_dim(p, 0, n, axis=axis) if d > 0 else lax.slice_in_dim(p, 1, n + 1, axis=axis)


def spread_runs(seeds, free, c: int):
    """``seeds`` spread through the runs of ``free`` along the packed axis (lines of c cells), both
    ways: the free cells joined to a seed by free cells of their line. Packed (..., words) uint32.

    Log-step doubling per direction (a ``lax.fori_loop`` over the steps s = 1, 2, 4, ... < c):
    ``reach |= open & shift(reach, s)``, ``open &= shift(open, s)``, where ``open`` holds the
    cells whose next s cells (this way) are all free."""
    steps = (c - 1).bit_length()
    for sign in (1, -1):
        def step(i, state, sign=sign):
            reach, open_ = state
            s = sign * (jnp.int32(1) << i)
            return reach | (open_ & shift_bits(reach, s)), open_ & shift_bits(open_, s)

        seeds = lax.fori_loop(0, steps, step, (seeds, free))[0]
    return seeds


def erode6(w):
    """6-neighbour erosion of a packed (a, b, words) grid: the cells whose 6 face neighbours are
    all set (cells beyond the grid count as unset), as ``scipy.ndimage.binary_erosion``."""
    out = w & shift_bits(w, 1) & shift_bits(w, -1)
    for axis in (0, 1):
        out = out & _step(w, axis, 1) & _step(w, axis, -1)
    return out


def flood(seeds, free, c: int):
    """The free cells 6-connected to ``seeds`` through free cells, on packed (a, b, words) grids.

    Args:
      seeds: (a, b, words) uint32, packed seed cells (a subset of ``free``).
      free: (a, b, words) uint32, packed free cells.
      c: cells per line along the packed axis.

    Returns:
      (a, b, words) uint32, the packed cells reached (seeds included).
    """

    def body(state):
        reach, _ = state
        new = spread_runs(reach, free, c)
        new = new | (free & (_step(new, 0, 1) | _step(new, 0, -1) | _step(new, 1, 1) | _step(new, 1, -1)))
        return new, jnp.any(new != reach)

    reach, _ = lax.while_loop(lambda state: state[1], body, (seeds, jnp.array(True)))
    return reach


def dilate_ball(w, r2, rmax: int):
    """The cells within Euclidean distance sqrt(r2) of a set cell, on a packed (a, b, words) grid.

    Args:
      w: (a, b, words) uint32, packed cells.
      r2: () int, the squared radius in cells (traced), 0 <= r2 <= rmax^2.
      rmax: static int, the largest radius r2 may reach.

    Returns:
      (a, b, words) uint32: cell x set iff some set cell y has |x - y|^2 <= r2 (cells beyond the
      grid count as unset; bits past the line's end may be set: :func:`unpack` drops them).
      Equals ``scipy.ndimage.distance_transform_edt(~x) ** 2 <= r2``.
    """
    def widen(row, k):  # the lines dilated by k cells along the packed axis, from those by k - 1
        row = row | shift_bits(w, k) | shift_bits(w, -k)
        return row, row

    wider = lax.scan(widen, w, jnp.arange(1, rmax + 1, dtype=jnp.int32))[1]
    rows = jnp.concatenate([w[None], wider, jnp.zeros_like(w)[None]])  # index rmax + 1: nothing
    lines = jnp.pad(rows, [(0, 0), (rmax, rmax), (rmax, rmax), (0, 0)])
    isqrt = jnp.asarray(np.floor(np.sqrt(np.arange(rmax * rmax + 1) + 0.5)).astype(np.int32))
    r2 = jnp.clip(jnp.asarray(r2, jnp.int32), 0, rmax * rmax)
    r = isqrt[r2]
    side = 2 * r + 1
    a, b, words = w.shape

    def add(i, out):
        dy, dz = i // side - r, i % side - r
        rest = r2 - dy * dy - dz * dz
        k = jnp.where(rest >= 0, isqrt[jnp.clip(rest, 0, rmax * rmax)], rmax + 1)
        start = (k, rmax - dy, rmax - dz, jnp.int32(0))
        return out | lax.dynamic_slice(lines, start, (1, a, b, words))[0]

    return lax.fori_loop(0, side * side, add, jnp.zeros_like(w))
