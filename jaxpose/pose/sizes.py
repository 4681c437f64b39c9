"""Point counts: the subset a fit uses above ``MAX_POINTS``, and padded row counts that share compilations.

A jitted function compiles once per input shape. :func:`bucket` rounds a point count up to one of
four sizes per octave, and :func:`pad` fills the extra rows (masked out of every sum), so point
sets of many sizes share a few compilations. Above ``MAX_POINTS`` points, :func:`subsample_index`
picks a seeded uniform subset, so the cost of a fit is bounded whatever the input's size.
"""
from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from .._validate import InvalidInputError, check_concrete, check_int

__all__ = ["MAX_POINTS", "bucket", "subsample_index", "pad"]

MAX_POINTS = 4096  # larger point sets are subsampled (seeded, uniform) to this many


def bucket(m: int) -> int:
    """The row count m points are padded to, so that point counts share compilations.

    Args:
      m: int >= 1, the number of points.

    Returns:
      int: m itself up to 8; else the smallest multiple of 2^(k-3) that is >= m, where
      2^(k-1) < m <= 2^k (four sizes per octave, at most 25 % padding). ``bucket(400) == 448``.

    Raises:
      InvalidInputError: m not an int >= 1 (int() took 1.5 as 1, and 0 or -5 came back as given).
    """
    m = check_int(m, "m", 1)
    if m <= 8:
        return m
    step = 2 ** ((m - 1).bit_length() - 3)
    return -(-m // step) * step


def subsample_index(m: int, max_points: int | None, seed: int = 0):
    """Which of m points a fit uses.

    Args:
      m: the number of points; max_points: None (no limit) or an int >= 1; seed: int >= 0.

    Returns:
      None when m <= max_points (or max_points is None: every point); else (max_points,) int,
      the sorted indices of a uniform random subset without replacement
      (``numpy.random.default_rng(seed)``). It depends on (m, max_points, seed) only, so traced
      and concrete calls take the same points.

    Raises:
      InvalidInputError: m not an int >= 0, seed not an int >= 0, max_points neither None nor an
        int >= 1 (:func:`jaxpose._validate.check_int`).
    """
    m = check_int(m, "m", 0)
    seed = check_int(seed, "seed", 0)
    max_points = None if max_points is None else check_int(max_points, "max_points", 1)
    if max_points is None or m <= max_points:
        return None
    return np.sort(np.random.default_rng(seed).choice(m, size=max_points, replace=False))


def pad(sets, rows, dtype):
    """Point sets stacked and padded to ``rows`` rows.

    Args:
      sets: sequence of (m_i, 3) arrays, m_i <= rows; rows: int; dtype: the floating dtype.

    Returns:
      (n, rows, 3) JAX points of ``dtype`` (float64 becomes float32 unless x64 is on) and (n, rows)
      bool mask, False on padding rows, which repeat each set's first point.

    Raises:
      InvalidInputError: a set that is empty, not (m_i, 3) or has more than ``rows`` rows (NumPy's
        broadcast ValueError and IndexError).
    """
    rows = check_int(rows, "rows", 1)
    check_concrete("sets", *sets)  # (padding is NumPy: under jit, vmap normalize instead)
    for i, a in enumerate(sets):
        if np.ndim(a) != 2 or np.shape(a)[1] != 3 or not 1 <= len(a) <= rows:
            raise InvalidInputError(f"sets[{i}] must have shape (m, 3) with 1 <= m <= rows={rows}, got {np.shape(a)}")
    pts = np.empty((len(sets), rows, 3), dtype)
    mask = np.zeros((len(sets), rows), bool)
    for i, a in enumerate(sets):
        pts[i, : len(a)] = a
        pts[i, len(a):] = a[0]  # padding sits on a real point, masked out
        mask[i, : len(a)] = True
    return jnp.asarray(pts), jnp.asarray(mask)  # float64 becomes float32 unless x64 is on
