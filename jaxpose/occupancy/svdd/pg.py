"""Accelerated projected gradient (FISTA) for the SVDD dual; the only module that imports jaxopt.

Each step is one kernel product: a step of fixed length 1 / L along -2 K a, then the exact
Euclidean projection onto the capped simplex (``projection_capped_simplex``), with Nesterov
momentum dropped whenever it points uphill (gradient restart, O'Donoghue and Candes 2015).

The step. Every iterate lies on the plane sum a = 1, and the projection removes any gradient
component along the ones vector (projecting y + t 1 gives the projection of y), so the
objective's curvature that matters is that of K on the sum-zero subspace: L = 2 lambda_max(P K P),
P = I - 1 1^T / m. At the default gamma it is a few percent below 2 lambda_max(K); at small gamma,
where K = 1 1^T - gamma D + O(gamma^2), lambda_max(K) ~ m is the constant part while
lambda_max(P K P) = O(gamma m), and a step from K would be ~1 / gamma times too short.
lambda_max(P K P) comes from 20 power steps (a close lower bound, raised by 4 %) and the
Gershgorin bound of K (the largest row sum, a guaranteed upper bound), whichever is smaller.
"""
from __future__ import annotations

import warnings

import jax
import jax.numpy as jnp

from ..kernels import power_iteration
from .projection import projection_capped_simplex
from .problem import kernel_ops, kkt_violation

__all__ = ["solve_pg"]


_JAXOPT_NOTICE = r"JAXopt is no longer maintained"
"""The start of the DeprecationWarning jaxopt (archived) gives when it is imported: the one warning
:func:`_jaxopt` leaves out."""


def _jaxopt():
    """jaxopt, imported on first use (its import warns), without its notice that it is no longer
    maintained (:data:`_JAXOPT_NOTICE`), which is this module's to know (``python -W error`` runs
    ``--method ocsvm``). Every other warning is left to the caller's filters."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=_JAXOPT_NOTICE, category=DeprecationWarning)
        import jaxopt
    return jaxopt


def solve_pg(points, gamma, caps, mask, init_alpha, config, *, tol=None, max_iter=None, restart=True):
    """Solve the dual from ``init_alpha`` by projected gradient (no derivatives).

    Args:
      points: (m, 3); gamma: (); caps: (m,) upper bounds; mask: (m,) bool;
      init_alpha: (m,) start, projected onto the feasible set first;
      config: :class:`jaxpose.config.SolverConfig` (check_every, kernel, block);
      tol, max_iter: the stopping rule's tolerance and iteration cap (default ``config.tol`` and
        ``config.max_iter``; may be traced); restart: gradient restart.

    Returns:
      alpha (m,), K alpha (m,), iterations (), relative KKT violation ().
      The stopping rule (:func:`kkt_violation` <= tol) is checked every ``check_every`` steps.
    """
    jaxopt = _jaxopt()

    tol = config.tol if tol is None else tol
    max_iter = config.max_iter if max_iter is None else max_iter
    check_every = config.check_every
    dtype = points.dtype
    matvec = kernel_ops(points, gamma, config.kernel, config.block)[0]
    m = points.shape[0]
    w = mask.astype(dtype)
    center = lambda v: w * (v - jnp.sum(w * v) / jnp.sum(w))  # P: sum-zero on the points that take part
    start = center(jnp.sin(jnp.arange(m, dtype=dtype) * 2.399963))  # deterministic, no structure in the order
    lam = power_iteration(lambda v: center(matvec(center(v))), m, dtype, iterations=20, start=start)
    gersh = jnp.max(jnp.where(mask, matvec(mask.astype(dtype)), 0.0))
    step = 1.0 / (2.0 * jnp.minimum(1.04 * lam, gersh))

    def fun(a):
        Ka = matvec(a)
        return jnp.vdot(a, Ka), 2.0 * Ka

    pg = jaxopt.ProjectedGradient(
        fun=fun,
        projection=lambda y, c: projection_capped_simplex(y, c),
        stepsize=lambda _: step,
        acceleration=True,
        value_and_grad=True,
        maxiter=max_iter,
        implicit_diff=False,
        jit=False,
    )
    a0 = projection_capped_simplex(init_alpha, caps)
    state0 = pg.init_state(a0, caps)
    viol0, _ = kkt_violation(a0, matvec(a0), caps, mask)

    def cond(carry):
        _, _, it, viol = carry
        return (viol > tol) & (it < max_iter)

    def body(carry):
        a, state, it, _ = carry

        def inner(_, c):
            a, state = c
            nxt = pg.update(a, state, caps)
            if restart:  # drop momentum when it points uphill
                up = jnp.vdot(state.velocity - nxt.params, nxt.params - a) > 0
                st = nxt.state
                st = st._replace(t=jnp.where(up, 1.0, st.t), velocity=jnp.where(up, nxt.params, st.velocity))
                return nxt.params, st
            return nxt.params, nxt.state

        a, state = jax.lax.fori_loop(0, check_every, inner, (a, state))
        viol, _ = kkt_violation(a, matvec(a), caps, mask)
        return a, state, it + check_every, viol

    a, _, it, viol = jax.lax.while_loop(cond, body, (a0, state0, jnp.asarray(0), viol0))
    return a, matvec(a), it, viol
