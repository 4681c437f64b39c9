"""Exact Euclidean distance transform of a boolean grid, in JAX (jittable, vmappable, no host step).

For every True cell of ``inside`` the distance, in cells, to the nearest False cell; 0 on False
cells: the same values as ``scipy.ndimage.distance_transform_edt(inside)``, bit for bit.

Squared distances are exact int32 arithmetic, one axis at a time (the squared distance is a sum
over axes, so the minimum separates):

1. along axis 0, f(i) = (distance to the nearest False cell in the same line)^2, from the index
   of the last False cell at or before i (``lax.cummax``) and the next at or after it
   (``lax.cummin``), in O(n);
2. along each further axis, g(i) = min_j f(j) + (i - j)^2. The minimiser j of a cell satisfies
   (i - j)^2 <= g(i), so after taking the offsets |i - j| <= K the result is exact for every cell
   whose current value is below (K + 1)^2; a ``lax.while_loop`` takes the offsets K = 1, 2, ...
   (both signs, one vector min each) until that holds for every cell (a traced bound: about the
   grid's largest depth steps, at most the axis length).

Memory: a few arrays the size of the grid (the shifted copies are padded along one axis), never
grid x grid. Cost: O(n) per cell for pass 1, O(largest depth) per cell for each further pass.

Conventions (those of scipy). Cells beyond the grid border are not outside: a line with no False
cell takes its distances from the other lines. A grid with no False cell at all gets scipy's
values for that case, the distance to the virtual cell (-1, 0, ..., 0) just before the first one;
a grid with no True cell is 0 everywhere.

Differentiation: the output is piecewise constant in anything the occupancy is computed from (its
derivative is 0 almost everywhere, and JAX gives 0); it carries no tangent.

Example::

    >>> inside = jnp.zeros((5, 5), bool).at[1:4, 1:4].set(True)
    >>> distance(inside)[2, 2]
    Array(2., dtype=float32)
"""
from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax

from .errors import InvalidInputError

__all__ = ["squared_distance", "distance", "host_distance", "MAX_SQUARED"]

MAX_SQUARED = 2**30  # int32 sentinel "no False cell in reach"; every exact squared distance is below it


def _check_shape(shape):
    if len(shape) == 0:
        raise InvalidInputError("the occupancy grid needs at least one axis, got a scalar")
    if sum((int(n) + 1) ** 2 for n in shape) >= MAX_SQUARED:
        raise InvalidInputError(f"grid shape {tuple(shape)} is too large for int32 squared distances")


def _first_pass(inside):
    """Squared distance to the nearest False cell along axis 0 (MAX_SQUARED where the line has none)."""
    n = inside.shape[0]
    idx = lax.broadcasted_iota(jnp.int32, inside.shape, 0)
    far = jnp.int32(2 * n + 1)
    before = lax.cummax(jnp.where(inside, -far, idx), axis=0)  # last False at or before i
    after = lax.cummin(jnp.where(inside, far + n, idx), axis=0, reverse=True)  # next False at or after i
    d = jnp.minimum(idx - before, after - idx)
    return jnp.where(d <= n, d * d, jnp.int32(MAX_SQUARED))


def _min_plus(f, axis):
    """g(i) = min_j f(j) + (i - j)^2 along ``axis``, exact (module docs)."""
    n = f.shape[axis]
    if n == 1:
        return f
    pad = [(0, 0)] * f.ndim
    pad[axis] = (n, n)
    padded = jnp.pad(f, pad, constant_values=MAX_SQUARED)  # beyond the border: nothing in reach
    # lines with no finite value stay MAX_SQUARED whatever the offsets: they do not hold the loop
    reachable = jnp.any(f < MAX_SQUARED, axis=axis, keepdims=True)

    def bound(g):
        return jnp.max(jnp.where(reachable, g, 0))

    def shifted(k):
        return lax.dynamic_slice_in_dim(padded, n + k, n, axis)

    def cond(state):
        k, _, top = state
        return (k < n) & (k * k <= top)

    def body(state):
        k, g, _ = state
        g = jnp.minimum(g, jnp.minimum(shifted(k), shifted(-k)) + k * k)
        return k + 1, g, bound(g)

    _, g, _ = lax.while_loop(cond, body, (jnp.int32(1), f, bound(f)))
    return g


@jax.jit
def squared_distance(inside):
    """Exact squared Euclidean distance of each True cell to the nearest False cell (module docs).

    Args:
      inside: (n_0, ..., n_{d-1}) bool (any nonzero value counts as True), static shape, d >= 1.

    Returns:
      int32 array of the same shape: 0 on False cells, the squared distance in cells elsewhere.

    Example::

        >>> squared_distance(jnp.array([False, True, True, True, False, True]))
        Array([0, 1, 4, 1, 0, 1], dtype=int32)
    """
    inside = jnp.asarray(inside).astype(bool)
    _check_shape(inside.shape)
    if inside.size == 0:
        return jnp.zeros(inside.shape, jnp.int32)
    d2 = _first_pass(inside)
    for axis in range(1, inside.ndim):
        d2 = _min_plus(d2, axis)
    # no False cell anywhere: scipy's value, the distance to the virtual cell (-1, 0, ..., 0)
    grids = [lax.broadcasted_iota(jnp.int32, inside.shape, a) for a in range(inside.ndim)]
    virtual = (grids[0] + 1) ** 2 + sum((g * g for g in grids[1:]), jnp.int32(0))
    return jnp.where(jnp.all(inside), virtual, d2)


@partial(jax.jit, static_argnames="dtype")
def distance(inside, dtype=None):
    """Exact Euclidean distance of each True cell to the nearest False cell, in cells (module docs).

    Args:
      inside: (n_0, ..., n_{d-1}) bool, static shape.
      dtype: float dtype of the result (default: JAX's default float, float32 unless x64 is on).

    Returns:
      Array of ``inside``'s shape, sqrt(:func:`squared_distance`) rounded once to ``dtype``.
    """
    dtype = jnp.result_type(float) if dtype is None else dtype
    return jnp.sqrt(squared_distance(inside).astype(dtype))


def host_distance(inside):
    """:func:`squared_distance` for NumPy callers: (shape) float64 NumPy distances, the values of
    ``scipy.ndimage.distance_transform_edt(inside)``."""
    inside = np.asarray(inside, bool)
    return np.sqrt(np.asarray(squared_distance(inside)).astype(np.float64))
