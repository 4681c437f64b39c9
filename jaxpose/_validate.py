"""Input checks on concrete (NumPy) values, run before anything is traced.

Every public entry point calls these first, so that bad input gets a readable
:class:`JaxposeError` instead of a NaN or a JAX-internal traceback.
"""
from __future__ import annotations

import numbers

import numpy as np

__all__ = [
    "JaxposeError",
    "InvalidInputError",
    "ConvergenceError",
    "check_points",
    "check_gamma",
    "check_nu",
    "check_resolution",
    "is_traced",
]

MIN_POINTS = 4


class JaxposeError(Exception):
    """Root of the library's exceptions."""


class InvalidInputError(JaxposeError, ValueError):
    """An argument has the wrong shape, dtype or value."""


class ConvergenceError(JaxposeError, RuntimeError):
    """A solver stopped at its iteration cap (raised only when asked)."""


def is_traced(x) -> bool:
    """True for JAX tracers (inside jit/vmap/grad), where values cannot be checked."""
    import jax

    return isinstance(x, jax.core.Tracer)


def check_points(points, name: str = "points", min_points: int = MIN_POINTS):
    """Check an (m, 3) array of finite, not all identical points; return it unchanged.

    Tracers are returned as they are (only their shape is checked).
    """
    shape = getattr(points, "shape", None)
    if shape is None:
        try:
            points = np.asarray(points)
        except Exception as exc:  # ragged lists and the like
            raise InvalidInputError(f"{name} must be an (m, 3) array: {exc}") from None
        shape = points.shape
    if len(shape) != 2 or shape[1] != 3:
        raise InvalidInputError(f"{name} must have shape (m, 3), got {tuple(shape)}")
    if shape[0] < min_points:
        raise InvalidInputError(f"{name} needs at least {min_points} points, got {shape[0]}")
    if is_traced(points):
        return points
    arr = np.asarray(points)
    if not (np.issubdtype(arr.dtype, np.floating) or np.issubdtype(arr.dtype, np.integer)):
        raise InvalidInputError(f"{name} must be real numbers, got dtype {arr.dtype}")
    if not np.all(np.isfinite(arr)):
        bad = int(np.count_nonzero(~np.isfinite(arr).all(axis=1)))
        raise InvalidInputError(f"{name} has {bad} rows with NaN or inf coordinates")
    if np.all(arr == arr[0]):
        raise InvalidInputError(f"all {shape[0]} {name} are identical: no shape to normalize")
    return points


def _scalar(value, name):
    if is_traced(value):
        return None
    arr = np.asarray(value)
    if arr.ndim != 0 or not (np.issubdtype(arr.dtype, np.floating) or np.issubdtype(arr.dtype, np.integer)):
        raise InvalidInputError(f"{name} must be a real scalar, got {value!r}")
    v = float(arr)
    if not np.isfinite(v):
        raise InvalidInputError(f"{name} must be finite, got {v}")
    return v


def check_gamma(gamma):
    v = _scalar(gamma, "gamma")
    if v is not None and v <= 0:
        raise InvalidInputError(f"gamma must be > 0, got {v}")
    return gamma


def check_nu(nu):
    v = _scalar(nu, "nu")
    if v is not None and not 0.0 <= v <= 1.0:
        raise InvalidInputError(f"nu must be in [0, 1], got {v}")
    return nu


def check_resolution(resolution, minimum: int = 8):
    if not isinstance(resolution, numbers.Integral) or isinstance(resolution, bool):
        raise InvalidInputError(f"resolution must be an int, got {resolution!r}")
    if resolution < minimum:
        raise InvalidInputError(f"resolution must be >= {minimum}, got {resolution}")
    return int(resolution)
