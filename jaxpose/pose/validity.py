"""When an OCSVM pose is valid: the traced checks behind ``Pose.valid`` and ``Pose.status``.

The codes, their messages and the thresholds live in :mod:`jaxpose.pose.result` (no JAX needed).

A pose is valid (``Pose.valid``, ``Pose.status == Status.OK``) when its number can be trusted as
the centroid and mean distance of a region that the samples and the grid actually determine:

* the parameters are in range and the points have an extent (:attr:`Status.BAD_PARAMETERS`,
  :attr:`Status.DEGENERATE_INPUT`);
* neighbouring samples' kernels overlap (:attr:`Status.SPARSE_SAMPLES`): the median distance of a
  sample to its nearest neighbour is at most ``MAX_SPACING`` kernel widths sigma = 1 / sqrt(2 gamma)
  (pre-scaled frame, :mod:`jaxpose.pose.frame`). Sparser samples make the region a cloud of separate
  balls, one around each sample, whose moments say more about the sampling than the shape;
* the grid resolves the kernel (:attr:`Status.UNRESOLVED_GRID`): the finest cell edge is at most
  ``MAX_CELL`` kernel widths, i.e. every cell center lies within one kernel width of the cell's
  faces, where the linearised occupancy of :mod:`jaxpose.moments` holds. Coarser cells make the
  result depend on the grid;
* the region has a positive volume (:attr:`Status.EMPTY_REGION`);
* the region has not collapsed (:attr:`Status.COLLAPSED_REGION`): its mean distance from its
  centroid is at least ``MIN_SPREAD`` times the samples' median distance from that centroid. A
  region that covers the samples has a ratio near 1 (3/4 for a solid ball sampled on its sphere, 1
  for a shell, about 1/2 when nu leaves far parts out); nu near 1 or a handful of samples shrink
  the region onto the densest few samples and the ratio towards 0;
* the center is finite and the scale positive and finite (:attr:`Status.NOT_FINITE`);
* the points' reference size is within what their dtype computes (:attr:`Status.OUT_OF_RANGE`,
  :func:`unresolved_size`; traced input only): the size is a root mean square of the distances
  from the mean, whose squares underflow (each square below the dtype's smallest normal number is
  lost) or overflow (their sum). In float32 that is an RMS distance from the mean below
  ``sqrt(1.5 tiny / MAX_ROUNDING)`` = 4.2e-18 (where lost squares may move the size by more than
  ``MAX_ROUNDING``) or above ``sqrt(max / m)`` = 1.8e19 / sqrt(m) for m points (5.8e17 at 1024);
  points that have no extent are ``DEGENERATE_INPUT``, whatever their size. Concrete inputs are
  rescaled on the host in float64 first and never trip this.

The solver's convergence is reported apart (``Pose.converged``). Every check is a traced
comparison (no Python branches on values), so poses under ``jit`` and ``vmap`` carry their status.

Example::

    pose = jaxpose.normalize(points, method="ocsvm", gamma=1e4)
    jaxpose.Status(int(pose.status)).message
"""
from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np

from .._validate import InvalidInputError, check_array, check_mask, compute_dtype, is_traced
from ..occupancy.kernels import map_blocks
from .frame import REFERENCE_RMS, reference_frame
from .result import MAX_CELL, MAX_ROUNDING, MAX_SPACING, MIN_SPREAD, Status, status_message

__all__ = ["Status", "MAX_SPACING", "MAX_CELL", "MIN_SPREAD", "MAX_ROUNDING", "status_message", "pose_status",
           "median_spacing", "median_distance", "no_extent", "unresolved_offset", "flag_offset", "unresolved_size",
           "flag_range"]



def _check_points(y, mask=None, name="y"):
    """The shapes (and kinds) the checks read, known while tracing (values are not read): ``y``
    (m, 3) real with m >= 1 (:func:`jaxpose._validate.check_array`, the library's rule), ``mask``
    None or (m,) (:func:`jaxpose._validate.check_mask`). InvalidInputError naming the one that
    does not fit: empty points were NumPy's / JAX's "zero-size array to reduction operation"
    ValueError or an IndexError, other shapes their broadcast or axis errors. Returns None."""
    check_array(y, name, 1, finite=False)
    check_mask(mask, tuple(jnp.shape(y))[0], name)


def _floats(points):
    """``points`` as a JAX array of floats: a float dtype as it is (bfloat16 too), integers in the
    dtype they are computed in (:func:`jaxpose._validate.compute_dtype`: float32, float64 with x64;
    cast before JAX sees them, so int64 beyond int32 keeps its value)."""
    given = getattr(points, "dtype", None)
    if given is not None and jnp.issubdtype(given, jnp.inexact):
        return jnp.asarray(points)
    x = points if is_traced(points) else np.asarray(points)
    return jnp.asarray(x if jnp.issubdtype(x.dtype, jnp.inexact) else x.astype(compute_dtype(x)))


