"""Active-set polishing: the exact solution on the support that an iterative solver stopped at.

Once the solver has stopped (:func:`jaxpose.occupancy.svdd.kkt_violation` <= tol), its iterate tells which
points are free (0 < a < C) and which are bounded (a = C). On that active set the dual is an
equality-constrained quadratic program whose solution is one linear solve,

    [2 K_FF  -1] [a_F]   [-2 K_FB C 1 ]
    [1^T      0] [mu ] = [1 - C |B|   ],

exact up to rounding. Where few points are free (small gamma, where the region tends to the
minimum enclosing ball and a handful of points carry it, or small nu) the first-order solvers
reach the tolerance with spurious small weights on points that belong at zero, and a tolerance
on the KKT violation bounds the objective, not the weights: along directions in which the
objective is flat (a ball held by three points in 3D) the region can be off by sqrt(tol). The
polished solution has none of that error when the active set is right.

It is reached by a primal active-set method: from the solver's iterate, step towards the solution
on the current free set as far as the box allows; a point whose weight reaches 0 leaves the free
set, one that reaches C becomes bounded; repeat (at most ``ROUNDS`` times) until the full step is
feasible. Each step lowers the objective. The result replaces the solver's only if it is reached
within the rounds and its KKT violation is smaller; with more than
``MAX_FREE`` free points (most points free: the default gamma) nothing is attempted, the linear
solve being O(|F|^3) and the iterate already well determined there.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp

from ..grid import first_true
from ..kernels import gaussian_kernel
from .problem import kkt_violation

__all__ = ["polish", "MAX_FREE", "ROUNDS"]

MAX_FREE = 128  # free points a polish is attempted for (a static size: its linear system is (MAX_FREE + 1)^2)
ROUNDS = MAX_FREE  # active-set steps (each drops or caps at least one point)


def _solve_free(points, gamma, caps, free, bounded, k):
    """Weights (m,) from the equality-constrained problem on ``free`` (at most k points) with the
    ``bounded`` points at their caps; the others 0."""
    dtype = points.dtype
    m = points.shape[0]
    idx = first_true(free, k)
    valid = (jnp.arange(k) < jnp.sum(free)).astype(dtype)
    a_b = jnp.where(bounded, caps, 0.0)
    xs = points[idx]
    kff = gaussian_kernel(xs, xs, gamma)
    rhs = -2.0 * (gaussian_kernel(xs, points, gamma) @ a_b) * valid
    ridge = 10.0 * jnp.finfo(dtype).eps * k
    a_mat = 2.0 * kff * valid[:, None] * valid[None, :] + jnp.diag(1.0 - valid) + ridge * jnp.diag(valid)
    system = jnp.concatenate([jnp.concatenate([a_mat, -valid[:, None]], axis=1),
                              jnp.concatenate([valid, jnp.zeros((1,), dtype)])[None, :]])
    sol = jnp.linalg.solve(system, jnp.concatenate([rhs, (1.0 - jnp.sum(a_b))[None]]))
    a_f = jnp.where(valid > 0, sol[:k], 0.0)
    return a_b + jnp.zeros((m,), dtype).at[idx].add(a_f)


def polish(points, gamma, caps, mask, alpha, violation, matvec, max_free=MAX_FREE, rounds=ROUNDS):
    """The polished solution (module docs), or ``alpha`` where polishing does not improve it.

    Args:
      points: (m, 3); gamma: (); caps: (m,) upper bounds; mask: (m,) bool; alpha: (m,) the
      solver's feasible iterate; violation: () its :func:`kkt_violation`; matvec: v -> K v;
      max_free, rounds: (static) see ``MAX_FREE``, ``ROUNDS``.

    Returns:
      alpha (m,) and its violation (); no derivatives.
    """
    sg = jax.lax.stop_gradient
    points, gamma, caps, alpha = sg(points), sg(gamma), sg(caps), sg(alpha)
    free = mask & (alpha > 0) & (alpha < caps)
    bounded = mask & (alpha >= caps) & (alpha > 0)
    inf = jnp.asarray(jnp.inf, alpha.dtype)

    def step(state):
        a, f, b, _, r = state
        d = _solve_free(points, gamma, caps, f, b, max_free) - a
        # ratio test: the longest step towards the equality solution that stays in the box
        t_lo = jnp.where(f & (d < 0), a / jnp.where(d < 0, -d, 1.0), inf)
        t_hi = jnp.where(f & (d > 0), (caps - a) / jnp.where(d > 0, d, 1.0), inf)
        t = jnp.minimum(1.0, jnp.minimum(jnp.min(t_lo), jnp.min(t_hi)))
        to_zero, to_cap = f & (t_lo <= t) & (t < 1), f & (t_hi <= t) & (t < 1)
        a = jnp.where(f, a + t * d, a)
        a = jnp.where(to_zero, 0.0, jnp.where(to_cap, caps, a))
        return a, f & ~to_zero & ~to_cap, b | to_cap, t >= 1.0, r + 1

    def attempt(_):
        state = (alpha, free, bounded, jnp.asarray(False), jnp.asarray(0))
        a, _, _, done, _ = jax.lax.while_loop(lambda s: ~s[3] & (s[4] < rounds), step, state)
        feasible = done & jnp.all(jnp.isfinite(a)) & jnp.all(jnp.where(mask, (a >= 0) & (a <= caps), a == 0))
        a = jnp.where(feasible, a, alpha)
        new = jnp.where(feasible, kkt_violation(a, matvec(a), caps, mask)[0], inf)
        better = new < violation
        return jnp.where(better, a, alpha), jnp.where(better, new, violation)

    return jax.lax.cond((jnp.sum(free) <= max_free) & jnp.any(free), attempt, lambda _: (alpha, violation), None)
