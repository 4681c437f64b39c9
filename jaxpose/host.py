"""Host-side frames of concrete inputs (NumPy, float64): what is moved out before device work.

Coordinates far from the origin (scanner or GIS units) lose their shape in float32, and even in
float64 once they are squared or averaged naively. :func:`host_frame` gives the mean and RMS size of
a point set without overflow, so that (x - mean) / size is of order 1; :func:`anchor` gives a vertex
by which a mesh can be moved exactly. No JAX here: NumPy estimators use it without importing JAX.
"""
from __future__ import annotations

import numpy as np

from ._validate import InvalidInputError, check_array, check_concrete, compute_dtype

__all__ = ["host_frame", "anchor", "check_cast", "check_query_cast", "MAX_ROUNDING"]

MAX_ROUNDING = 1e-3  # rounding of the largest coordinate (eps |x|max) / the points' RMS spread


def host_frame(points, name: str = "points"):
    """Mean and RMS distance of concrete points, in float64 NumPy, without overflow.

    Args:
      points: (m, 3) array-like of finite numbers.
      name: how error messages call the points.

    Returns:
      mean (3,) float64 and rms () float. Dividing ``points - mean`` by ``rms`` gives
      coordinates of order 1 that keep their shape in float32, whatever the offset or the units.

    Raises:
      InvalidInputError: traced points, points not (m, 3) finite real numbers with m >= 1
        (:func:`jaxpose._validate.check_array`; complex ones lost their imaginary part with a NumPy
        warning, none were NumPy's 'zero-size array to reduction'), named ``name``; points all
        identical (one point: no spread); a frame the compute dtype cannot represent.
    """
    check_concrete(name, points)  # (np.asarray of a tracer: JAX's TracerArrayConversionError)
    given = np.asarray(check_array(points, name, 1))
    arr = np.asarray(given, dtype=np.float64)
    big = float(np.max(np.abs(arr)))
    # the mean as an input point plus the mean of the differences from it: far from the origin the
    # differences are exact (Sterbenz), so the mean keeps every digit the offset leaves
    with np.errstate(over="ignore", invalid="ignore"):  # coordinates near the float64 limit: refused below
        base = anchor(arr) if np.all(np.isfinite(arr)) else np.zeros(arr.shape[1:])
    residual = arr - base
    spread0 = float(np.max(np.abs(residual))) if residual.size else 0.0
    unit = spread0 if 0 < spread0 < np.inf else 1.0
    mean = base + np.mean(residual / unit, axis=0) * unit
    d = arr - mean
    spread = float(np.max(np.abs(d)))
    rms = spread * float(np.sqrt(np.mean(np.sum((d / spread) ** 2, axis=1)))) if spread > 0 else 0.0
    finfo = np.finfo(compute_dtype(points))
    if rms == 0 and big <= float(finfo.max):  # (it read "outside the range of float32 (rescale the input ...)")
        same = "one point" if len(arr) == 1 else f"all {len(arr)} identical"
        raise InvalidInputError(f"{name} have no spread to scale by ({same}); give at least two distinct points")
    if not (np.all(np.isfinite(mean)) and np.isfinite(rms)) or big > float(finfo.max) or not rms > float(finfo.tiny):
        raise InvalidInputError(
            f"{name} span {rms:.3g} at coordinates up to {big:.3g}: outside the range of {finfo.dtype} "
            f"(rescale the input, or enable jax_enable_x64 for float64)"
        )
    return mean, rms


