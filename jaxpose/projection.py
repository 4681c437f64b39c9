"""Euclidean projection onto the capped simplex {a : 0 <= a_i <= C, sum(a) = 1}.

The threshold tau with a = clip(y - tau, 0, C) is bracketed by bisection under
``stop_gradient``; tau is then recomputed exactly from the active set,
tau = (sum_F y_i + C |U| - 1) / |F| (F: free, U: at the cap), which is a smooth
function of y on that set. So values are exact to rounding (sum(a) = 1 to ~eps)
and derivatives are the projection's true Jacobian, without nested implicit
differentiation of the bisection.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp

__all__ = ["projection_capped_simplex"]


def _bisect_tau(y, cap, iterations):
    lo = jnp.min(y) - jnp.max(cap)  # sum(clip(y - lo, 0, C)) = sum(C) >= 1
    hi = jnp.max(y)  # sum = 0

    def body(_, bounds):
        lo, hi = bounds
        mid = 0.5 * (lo + hi)
        s = jnp.sum(jnp.clip(y - mid, 0.0, cap))
        return jnp.where(s > 1.0, mid, lo), jnp.where(s > 1.0, hi, mid)

    lo, hi = jax.lax.fori_loop(0, iterations, body, (lo, hi))
    return 0.5 * (lo + hi)


def projection_capped_simplex(y, cap, iterations=None):
    """Project y (m,) onto {0 <= a_i <= cap_i, sum a = 1}; needs sum(cap) >= 1.

    y : (m,) float, cap : scalar or (m,) (a zero cap pins a coordinate to 0) -> (m,)
    """
    cap = jnp.asarray(cap, y.dtype)
    if iterations is None:
        iterations = 64 if y.dtype == jnp.float64 else 40
    ys, cs = jax.lax.stop_gradient(y), jax.lax.stop_gradient(cap)
    tau0 = _bisect_tau(ys, cs, iterations)
    z = ys - tau0
    free = (z > 0) & (z < cs)
    upper = z >= cs
    n_free = jnp.sum(free)
    tau_exact = (jnp.sum(jnp.where(free, y, 0.0)) + jnp.sum(jnp.where(upper, cap, 0.0)) - 1.0) / jnp.maximum(n_free, 1)
    tau = jnp.where(n_free > 0, tau_exact, tau0)
    return jnp.clip(y - tau, 0.0, cap)
