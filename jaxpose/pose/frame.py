"""Reference frame of a point set: mean, size and principal axes, and the maps to and from it.

The OCSVM's gamma is made dimensionless by fitting it to points in the reference frame

    y = ((x - mean) / s_ref) @ axes,   s_ref = sqrt(mean ||x - mean||^2) / sqrt(5 / 12),

the RMS distance from the mean relative to that of a unit cube's surface (sqrt(5/12) ~ 0.6455),
so a unit cube's surface has s_ref = 1 and the paper's gamma range (0, 50] keeps its meaning.
The size is invariant to rotation and translation and proportional to scale, and the principal
axes turn with the object, so the grid of the volume integrals turns with it too: the pose is
equivariant under similarities up to float rounding, not only up to grid error.

Concrete inputs are first centered and scaled on the host in float64 (:func:`host_frame`), so
coordinates far from the origin keep their shape when they become float32. Meshes are moved by one
of their own vertices (:func:`anchor`), which is exact.
"""
from __future__ import annotations

import math

import jax
import jax.numpy as jnp

from .._validate import check_array, check_mask
from ..host import anchor, host_frame

__all__ = ["REFERENCE_RMS", "reference_frame", "principal_axes", "prescale", "host_frame", "anchor"]

REFERENCE_RMS = math.sqrt(5.0 / 12.0)


def reference_frame(points, mask=None):
    """Mean and reference size of a point set.

    Args:
      points: (m, 3) float.
      mask: optional (m,) bool; False rows (padding) are left out.

    Returns:
      mean (3,) and s_ref () in the units of ``points`` (module docs). The mean takes a second
      pass over the residuals, so offsets far from the origin lose no digits.

    Raises:
      InvalidInputError: ``points`` not (m, 3) real numbers with m >= 1, or ``mask`` not (m,)
        (shapes, known while tracing; no points gave a NaN frame, a (3,) point JAX's broadcast
        error).
    """
    _check(points, mask)
    m = points.shape[0]
    w = jnp.ones((m,), points.dtype) if mask is None else jnp.asarray(mask, points.dtype)
    n = jnp.sum(w)
    mean = jnp.sum(w[:, None] * points, axis=0) / n
    mean = mean + jnp.sum(w[:, None] * (points - mean), axis=0) / n
    d = points - mean
    ms = jnp.sum(w * jnp.sum(d * d, axis=-1)) / n
    # sqrt(ms) (NaN kept), without sqrt's infinite slope at 0 (identical points: a NaN derivative)
    rms = jnp.where(ms > 0, jnp.sqrt(jnp.where(ms > 0, ms, 1.0)), jnp.where(jnp.isnan(ms), ms, 0.0))
    return mean, rms / REFERENCE_RMS


def principal_axes(y, mask=None):
    """Orthonormal eigenvectors of the covariance of centered points.

    Args:
      y: (m, 3) float, centered.
      mask: optional (m,) bool.

    Returns:
      (3, 3) float, eigenvectors as columns, eigenvalues ascending. Treated as a constant for
      differentiation: the exact moments do not depend on the frame the grid is laid out in.

    Raises:
      InvalidInputError: as :func:`reference_frame` (a (3,) point was an einsum error).
    """
    _check(y, mask, "y")
    w = jnp.ones(y.shape[:1], y.dtype) if mask is None else jnp.asarray(mask, y.dtype)
    cov = jnp.einsum("m,mi,mj->ij", w, y, y) / jnp.sum(w)
    _, axes = jnp.linalg.eigh(jax.lax.stop_gradient(cov))
    return jax.lax.stop_gradient(axes)


def prescale(points, mask=None):
    """Points in the reference frame.

    Args:
      points: (m, 3) float; mask: optional (m,) bool.

    Returns:
      y (m, 3) = ((points - mean) / s_ref) @ axes; ``to_world``, the map of a point c of that
      frame back to mean + s_ref * axes @ c; and s_ref () (0 for degenerate input, where y is
      computed with 1 instead).

    Raises:
      InvalidInputError: as :func:`reference_frame` (a (3,) point or a batch (B, m, 3) was an
        einsum error).
    """
    mean, size = reference_frame(points, mask)
    safe = jnp.where(size > 0, size, 1.0)
    axes = principal_axes(points - mean, mask)
    y = ((points - mean) / safe) @ axes
    return y, (lambda c: mean + safe * (axes @ c)), size


def _check(points, mask, name="points"):
    """(m, 3) real ``points`` with m >= 1 and a ``mask`` None or (m,), by their shapes and dtype
    (known while tracing; values are not read: a NaN is the pose's status to report)."""
    check_array(points, name, 1, finite=False)
    check_mask(mask, jnp.shape(points)[0], name)
