"""Sequential minimal optimization (libsvm's algorithm) for the SVDD dual, in JAX.

Each update moves mass between the most violating pair (second-order working-set selection,
Fan, Chen and Lin 2005) and keeps the gradient G = K a up to date with two kernel columns: O(m)
per update, no kernel matrix needed. The stopping rule is checked every ``SMO_GROUP`` updates
(updates never raise the objective, so the few after convergence only help); G is recomputed
exactly at the end of each sweep, since it drifts in float32. Started cold, SMO puts alpha = C on
the lowest-density points (the likely bounded support vectors) until the mass is 1.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp

from .projection import projection_capped_simplex
from .problem import kernel_ops, kkt_violation

__all__ = ["solve_smo", "density_start", "SMO_GROUP"]

SMO_GROUP = 8  # updates between two checks of the stopping rule


def density_start(matvec, caps, mask):
    """A feasible start (m,): alpha = C on the lowest kernel-density points (K 1) until sum 1."""
    dtype = caps.dtype
    dens = jnp.where(mask, matvec(mask.astype(dtype)), jnp.inf)
    order = jnp.argsort(dens)
    c = jnp.max(caps)
    before = jnp.arange(caps.shape[0], dtype=dtype) * c  # mass given to the lower-density points
    a = jnp.zeros_like(caps).at[order].set(jnp.clip(1.0 - before, 0.0, c))
    return jnp.where(mask, a, 0.0)


def first_index(x, value):
    """The first i with x[i] == value (as argmin / argmax break ties), by two vector reductions
    (XLA's CPU variadic argmin / argmax is a scalar loop). () int."""
    return jnp.min(jnp.where(x == value, jnp.arange(x.shape[0]), x.shape[0] - 1))


def solve_smo(points, gamma, caps, mask, init_alpha, config, tol, max_iter, density_start_=True):
    """Solve the dual by SMO (no derivatives).

    Args:
      points: (m, 3); gamma: (); caps: (m,); mask: (m,) bool;
      init_alpha: (m,) warm start (projected), used when ``density_start_`` is False;
      config: :class:`jaxpose.config.SolverConfig` (kernel, block);
      tol: () the stopping rule's tolerance; max_iter: () cap on pair updates (never exceeded);
        both may be traced.

    Returns:
      alpha (m,), K alpha (m,), pair updates (), relative KKT violation () from an exact K alpha.
    """
    dtype = points.dtype
    inf = jnp.asarray(jnp.inf, dtype)
    matvec, column = kernel_ops(points, gamma, config.kernel, config.block)
    if density_start_:
        a0 = density_start(matvec, caps, mask)
    else:
        a0 = projection_capped_simplex(init_alpha, caps)

    violation = lambda a, G: kkt_violation(a, G, caps, mask)[0]

    def step(carry):
        a, G, it = carry
        low = jnp.where(mask & (a < caps), G, inf)
        g_i = jnp.min(low)
        i = first_index(low, g_i)  # most violating pair: i gains mass
        ki = column(i)
        d = G - g_i
        quad = jnp.maximum(2.0 - 2.0 * ki, jnp.finfo(dtype).eps)  # k(x,x) = 1
        score = jnp.where(mask & (a > 0) & (d > 0), d * d / quad, -inf)
        best = jnp.max(score)
        j = first_index(score, best)  # ... from j, the largest decrease of the objective
        delta = jnp.minimum(jnp.minimum(d[j] / quad[j], caps[i] - a[i]), a[j])
        live = jnp.isfinite(best) & (it < max_iter)
        delta = jnp.where(live, delta, 0.0)
        a = a.at[i].add(delta).at[j].add(-delta)
        G = G + delta * (ki - column(j))
        return a, G, it + live.astype(it.dtype)

    def steps(carry):
        a, G, it, _ = carry
        a, G, it = jax.lax.fori_loop(0, SMO_GROUP, lambda _, c: step(c), (a, G, it))  # rolled: one step compiled
        return a, G, it, violation(a, G)

    def running(carry):
        return (carry[3] > tol) & (carry[2] < max_iter)

    def sweep(carry):
        a, _, it, _ = jax.lax.while_loop(running, steps, carry)
        G = matvec(a)
        return a, G, it, violation(a, G)

    G0 = matvec(a0)
    a, G, it, viol = jax.lax.while_loop(running, sweep, (a0, G0, jnp.asarray(0), violation(a0, G0)))
    return a, G, it, viol
