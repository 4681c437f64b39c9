"""Connected components of a 3-D boolean grid labelled by runs of cells, not by cells.

A run is a maximal segment of True cells along the last axis of a (a, b, c) grid: the grid packed
32 cells to a word (:mod:`.bits`) gives each run's first and last cell as one bit each. A solid
that fills a small share of its grid (a body in its margins) has few runs (about 2,000 for a
human on a 127^3 grid of 2 million cells), so the labelling works on arrays of ``cap`` runs:

1. :func:`find_runs`: the flat index of the first and last cell of every run, in flat order (the
   k-th first cell and the k-th last cell are one run's), at most ``cap`` of them
   (``Runs.fits`` False when there are more).
2. Neighbours: two runs in lines (x, y) and (x + dx, y + dy), |dx|, |dy| <= 1, touch
   (26-connectivity) when their intervals [z0, z1] overlap once widened by one cell. The runs of
   a neighbouring line that touch run r are consecutive there: from the first whose end is
   >= z0 - 1 to the last whose start is <= z1 + 1 (popcounts of the packed line under a mask).
   Edges from r to the first and the last of each of the 8 ranges connect every touching pair:
   when s lies strictly inside r's range, s spans r with a free cell on each side, so r is the
   only run of its line that s touches, and s's range names r.
3. :func:`run_labels`: each run's label is the smallest run index of its component (min-label
   propagation over the edges, hooking and pointer jumping, as FastSV, Zhang et al. 2020), that
   is the run holding the component's smallest flat cell index.

:func:`either` picks the run labelling or a dense one for a grid with more runs than ``cap``: a
``lax.cond`` one at a time; under ``jax.vmap`` one branch for the whole batch (the dense one when
any member needs it), so a batch does not run both.

Example::

    runs = find_runs(bits.pack(solid), solid.shape[-1], cap=16384)
    labels = run_labels(runs)       # (cap,) int32, cap on unused slots
"""
from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax
from jax.custom_batching import custom_vmap

from . import bits

__all__ = ["Runs", "running_sum", "find_runs", "run_labels", "run_counts", "run_sums", "paint", "either", "default_cap"]

_WORD = 32
_ONES = np.uint32(0xFFFFFFFF)
_EDGE_DIRECTIONS = [(dx, dy) for dx in (-1, 0, 1) for dy in (-1, 0, 1) if (dx, dy) != (0, 0)]


class Runs(NamedTuple):
    """The runs of True cells along the last axis of a (a, b, c) grid (a pytree).

    Attributes:
      first, last: (cap,) int32, flat index of each run's first and last cell, runs in flat
        order; unused slots hold ``a * b * c``.
      valid: (cap,) bool, the used slots (the first ``min(count, cap)``).
      count: () int32, the runs of the grid (may exceed ``cap``); fits: () bool, count <= cap.
      line_start: (a * b,) int32, index of the first run of each line (x * b + y).
      starts, ends: (a * b, words) uint32, the packed first and last cells of the runs.
    """

    first: jax.Array
    last: jax.Array
    valid: jax.Array
    count: jax.Array
    fits: jax.Array
    line_start: jax.Array
    starts: jax.Array
    ends: jax.Array