def check_cast(points, name: str = "points"):
    """Refuse concrete points that their cast to the compute dtype (:func:`compute_dtype`: float64
    points become float32 with x64 off) rounds by more than ``MAX_ROUNDING`` of their RMS spread
    (:data:`MAX_ROUNDING`, the bound :mod:`jaxpose.pose.validity` flags traced
    inputs by), or beyond the compute dtype's range (:func:`host_frame`'s refusal). For functions
    that compute on the points in the frame given (:func:`jaxpose.fit_svdd`), where
    :func:`jaxpose.normalize` moves them near the origin on the host first. Returns ``points``.

    Raises:
      InvalidInputError: the cast loses the points' shape, naming the fix (move them near the
        origin first, or enable jax_enable_x64).
    """
    arr = np.asarray(points)
    dtype = compute_dtype(arr)
    rounding = _rounding(arr, dtype)
    if rounding == 0:  # exact (float16, small integers, float64 values that float32 holds)
        return points
    _, rms = host_frame(arr, name)
    if rounding > MAX_ROUNDING * rms:
        raise InvalidInputError(
            f"{name} lie so far from the origin, relative to their spread, that {dtype} (JAX's compute dtype "
            f"here) cannot resolve them: the cast rounds them by {rounding:.3g}, {rounding / rms:.3g} of their "
            f"RMS spread {rms:.3g} (above {MAX_ROUNDING:g}); subtract an offset first (the same from every "
            "point given later, e.g. to decision_function), or enable jax_enable_x64 for float64"
        )
    return points


def check_query_cast(x, dtype, spread, name="x"):
    """Refuse concrete query points ``x`` that their cast to a model's ``dtype`` rounds by more than
    ``MAX_ROUNDING`` of the model's RMS ``spread`` (the spread of the points it was fitted on), or
    beyond ``dtype``'s range: :func:`check_cast`'s rule, measured against the model's size, since a
    query set need have no spread of its own (one point). A ``spread`` of 0 (a model of one point)
    refuses only the range. For :func:`jaxpose.decision_function`. Returns ``x``.

    Raises:
      InvalidInputError: the cast loses the queries' place relative to the model, naming the fix.
    """
    arr = np.asarray(x)
    dtype = np.dtype(dtype)
    rounding = _rounding(arr, dtype)
    if np.isinf(rounding):
        raise InvalidInputError(
            f"{name} has coordinates up to {float(np.max(np.abs(arr.astype(np.float64)))):.3g}: outside the range of "
            f"{dtype} (the model's dtype); give the queries in the model's frame")
    if not (spread > 0 and rounding > MAX_ROUNDING * spread):  # (exact casts: 0; a model of one point: no spread)
        return x
    raise InvalidInputError(
        f"{name} lies so far from the origin, relative to the model's spread, that {dtype} (the model's dtype) cannot "
        f"resolve it: the cast rounds it by {rounding:.3g}, {rounding / spread:.3g} of the RMS spread {spread:.3g} of "
        f"the points the model was fitted on (above {MAX_ROUNDING:g}); subtract from the queries the offset "
        "subtracted from those points, or fit and query in float64 (jax_enable_x64)")


def _rounding(arr, dtype) -> float:
    """The largest change of an array's values by its cast to ``dtype`` (inf: beyond its range; 0:
    already ``dtype``, or exact)."""
    if arr.dtype == dtype:
        return 0.0
    exact = arr.astype(np.float64)
    with np.errstate(over="ignore", invalid="ignore"):  # beyond the dtype's range: inf
        return float(np.max(np.abs(arr.astype(dtype).astype(np.float64) - exact), initial=0.0))


def anchor(vertices):
    """The vertex nearest the middle of the bounding box, (3,) float64.

    Far from the origin (coordinates much larger than the shape's extent) x - a is exact
    (Sterbenz's lemma: nearby floats), so geometry moved by it keeps every digit of its shape; near
    the origin the difference rounds by at most half an ulp of the coordinate.

    Raises:
      InvalidInputError: traced vertices, or none.
    """
    check_concrete("vertices", vertices)
    v = np.asarray(vertices, np.float64)
    if v.ndim != 2 or not len(v):  # (NumPy's 'zero-size array to reduction operation minimum')
        raise InvalidInputError(f"vertices must have shape (n >= 1, d), got {v.shape}")
    columns = [v[:, axis] for axis in range(v.shape[1])]  # (per column: NumPy's axis-0 min of (n, 3) is slow)
    middle = [0.5 * (c.min() + c.max()) for c in columns]
    with np.errstate(over="ignore"):  # beyond ~1e154 from the middle: inf, never the nearest
        squared = sum((c - m) * (c - m) for c, m in zip(columns, middle))
    return v[int(np.argmin(squared))].copy()