def _masked_median(values, mask):
    """Lower median of values (m,) over mask (m,) bool (at least one True)."""
    n = jnp.sum(mask)
    ordered = jnp.sort(jnp.where(mask, values, jnp.inf))
    return ordered[jnp.maximum(n - 1, 0) // 2]


def median_spacing(y, mask=None, block=512):
    """Median distance of each point to its nearest other point.

    Args:
      y: (m, 3) float; mask: optional (m,) bool (False rows are padding, left out).
      block: rows per block (memory O(block * m)).

    Returns:
      () float in the units of ``y`` (0 when points repeat; inf for one point, which has no other).
      Not differentiated.

    Raises:
      InvalidInputError: ``y`` not (m, 3) real with m >= 1, ``mask`` not (m,) (:func:`_check_points`).
    """
    _check_points(y, mask)
    y = jax.lax.stop_gradient(jnp.asarray(y))  # an array of the default float type, NumPy input too
    m = y.shape[0]
    mask = jnp.ones((m,), bool) if mask is None else jnp.asarray(mask, bool)
    idx = jnp.arange(m)

    def nearest(rows):
        yi, i = rows[:, :3], rows[:, 3].astype(jnp.int32)
        d2 = jnp.sum((yi[:, None, :] - y[None, :, :]) ** 2, axis=-1)
        d2 = jnp.where(mask[None, :] & (idx[None, :] != i[:, None]), d2, jnp.inf)
        return jnp.min(d2, axis=1)

    rows = jnp.concatenate([y, idx[:, None].astype(y.dtype)], axis=1)
    return jnp.sqrt(_masked_median(map_blocks(nearest, rows, block), mask))


def median_distance(y, center, mask=None):
    """Median distance of the points y (m, 3) (over ``mask``) from center (3,). () float.
    InvalidInputError for y not (m, 3) real with m >= 1, center not (3,), mask not (m,)."""
    _check_points(y, mask)
    if tuple(jnp.shape(center)) != (3,):
        raise InvalidInputError(f"center must have shape (3,), got {tuple(jnp.shape(center))}")
    y = jax.lax.stop_gradient(jnp.asarray(y))  # an array of the default float type, NumPy input too
    mask = jnp.ones(y.shape[:1], bool) if mask is None else jnp.asarray(mask, bool)
    return _masked_median(jnp.linalg.norm(y - jax.lax.stop_gradient(center), axis=-1), mask)


def pose_status(y, mask, gamma, size, moments, refine, center, scale):
    """The status of a pose (module docs), traced.

    Args:
      y: (m, 3) the pre-scaled samples; mask: (m,) bool or None; gamma: () the pre-scaled gamma;
      size: () the reference size (0: degenerate input); moments: the region's
      :class:`jaxpose.moments.Moments` in the pre-scaled frame; refine: the grid's (static) refine;
      center (3,), scale (): the pose in world units.

    Returns:
      () int32, a :class:`Status` code.
    """
    sg = jax.lax.stop_gradient
    gamma = sg(gamma)
    width = jnp.sqrt(1.0 / (2.0 * jnp.maximum(gamma, jnp.finfo(y.dtype).tiny)))
    spacing = median_spacing(y, mask)
    cell = jnp.max(sg(moments.cell)) / refine
    spread = median_distance(y, moments.center, mask)
    finite = jnp.all(jnp.isfinite(center)) & jnp.isfinite(scale) & (scale > 0)
    volume, md = sg(moments.volume), sg(moments.mean_distance)
    conditions = [
        ~(size > 0) | ~jnp.all(jnp.isfinite(sg(y))),
        spacing > MAX_SPACING * width,
        cell > MAX_CELL * width,
        ~(volume > 0),
        ~(md >= MIN_SPREAD * spread),
        ~finite,
    ]
    codes = [Status.DEGENERATE_INPUT, Status.SPARSE_SAMPLES, Status.UNRESOLVED_GRID, Status.EMPTY_REGION,
             Status.COLLAPSED_REGION, Status.NOT_FINITE]
    return jnp.select(conditions, [jnp.int32(int(c)) for c in codes], jnp.int32(0))


def no_extent(points, mask=None):
    """() bool: the points (over ``mask``) have no extent in their dtype (every coordinate equal
    along each axis: one point repeated) or one of them is not finite: a degenerate input
    (:attr:`Status.DEGENERATE_INPUT`), whatever else is computed from it. Not differentiated.

    Args:
      points: (m, 3) float, m >= 1; mask: optional (m,) bool (False rows are padding, left out).
        Other shapes: InvalidInputError (:func:`_check_points`).
    """
    _check_points(points, mask, "points")
    x = jax.lax.stop_gradient(jnp.asarray(points))
    mask = jnp.ones(x.shape[:1], bool) if mask is None else jnp.asarray(mask, bool)
    lo = jnp.min(jnp.where(mask[:, None], x, jnp.inf), axis=0)
    hi = jnp.max(jnp.where(mask[:, None], x, -jnp.inf), axis=0)
    return ~(jnp.max(hi - lo) > 0) | ~jnp.all(jnp.isfinite(jnp.where(mask[:, None], x, 0)))


def unresolved_size(points, mask=None):
    """() bool: the points have an extent (not :func:`no_extent`), but their reference size
    (:func:`jaxpose.pose.frame.reference_frame`, s_ref = rms / sqrt(5/12), rms the root mean
    square of the distances from the mean) is out of what their dtype computes.

    The mean square sums squared coordinates: each square below the dtype's smallest normal
    number ``tiny`` is lost (flushed to 0 on CPU), at most 3 tiny per point, a relative error of
    the size of at most 1.5 tiny / rms^2; the sum of m squares overflows above ``max``. So the
    size is trusted where ``rms >= sqrt(1.5 tiny / MAX_ROUNDING)`` (its error at most
    ``MAX_ROUNDING``) and it is finite: in float32, RMS distances in [4.2e-18, 1.8e19 / sqrt(m)]
    (5.8e17 at m = 1024); in float64, [5.8e-153, 1.3e154 / sqrt(m)]. Outside, the OCSVM's
    pre-scaled frame (and so gamma's meaning) is lost: the size is 0, inf or NaN, or off by up to
    several percent, and the pose with it (docs/design.md, traced inputs out of range). Not
    differentiated.

    Args:
      points: (m, 3) real, m >= 1, as given to the pipeline (traced; integers are judged in the
        float dtype they compute in, :func:`jaxpose._validate.compute_dtype`); mask: optional (m,) bool.
        Other shapes: InvalidInputError (:func:`_check_points`).

    Example::

        unresolved_size(jnp.asarray(points * 1e-20, jnp.float32))   # True
    """
    _check_points(points, mask, "points")
    x = jax.lax.stop_gradient(_floats(points))  # (integers: the float dtype they compute in; was finfo's ValueError)
    _, size = reference_frame(x, mask)
    finfo = jnp.finfo(x.dtype)
    smallest = math.sqrt(1.5 * float(finfo.tiny) / MAX_ROUNDING)  # the least RMS whose size is trusted
    resolved = (size * REFERENCE_RMS >= smallest) & jnp.isfinite(size)
    return ~resolved & ~no_extent(x, mask)


def flag_range(pose, points, mask=None):
    """``pose`` with status OUT_OF_RANGE (and valid False) where :func:`unresolved_size`: the root
    cause, reported before what it leads to (a size of 0 that looks degenerate, an empty region, a
    valid-looking pose off by percents). For the OCSVM pipeline, whose size is its reference size."""
    out = unresolved_size(points, mask)
    status = jnp.where(out, jnp.int32(int(Status.OUT_OF_RANGE)), pose.status)
    return pose._replace(status=status.astype(jnp.int32), valid=status == 0)


def unresolved_offset(points, mask=None):
    """() bool: the points' coordinates are rounded by more than ``MAX_ROUNDING`` of their spread.

    eps(dtype) max |x| against the RMS distance of the points from their mean: a traced input far
    from the origin (|x| >> spread) has lost its shape before any computation, and every result
    computed from it is off by about that rounding. Concrete inputs are moved near the origin on
    the host first (:func:`jaxpose.host.host_frame`) and never trip this. Not differentiated.
    ``points`` (m, 3) real (integers judged in the float dtype they compute in), m >= 1, ``mask``
    None or (m,): InvalidInputError otherwise.
    """
    _check_points(points, mask, "points")
    x = jax.lax.stop_gradient(_floats(points))  # (integers: the float dtype they compute in; was finfo's ValueError)
    w = jnp.ones(x.shape[:1], bool) if mask is None else jnp.asarray(mask, bool)
    n = jnp.maximum(jnp.sum(w), 1).astype(x.dtype)
    big = jnp.max(jnp.where(w[:, None], jnp.abs(x), 0))
    mean = jnp.sum(jnp.where(w[:, None], x, 0), axis=0) / n
    mean = mean + jnp.sum(jnp.where(w[:, None], x - mean, 0), axis=0) / n
    d = jnp.where(w[:, None], x - mean, 0)
    rms = jnp.sqrt(jnp.sum(d * d) / n)
    return (rms > 0) & (jnp.finfo(x.dtype).eps * big > MAX_ROUNDING * rms)  # rms 0: degenerate, said apart


def flag_offset(pose, points, mask=None):
    """``pose`` with status FAR_FROM_ORIGIN (and valid False) where :func:`unresolved_offset`: the
    root cause, reported before what it leads to (rounded points that look degenerate or sparse)."""
    far = unresolved_offset(points, mask)
    status = jnp.where(far, jnp.int32(int(Status.FAR_FROM_ORIGIN)), pose.status)
    return pose._replace(status=status.astype(jnp.int32), valid=status == 0)
