"""Weighted moments of points or of a grid, and the depth^p weights of a solid: written once for
NumPy and jax.numpy.

Each function takes its array backend from its arguments (:func:`jaxpose.backend.array_namespace`):
concrete NumPy arrays (and Python numbers and lists of them, as their NumPy arrays: a list of floats
is float64) compute in NumPy on the host (in their own dtype, no JAX imported); JAX
arrays and tracers compute in ``jax.numpy`` (``jit``, ``vmap``, ``grad``). The operations are the
same in both, so an estimator's host path and its JAX path are one implementation, and their
results differ only by the rounding of the float they run in.

Example::

    >>> import numpy as np, jax.numpy as jnp
    >>> occ = np.zeros((8, 8, 8)); occ[2:6, 2:6, 2:6] = 1.0
    >>> grid_moments(occ, occ, np.zeros(3), 0.5).center      # NumPy
    array([2., 2., 2.])
    >>> grid_moments(jnp.asarray(occ), jnp.asarray(occ), jnp.zeros(3), 0.5).center  # JAX
    Array([2., 2., 2.], dtype=float32)
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .backend import array_namespace
from .errors import InvalidInputError

__all__ = ["Moments", "weighted_center", "weighted_moments", "grid_axes", "grid_moments", "depth_power_weights",
           "solid_occupancy", "check_shape"]


def check_shape(name, value, want, note=""):
    """Refuse ``value`` unless its shape is ``want`` (known while tracing too): InvalidInputError
    "{name} must have shape {want}{note}, got {shape}" (a (2,) origin was read as (o0, o1, o1) in
    JAX, whose indexing clamps; a (3,) pitch broadcast against the cells). Returns None."""
    shape = tuple(np.shape(value))
    if shape != tuple(want):
        raise InvalidInputError(f"{name} must have shape {tuple(want)}{note}, got {shape}")


class Moments(NamedTuple):
    """center : (3,) c_m (eq. 4); mean_distance : () d_m (eq. 5); volume : ();
    second_moment : (3, 3) (1/V) int (x - c)(x - c)^T; cell : (3,) coarse grid spacing;
    unrefined : () cells cut by the boundary left unrefined because ``band`` was too small.

    Example::

        m = jaxpose.volume_moments(jaxpose.fit_svdd(points, gamma=47.0, nu=0.5))
        m.center.shape, m.mean_distance.shape, m.second_moment.shape   # (3,), (), (3, 3)
    """

    center: object
    mean_distance: object
    volume: object
    second_moment: object
    cell: object
    unrefined: object = 0


def weighted_center(x, w):
    """Mass and weighted center of points.

    Args:
      x: 3 arrays, the coordinates along each axis, broadcastable to the shape of ``w``
        (:func:`weighted_moments`).
      w: float >= 0, the weights.

    Returns:
      mass () = sum w, center (3,) = sum w x / mass (0 with mass 0).

    Raises:
      InvalidInputError: ``x`` not 3 arrays (an (n, 3) array of points: pass its transpose).
    """
    _check_axes(x)
    xp = array_namespace(w, *x)
    w, x = xp.asarray(w), [xp.asarray(xa) for xa in x]  # (lists: the backend's arrays)
    mass = xp.sum(w)
    safe = xp.where(mass > 0, mass, 1.0)
    return mass, xp.stack([xp.sum(w * xa) / safe for xa in x])


def _check_axes(x):
    """``x`` as 3 coordinate arrays; an (n, 3) array of points (n != 3) refused by name, with the
    fix (its rows were read as n axes: a center of n coordinates, or a broadcasting error)."""
    shape = getattr(x, "shape", None)
    if len(x) != 3:
        got = f"an array of shape {tuple(shape)}" if shape is not None else f"{len(x)} arrays"
        hint = ": pass points.T (or x[:, 0], x[:, 1], x[:, 2])" if shape is not None and shape[-1:] == (3,) else ""
        raise InvalidInputError(f"x must be 3 coordinate arrays (one per axis), got {got}{hint}")


def weighted_moments(x, w):
    """Weighted moments of points (the one implementation behind every estimator's moments).

    Args:
      x: 3 arrays, the points' coordinates along each axis, broadcastable to the shape of ``w``
        (a cell list: ``x[:, 0], x[:, 1], x[:, 2]`` with w (n,); a grid: the axes' cell centers
        shaped (nx, 1, 1), (1, ny, 1), (1, 1, nz) with w (nx, ny, nz), never stored per cell).
      w: float >= 0, the weights.

    Returns:
      mass () = sum w; center (3,) = sum w x / mass; mean distance () = sum w |x - c| / mass;
      second moment (3, 3) = sum w (x - c)(x - c)^T / mass. With mass 0 the center is 0.
      Differentiable in x and w (the distance's square root is kept off 0 by the float's tiny).

    Raises:
      InvalidInputError: ``x`` not 3 arrays (an (n, 3) array of points: pass its transpose).
    """
    _check_axes(x)
    xp = array_namespace(w, *x)
    w, x = xp.asarray(w), [xp.asarray(xa) for xa in x]  # (lists: the backend's arrays)
    mass, c = weighted_center(x, w)
    safe = xp.where(mass > 0, mass, 1.0)
    d = [xa - c[a] for a, xa in enumerate(x)]
    tiny = xp.finfo(w.dtype).tiny
    md = xp.sum(w * xp.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2] + tiny)) / safe
    second = xp.stack([xp.stack([xp.sum(w * da * db) for db in d]) for da in d]) / safe
    return mass, c, md, second


def grid_axes(shape, origin, pitch, dtype):
    """The cell centers of a regular grid per axis: 3 arrays origin_a + pitch (i + 1/2), shaped
    (nx, 1, 1), (1, ny, 1), (1, 1, nz) (broadcastable to the grid, never stored per cell), in
    ``dtype``; the backend of ``origin`` and ``pitch``."""
    xp = array_namespace(origin, pitch)
    origin = xp.asarray(origin, dtype)
    return [(origin[a] + pitch * (xp.arange(n, dtype=dtype) + 0.5)).reshape([n if b == a else 1 for b in range(3)])
            for a, n in enumerate(shape)]


def grid_moments(occupancy, weights, origin, pitch):
    """Moments of a weighted occupancy on a regular grid.

    Args:
      occupancy: (nx, ny, nz) float in [0, 1] (or bool), the share of each cell inside the shape.
      weights: (nx, ny, nz) float >= 0, each cell's weight in the center and second moment (e.g.
        1, or depth^p on the occupied cells); cells outside the shape should weigh 0.
      origin: (3,) lower corner of cell (0, 0, 0); pitch: () cell edge (traced: differentiable).

    Returns:
      :class:`Moments`: center sum w x / sum w over the cell centers x = origin + pitch (i + 1/2),
      mean distance and second moment with the same weights, volume = pitch^3 sum occupancy,
      cell = (pitch,) * 3; in the weights' dtype (integer or bool weights: as floats, NumPy's
      float64 or JAX's default float) and backend.

    Raises:
      InvalidInputError: weights that are not a 3-D grid of real numbers, an occupancy of another
        shape, an origin that is not (3,) or a pitch that is not () (shapes are known while tracing
        too).

    Example::

        >>> import jax.numpy as jnp
        >>> occ = jnp.zeros((8, 8, 8)).at[2:6, 2:6, 2:6].set(1.0)
        >>> grid_moments(occ, occ, jnp.zeros(3), 0.5).center  # cells 2..5 at 0.5 (i + 1/2): 1.25 ... 2.75
        Array([2., 2., 2.], dtype=float32)
    """
    xp = array_namespace(occupancy, weights, origin, pitch)
    weights = xp.asarray(weights)
    if weights.ndim != 3:
        raise InvalidInputError(f"weights must be a 3-D grid (nx, ny, nz), got shape {tuple(weights.shape)}")
    check_shape("occupancy", occupancy, weights.shape, ", the shape of weights")
    check_shape("origin", origin, (3,))
    check_shape("pitch", pitch, ())
    kind = np.dtype(weights.dtype).kind
    if kind in "biu":  # (an integer dtype failed in finfo; a bool one in arange, and cast the origin to it)
        weights = weights.astype(xp.result_type(float))
    elif kind not in "fV":
        raise InvalidInputError(f"weights must be real numbers, got dtype {weights.dtype}")
    dtype = weights.dtype
    x = grid_axes(weights.shape, xp.asarray(origin, dtype), pitch, dtype)
    _, c, md, second = weighted_moments(x, weights)
    volume = xp.sum(xp.asarray(occupancy, dtype)) * pitch**3
    return Moments(c, md, volume, second, xp.full(3, pitch, dtype), xp.asarray(0))


def depth_power_weights(distance, inside, power, bias=0.0):
    """Weights (depth / largest depth)^power of the cells of a solid (0 outside it), from its
    distance transform.

    The depth of a True cell is its ``distance`` (to the nearest False cell, in cells) minus
    ``bias`` cells, at least 0. The pitch cancels in the ratio.

    Args:
      distance: (n_0, ..., n_{d-1}) float, the exact distance transform of ``inside``
        (``scipy.ndimage.distance_transform_edt`` on the host, :func:`jaxpose.depth.distance` in
        JAX); its dtype is the result's.
      inside: (n_0, ..., n_{d-1}) bool.
      power: () float >= 0 (traced: differentiable). 0 gives weight 1 on every True cell (0^0 = 1).
        A traced power cannot be refused: one outside [0, inf) (negative, NaN, inf) gives weight 0
        on every cell (finite, and a derivative 0), which no power in range gives a grid with a
        True cell (its deepest cells weigh 1): test ``jnp.isfinite(power) & (power >= 0)``, or the
        weights' maximum, where the power may be out of range. (A negative power gave weights
        above 1, NaN a NaN grid.)
      bias: () float, cells subtracted from the distance.

    Returns:
      (n_0, ..., n_{d-1}) float weights in [0, 1]; 1 on every True cell when no cell is deeper than
      ``bias``; 0 everywhere for a power outside [0, inf). Their derivative in ``power`` is
      log(ratio) * weight (0 where the depth is 0).
    """
    xp = array_namespace(distance, inside, power, bias)
    distance, inside = xp.asarray(distance), xp.asarray(inside)  # (lists: the backend's arrays)
    if xp is np:  # concrete (the host path): its callers refuse a power out of range; the same rule
        ok = bool(np.isfinite(power) and power >= 0)
        power = power if ok else 0.0
    else:  # traced: a power out of range weighs every cell 0 (its branch computed at power 0: no NaN derivative)
        ok = xp.isfinite(power) & (power >= 0)
        power = xp.where(ok, power, 0.0)
    d = xp.maximum(distance - bias, 0.0)
    top = xp.max(d)
    ratio = d / xp.where(top > 0, top, 1.0)
    positive = ratio > 0
    w = xp.where(positive, xp.where(positive, ratio, 1.0) ** power, xp.where(power == 0, 1.0, 0.0))
    return xp.where(inside & ok, xp.where(top > 0, w, 1.0), 0.0)


def solid_occupancy(inside, occupied, dtype):
    """The volume share of each cell of a voxel solid: 1 inside, 1/2 on inside cells that straddle
    the surface (``occupied``: a point solid's cells holding points), 0 outside."""
    return inside.astype(dtype) - 0.5 * (inside & occupied).astype(dtype)
