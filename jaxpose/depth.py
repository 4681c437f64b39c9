"""Exact Euclidean distance transform of a boolean grid, in JAX (jittable, vmappable, no host step).

For every True cell of ``inside`` the distance, in cells, to the nearest False cell; 0 on False
cells: the same values as ``scipy.ndimage.distance_transform_edt(inside)``, bit for bit.

Squared distances are exact int32 arithmetic, one axis at a time (the squared distance is a sum
over axes, so the minimum separates):

starting from f = 0 on False cells and "none in reach" elsewhere, each axis in turn replaces f by
g(i) = min_j f(j) + (i - j)^2 along it (the first pass gives the squared distance to the nearest
False cell in the same line, the second within the same plane, the third in the grid). The
first pass is the distance to the nearest False cell before or after each cell in its line (two
running extrema, each a ``lax.scan`` over the slices across the axis). For the others, the
minimiser j of a cell satisfies (i - j)^2 <= g(i) <= f(i),
so a ``lax.while_loop`` over the offsets k = 1, 2, ... (both signs, one vector min each) is exact
once k^2 exceeds every value still to be improved: a traced bound, the largest distance within
the plane (second pass) or the grid (third), never more than the axis length.

Memory: a few arrays the size of the grid (the shifted copies are padded along one axis), never
grid x grid. Cost: n slice operations for the first axis, O(largest depth) vector operations
for the others.

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

from ._validate import check_power
from .errors import InvalidInputError
from .weighted import depth_power_weights

__all__ = ["squared_distance", "distance", "depth_weights", "host_distance", "to_bucket", "from_bucket", "MAX_SQUARED", "BUCKET"]

MAX_SQUARED = 2**30  # int32 sentinel "no False cell in reach"; every exact squared distance is below it
BUCKET = 32  # host grids are padded to a multiple of this per axis (one compilation per bucket) ...
BUCKET_LONG = 16  # ... and their longest axis, which the resolution sets, to a multiple of this


def _check_shape(shape):
    if len(shape) == 0:
        raise InvalidInputError("the occupancy grid needs at least one axis, got a scalar")
    if sum((int(n) + 1) ** 2 for n in shape) >= MAX_SQUARED:
        raise InvalidInputError(f"grid shape {tuple(shape)} is too large for int32 squared distances")


def _line_distance(outside, axis):
    """The first pass in closed form: the squared distance along ``axis`` from each cell to the
    nearest ``outside`` cell of its line (MAX_SQUARED when the line has none), from the index of
    the last outside cell before each cell and the first after it: a running max and a running
    min, each a ``lax.scan`` over the slices across ``axis`` (one vector extremum per slice; a
    small program, where ``lax.cummax`` is a sliding window on CPU and a log-step scan unrolls)."""
    n = outside.shape[axis]
    outside = jnp.moveaxis(outside, axis, 0)
    idx = lax.broadcasted_iota(jnp.int32, outside.shape, 0)

    def running(op, fill, reverse):
        def step(carry, x):
            carry = op(carry, x)
            return carry, carry

        init = jnp.full(outside.shape[1:], fill, jnp.int32)
        return lax.scan(step, init, jnp.where(outside, idx, fill), reverse=reverse)[1]

    before = running(jnp.maximum, -n - 1, False)
    after = running(jnp.minimum, 2 * n + 1, True)
    d = jnp.minimum(idx - before, after - idx)  # > n when there is none on either side
    return jnp.moveaxis(jnp.where(d < n, d * d, jnp.int32(MAX_SQUARED)), 0, axis)


def _min_plus(f, axis, valid):
    """g(i) = min_j f(j) + (i - j)^2 along ``axis``, exact (module docs) on the ``valid`` cells.

    Offsets k = 1, 2, ... (both signs, one vector min each) until no valid cell can improve: a cell
    whose value is below k^2 is final, since any j at |i - j| >= k adds at least k^2. Lines with no
    finite value stay MAX_SQUARED whatever the offsets, and cells beyond the extent are never the
    minimiser of a cell within it (they hold no background): neither holds the loop. The bound
    k^2 <= max f, fixed before the loop, ends it without a reduction when every value is small.
    """
    n = f.shape[axis]
    if n == 1:
        return f
    pad = [(0, 0)] * f.ndim
    pad[axis] = (n, n)
    padded = jnp.pad(f, pad, constant_values=MAX_SQUARED)  # beyond the border: nothing in reach
    reachable = jnp.any(f < MAX_SQUARED, axis=axis, keepdims=True) & valid
    top = jnp.max(jnp.where(reachable, f, 0))  # MAX_SQUARED when a cell has nothing in reach yet

    def shifted(k):
        return lax.dynamic_slice_in_dim(padded, n + k, n, axis)

    def cond(state):
        k, g = state
        return (k < n) & (k * k <= top) & jnp.any(reachable & (g >= k * k))

    def body(state):
        k, g = state
        return k + 1, jnp.minimum(g, jnp.minimum(shifted(k), shifted(-k)) + k * k)

    return lax.while_loop(cond, body, (jnp.int32(1), f))[1]


@jax.jit
def squared_distance(inside, extent=None):
    """Exact squared Euclidean distance of each True cell to the nearest False cell (module docs).

    Args:
      inside: (n_0, ..., n_{d-1}) bool (any nonzero value counts as True), static shape, d >= 1.
      extent: optional (d,) int, traced: only the cells with index < extent along every axis are
        the grid; the others (padding that lets grids of different sizes share one compilation)
        are neither inside nor outside, and get 0. Default: the whole array.

    Returns:
      int32 array of the same shape: 0 on False cells, the squared distance in cells elsewhere.

    Raises:
      InvalidInputError: a scalar or too large grid; an extent of another shape than (d,).

    Example::

        >>> squared_distance(jnp.array([False, True, True, True, False, True]))
        Array([0, 1, 4, 1, 0, 1], dtype=int32)
    """
    inside = jnp.asarray(inside).astype(bool)
    _check_shape(inside.shape)
    if extent is not None and tuple(jnp.shape(extent)) != (inside.ndim,):  # (a short one was read clamped: extent[-1] again)
        raise InvalidInputError(f"extent must have shape ({inside.ndim},), one count per axis of inside, got "
                                f"{tuple(jnp.shape(extent))}")
    if inside.size == 0:
        return jnp.zeros(inside.shape, jnp.int32)
    grids = [lax.broadcasted_iota(jnp.int32, inside.shape, a) for a in range(inside.ndim)]
    if extent is None:
        valid = jnp.ones(inside.shape, bool)
    else:
        extent = jnp.asarray(extent, jnp.int32)
        valid = jnp.all(jnp.stack([g < extent[a] for a, g in enumerate(grids)]), axis=0)
    d2 = _line_distance(valid & ~inside, 0)  # the first pass; cells beyond the extent never reach in
    for axis in range(1, inside.ndim):
        d2 = _min_plus(d2, axis, valid)
    # no False cell anywhere: scipy's value, the distance to the virtual cell (-1, 0, ..., 0)
    virtual = (grids[0] + 1) ** 2 + sum((g * g for g in grids[1:]), jnp.int32(0))
    d2 = jnp.where(jnp.all(inside | ~valid), virtual, d2)
    return jnp.where(inside & valid, d2, 0)


@partial(jax.jit, static_argnames="dtype")
def distance(inside, extent=None, dtype=None):
    """Exact Euclidean distance of each True cell to the nearest False cell, in cells (module docs).

    Args:
      inside: (n_0, ..., n_{d-1}) bool, static shape.
      extent: as :func:`squared_distance`.
      dtype: float dtype of the result (default: JAX's default float, float32 unless x64 is on).

    Returns:
      Array of ``inside``'s shape, sqrt(:func:`squared_distance`) rounded once to ``dtype``.
    """
    dtype = jnp.result_type(float) if dtype is None else dtype
    return jnp.sqrt(squared_distance(inside, extent).astype(dtype))


def depth_weights(inside, power, bias=0.0, extent=None):
    """Weights (depth / largest depth)^power of the cells of an occupancy (0 outside it):
    :func:`jaxpose.weighted.depth_power_weights` of :func:`distance` (the host computes the same
    weights from scipy's distance transform, which :func:`distance` equals).

    The depth of a True cell is its :func:`distance` minus ``bias`` cells (where the shape's
    surface lies relative to its outermost cells), at least 0. The pitch cancels in the ratio.

    Args:
      inside: (n_0, ..., n_{d-1}) bool; extent: as :func:`squared_distance`.
      power: () float >= 0 (traced: differentiable). 0 gives weight 1 on every True cell (0^0 = 1).
        A traced power outside [0, inf) (negative, NaN, inf), which cannot be refused, gives
        weight 0 on every cell (:func:`jaxpose.weighted.depth_power_weights`; no NaN, derivative 0):
        a result no power in range gives a grid with a True cell.
      bias: () float >= 0, cells subtracted from the distance.

    Returns:
      (n_0, ..., n_{d-1}) float weights in [0, 1]; 1 on every True cell when no cell is deeper than
      ``bias``; 0 everywhere for a traced power outside [0, inf). Their derivative in ``power`` is
      log(ratio) * weight (0 where the depth is 0).

    Raises:
      InvalidInputError: a power or bias that is not a () real (known while tracing too), or
        concrete and not a finite number >= 0 (:func:`jaxpose._validate.check_power`).
    """
    check_power(power)
    if jnp.ndim(bias) != 0:
        raise InvalidInputError(f"bias must be a scalar, got shape {tuple(jnp.shape(bias))}")
    check_power(bias, "bias")  # (a string was JAX's TypeError; NaN weighed every cell 0 without a word)
    return _depth_weights(inside, power, bias, extent)


@jax.jit
def _depth_weights(inside, power, bias, extent):
    """:func:`depth_weights` without its checks (compiled)."""
    power = jnp.asarray(power, jnp.result_type(float))
    inside = jnp.asarray(inside).astype(bool)
    if extent is not None:  # cells beyond the extent are not part of the occupancy
        grids = [lax.broadcasted_iota(jnp.int32, inside.shape, a) for a in range(inside.ndim)]
        inside = inside & jnp.all(jnp.stack([g < jnp.asarray(extent)[a] for a, g in enumerate(grids)]), axis=0)
    return depth_power_weights(distance(inside, extent, dtype=power.dtype), inside, power, bias)


def to_bucket(grid, multiple=BUCKET, longest=BUCKET_LONG):
    """A NumPy grid with its axes in ascending order of length, padded with False (0) at the high
    end of each axis to a multiple of ``multiple`` (the longest axis: of ``longest``): grids whose
    sorted sides round up alike share one compilation of :func:`squared_distance` ``(padded,
    extent)`` (the 52 meshes of the dev datasets at the default resolution fall into 6 buckets),
    and the shortest axis comes first (its 1-D distances, which bound the second pass's loop, are
    then the shortest).

    Returns:
      padded (NumPy, the grid's dtype), extent (d,) int32 NumPy (the sorted shape), axes (d,) int:
      ``padded[:extent...] == grid.transpose(axes)``.
    """
    grid = np.asarray(grid)
    axes = np.argsort(grid.shape, kind="stable")
    moved = grid.transpose(axes)
    last = moved.ndim - 1
    pad = [(0, -n % int(longest if a == last else multiple)) for a, n in enumerate(moved.shape)]
    return np.pad(moved, pad), np.asarray(moved.shape, np.int32), axes


def from_bucket(values, axes, extent):
    """The inverse of :func:`to_bucket` on a result of the padded grid's shape (NumPy)."""
    values = np.asarray(values)[tuple(slice(0, int(n)) for n in extent)]
    return values.transpose(np.argsort(axes))


def host_distance(inside):
    """:func:`distance` for NumPy callers: (shape) float64 NumPy distances, the values of
    ``scipy.ndimage.distance_transform_edt(inside)`` (computed on :func:`to_bucket`'s grid)."""
    inside = np.asarray(inside, bool)
    if inside.size and inside.all():  # scipy's value for no False cell depends on the axes' order
        idx = np.indices(inside.shape)
        return np.sqrt(((idx[0] + 1) ** 2 + np.sum(idx[1:] ** 2, axis=0)).astype(np.float64))
    padded, extent, axes = to_bucket(inside)
    d2 = from_bucket(squared_distance(padded, extent), axes, extent)
    return np.sqrt(d2.astype(np.float64))