def default_cap(shape) -> int:
    """Run slots for a grid of ``shape``: every run it can hold (ceil(c / 2) per line) when that is
    at most 16384, else 16384."""
    a, b, c = shape
    return int(min(a * b * (-(-c // 2)), 16384))


def running_sum(x):
    """Inclusive running sum along the last axis (integers, exact): log-step doubling in a
    ``lax.fori_loop`` (a small program, where ``jnp.cumsum`` compiles to a tree of reduce-window
    stages)."""
    n = x.shape[-1]

    def step(i, x):
        s = jnp.int32(1) << i
        padded = jnp.concatenate([jnp.zeros(x.shape[:-1] + (n,), x.dtype), x], -1)
        return x + lax.dynamic_slice_in_dim(padded, n - s, n, -1)

    return lax.fori_loop(0, (n - 1).bit_length(), step, x)


def _positions(words, c: int, cap: int):
    """Flat cell index (line * c + cell) of every set bit of packed lines (lines, words), in flat
    order, into (cap,) int32 (unused slots: lines * c); and the number of set bits."""
    lines, nw = words.shape
    flat = words.reshape(-1)
    n = lax.population_count(flat).astype(jnp.int32)
    offset = running_sum(n) - n
    k = jnp.arange(flat.shape[0], dtype=jnp.int32)
    base = (k // nw) * c + (k % nw) * _WORD
    out = jnp.full((cap,), lines * c, jnp.int32)

    def body(state):
        i, w, out = state
        low = w & (~w + np.uint32(1))
        bit = lax.population_count(low - np.uint32(1)).astype(jnp.int32)
        dest = jnp.where(w != 0, offset + i, cap)
        out = out.at[dest].set(base + bit, mode="drop")
        return i + 1, w & (w - np.uint32(1)), out

    out = lax.while_loop(lambda s: jnp.any(s[1] != 0), body, (jnp.int32(0), flat, out))[2]
    return out, jnp.sum(n, dtype=jnp.int32)


def _below(p, nw: int):
    """(m, nw) uint32 masks of the cells at positions < p (m,) of a packed line."""
    s = jnp.clip(p[:, None] - _WORD * jnp.arange(nw, dtype=jnp.int32)[None, :], 0, _WORD)
    return jnp.where(s >= _WORD, _ONES, (jnp.uint32(1) << jnp.minimum(s, _WORD - 1).astype(jnp.uint32)) - 1)


def _popcount(x):
    return jnp.sum(lax.population_count(x).astype(jnp.int32), axis=-1, dtype=jnp.int32)


def find_runs(packed, c: int, cap: int) -> Runs:
    """The runs of a packed grid (a, b, words) uint32 of lines of ``c`` cells (:func:`.bits.pack`)."""
    a, b, nw = packed.shape
    starts = packed & ~bits.shift_bits(packed, 1)
    ends = packed & ~bits.shift_bits(packed, -1)
    starts, ends = starts.reshape(a * b, nw), ends.reshape(a * b, nw)
    # both in one vmapped call: one loop compiled (they hold as many bits, in the same words or the next)
    (first, last), (count, _) = jax.vmap(_positions, (0, None, None))(jnp.stack([starts, ends]), c, cap)
    per_line = _popcount(starts)
    line_start = running_sum(per_line) - per_line
    valid = jnp.arange(cap) < count
    return Runs(first, last, valid, count, count <= cap, line_start, starts, ends)


def _edges(runs: Runs, shape):
    """(cap, 16) int32: for each run and each of the 8 neighbouring lines, the first and the last
    run there that it touches (module docs, step 2); the run itself where there is none."""
    a, b, c = shape
    nw = runs.starts.shape[-1]
    cap = runs.first.shape[0]
    me = jnp.arange(cap, dtype=jnp.int32)
    line = runs.first // c
    x, y = line // b, line % b
    z0, z1 = runs.first % c, runs.last % c
    dx, dy = (jnp.asarray([d[k] for d in _EDGE_DIRECTIONS], jnp.int32)[:, None] for k in (0, 1))  # (8, 1)
    x2, y2 = x[None, :] + dx, y[None, :] + dy  # (8, cap): all directions at once (one set of operations)
    ok = runs.valid[None, :] & (x2 >= 0) & (x2 < a) & (y2 >= 0) & (y2 < b)
    other = jnp.where(ok, x2 * b + y2, 0)
    base = runs.line_start[other]
    below_first = _below(jnp.broadcast_to(z0 - 1, other.shape).reshape(-1), nw).reshape(other.shape + (nw,))
    below_last = _below(jnp.broadcast_to(z1 + 2, other.shape).reshape(-1), nw).reshape(other.shape + (nw,))
    lo = base + _popcount(runs.ends[other] & below_first)
    hi = base + _popcount(runs.starts[other] & below_last) - 1
    ok = ok & (lo <= hi)
    return jnp.concatenate([jnp.where(ok, lo, me[None, :]), jnp.where(ok, hi, me[None, :])]).T


def run_labels(runs: Runs, shape, jumps: int = 2):
    """The label of each run: the smallest run index of its 26-connected component (module docs,
    step 3); ``cap`` on unused slots. (cap,) int32. Exact when ``runs.fits``."""
    cap = runs.first.shape[0]
    edges = _edges(runs, shape)
    labels = jnp.where(runs.valid, jnp.arange(cap, dtype=jnp.int32), cap)

    def body(state):
        lab, _ = state
        low = jnp.minimum(lab, jnp.min(lab[edges], axis=1))
        new = lab.at[jnp.where(runs.valid, lab, cap)].min(low, mode="drop")  # hooking
        new = jnp.minimum(new, low)
        for _ in range(jumps):
            new = jnp.where(runs.valid, new[jnp.minimum(new, cap - 1)], cap)
        return new, jnp.any(new != lab)

    return lax.while_loop(lambda s: s[1], body, (labels, jnp.array(True)))[0]


def run_counts(runs: Runs, packed, c: int):
    """(cap,) int32: the set cells of the packed grid (a, b, words) within each run."""
    a, b, nw = packed.shape
    line = jnp.minimum(runs.first // c, a * b - 1)
    inside = _below(runs.last % c + 1, nw) & ~_below(runs.first % c, nw)
    return jnp.where(runs.valid, _popcount(packed.reshape(a * b, nw)[line] & inside), 0)


def run_sums(runs: Runs, values):
    """(cap,) the sums of the integers ``values`` (a, b, c) over the cells of each run (0 on unused slots)."""
    a, b, c = values.shape
    acc = running_sum(values).reshape(-1)
    size = acc.shape[0]
    upto = acc[jnp.minimum(runs.last, size - 1)]
    before = jnp.where(runs.first % c == 0, 0, acc[jnp.clip(runs.first - 1, 0, size - 1)])
    return jnp.where(runs.valid, upto - before, 0)


def paint(runs: Runs, chosen, packed, c: int):
    """The cells of the ``chosen`` (cap,) bool runs, packed like ``packed`` (the grid the runs were
    found in): a toggle bit at each chosen run's first cell and just after its last (never the
    first cell of another run: runs are apart), then a running XOR along each line (within a word
    by 5 shift-XOR steps, across words by the parity of the words before)."""
    a, b, nw = packed.shape
    lines = a * b
    line, z0, z1 = runs.first // c, runs.first % c, runs.last % c + 1
    pick = runs.valid & chosen
    at = jnp.concatenate([jnp.where(pick, line * nw + z0 // _WORD, lines * nw),
                          jnp.where(pick & (z1 < c), line * nw + z1 // _WORD, lines * nw)])
    bit = jnp.uint32(1) << (jnp.concatenate([z0, z1]) % _WORD).astype(jnp.uint32)
    toggles = jnp.zeros(lines * nw, jnp.uint32).at[at].add(bit, mode="drop").reshape(a, b, nw)  # distinct bits
    x = toggles
    for s in (1, 2, 4, 8, 16):
        x = x ^ (x << np.uint32(s))
    odd = (lax.population_count(toggles) & np.uint32(1)).astype(bool)
    carry = running_sum(odd.astype(jnp.int32)) - odd.astype(jnp.int32)
    return jnp.where(carry % 2 == 1, ~x, x) & packed


def either(use_dense, dense, sparse, *args):
    """``lax.cond(use_dense, dense, sparse, *args)``; under ``jax.vmap`` one branch for the whole
    batch, ``dense`` when any member's ``use_dense`` is True (``vmap`` of a ``lax.cond`` with a
    batched predicate would run both). ``dense`` and ``sparse``: functions of ``*args`` (arrays)."""
    leaves, tree = jax.tree.flatten(args)

    def call(fn, leaves):
        return fn(*jax.tree.unflatten(tree, leaves))

    @custom_vmap
    def pick(flag, leaves):
        return lax.cond(flag, lambda l: call(dense, l), lambda l: call(sparse, l), leaves)

    @pick.def_vmap
    def _rule(axis_size, in_batched, flag, leaves):
        flag_batched, leaves_batched = in_batched
        leaves = [x if batched else jnp.broadcast_to(x, (axis_size,) + jnp.shape(x))
                  for x, batched in zip(leaves, leaves_batched)]
        batch_dense = jax.vmap(lambda l: call(dense, l))
        batch_sparse = jax.vmap(lambda l: call(sparse, l))
        out = lax.cond(jnp.any(flag) if flag_batched else flag, batch_dense, batch_sparse, leaves)
        return out, jax.tree.map(lambda _: True, out)

    return pick(jnp.asarray(use_dense, bool), leaves)
