"""Euclidean projection onto the capped simplex {a : 0 <= a_i <= C, sum(a) = 1}.

The threshold tau with a = clip(y - tau, 0, C) is found by safeguarded Newton steps under
``stop_gradient``; tau is then recomputed exactly from the active set,
tau = (sum_F y_i + C |U| - 1) / |F| (F: free, U: at the cap), which is a smooth
function of y on that set. So values are exact to rounding (sum(a) = 1 to ~eps)
and derivatives are the projection's true Jacobian, without nested implicit
differentiation of the search.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp

__all__ = ["projection_capped_simplex"]


def _find_tau(y, cap, max_steps):
    """tau with sum(clip(y - tau, 0, cap)) = 1: Newton steps on that piecewise-linear, decreasing
    sum, kept in a bracket [lo, hi] (bisection when a step would leave it), until the sum is 1 to
    rounding or tau stops moving, at most max_steps (typically 2-7 steps). () float."""
    dtype = y.dtype
    lo = jnp.min(y) - jnp.max(cap)  # sum(clip(y - lo, 0, C)) = sum(C) >= 1
    hi = jnp.max(y)  # sum = 0
    tol = 16 * jnp.finfo(dtype).eps

    def sums(tau):
        z = y - tau
        return jnp.sum(jnp.clip(z, 0.0, cap)), jnp.sum(((z > 0) & (z < cap)).astype(dtype))

    def running(state):
        _, _, _, s, _, it, moved = state
        return (jnp.abs(s - 1.0) > tol) & (it < max_steps) & moved

    def step(state):
        lo, hi, tau, s, n_free, it, _ = state
        lo, hi = jnp.where(s > 1.0, tau, lo), jnp.where(s > 1.0, hi, tau)
        newton = tau + (s - 1.0) / jnp.maximum(n_free, 1.0)  # slope of the sum: -n_free
        inside = (n_free > 0) & (newton > lo) & (newton < hi)
        new = jnp.where(inside, newton, 0.5 * (lo + hi))
        s, n_free = sums(new)
        return lo, hi, new, s, n_free, it + 1, new != tau

    tau = 0.5 * (lo + hi)
    state = (lo, hi, tau, *sums(tau), 0, jnp.asarray(True))
    return jax.lax.while_loop(running, step, state)[2]


def projection_capped_simplex(y, cap, iterations=None):
    """Project y (m,) onto {0 <= a_i <= cap_i, sum a = 1}; needs sum(cap) >= 1.

    y : (m,) float, cap : scalar or (m,) (a zero cap pins a coordinate to 0) -> (m,)
    iterations : at most this many steps to find tau (default 40 in float32, 64 in float64)
    """
    cap = jnp.asarray(cap, y.dtype)
    if iterations is None:
        iterations = 64 if y.dtype == jnp.float64 else 40
    ys, cs = jax.lax.stop_gradient(y), jax.lax.stop_gradient(cap)
    tau0 = _find_tau(ys, cs, iterations)
    z = ys - tau0
    free = (z > 0) & (z < cs)
    upper = z >= cs
    n_free = jnp.sum(free)
    tau_exact = (jnp.sum(jnp.where(free, y, 0.0)) + jnp.sum(jnp.where(upper, cap, 0.0)) - 1.0) / jnp.maximum(n_free, 1)
    tau = jnp.where(n_free > 0, tau_exact, tau0)
    return jnp.clip(y - tau, 0.0, cap)
