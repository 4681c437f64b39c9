"""Trend derivatives of the SVDD solution in gamma and nu: secant slopes over theta (1 +- delta).

With C = 1 / (nu m) the dual solution is a continuous, piecewise linear function of C (a
parametric QP whose parameter enters only the box constraints); in gamma it is piecewise smooth.
Each time a point moves between zero, free and bounded the slope jumps, and on a few hundred to a
few thousand samples such breakpoints lie ~0.1 % of nu (or of gamma) apart, so the exact one-sided
derivative is the slope of one tiny piece. The secant over theta (1 +- delta),

    d alpha / d theta := (alpha*(theta (1 + delta)) - alpha*(theta (1 - delta))) / (2 theta delta),

and likewise for the offset mu, is the slope of the trend over the pieces it spans: what a change
of theta by a few percent really does. Each parameter costs two solves at a tighter tolerance
(so that the solver error is small against the change), warm-started from the solution. On CPU
they run SMO first (:func:`end_solver`): from a warm start a few thousand pair updates of O(m)
each reach the tolerance, where projected gradient needs about a thousand O(m^2) kernel products.

:func:`with_secants` attaches these slopes as the tangents of (alpha, mu) through a custom JVP:
the values are untouched and nothing is solved unless a derivative is taken. In gamma the kernel
of f(x) = 2 k(x)^T alpha - mu also depends on gamma directly; that part stays exact (the moments
differentiate it), only the solution's response is a secant.
"""
from __future__ import annotations

import dataclasses
from functools import partial

import jax
import jax.numpy as jnp

from .fit import pick_solver, solve_svdd

__all__ = ["slopes", "nu_slopes", "with_secants", "with_nu_secant", "end_solver", "PARAMS"]

PARAMS = ("gamma", "nu")


def end_solver(config):
    """The solver of the two end solves (static): ``"auto"`` on CPU (SMO from the warm start,
    projected gradient after it if SMO has not converged within its budget, as in
    :func:`jaxpose.occupancy.svdd.pick_solver`), else ``config.solver`` (on accelerators kernel products
    are cheap and thousands of sequential pair updates are not)."""
    return "auto" if jax.default_backend() == "cpu" else config.solver


def slopes(points, gamma, nu, mask, alpha0, config, delta, tol, param="nu", iterations=None, max_iter=None):
    """Secant slopes of (alpha, mu) in ``param`` over [theta (1 - delta), theta (1 + delta)]
    (nu's upper end capped at 1).

    Args:
      points: (m, 3); gamma, nu: (); mask: (m,) bool or None; alpha0: (m,) warm start (the
        solution at (gamma, nu)); config: SolverConfig of the solves (its tol replaced by ``tol``);
      delta: relative half-width; param: "gamma" or "nu"; iterations: None (each end solved to
        ``tol`` by :func:`end_solver`, within ``max_iter`` iterations, default ``config.max_iter``;
        ``tol`` and ``max_iter`` may be traced) or a number of projected-gradient steps both ends
        take from alpha0 in lock-step.

    Returns:
      (m,) and () slopes, without derivatives (non-finite slopes are 0).
    """
    sg = jax.lax.stop_gradient
    nu, points, gamma, alpha0 = sg(nu), sg(points), sg(gamma), sg(alpha0)
    theta = gamma if param == "gamma" else nu
    lo = theta * (1.0 - delta)
    hi = theta * (1.0 + delta) if param == "gamma" else jnp.minimum(theta * (1.0 + delta), 1.0)
    if iterations is None:
        tight = dataclasses.replace(config, solver=end_solver(config))
        stops = (tol, config.max_iter if max_iter is None else max_iter)
    else:  # lock-step: both ends run the same projected-gradient steps from the same start
        tight = dataclasses.replace(config, solver="pg")
        stops = (1e-300, int(iterations))

    def solve(g, n, a0):
        s = solve_svdd(points, g, n, mask, a0, tight, *stops)
        return s.alpha, s.offset

    end = (lambda t: solve(t, nu, alpha0)) if param == "gamma" else (lambda t: solve(gamma, t, alpha0))
    ends = jnp.stack([hi, lo])
    # SMO's sequential updates: one end after the other (a vmap would run both to the slower's
    # count); projected gradient: both at once (in nu one kernel matrix, two columns per product)
    sequential = pick_solver(tight.solver, points.shape[0]) != "pg"
    a, mu = jax.lax.map(end, ends) if sequential else jax.vmap(end)(ends)
    slope, mu_slope = (a[0] - a[1]) / (hi - lo), (mu[0] - mu[1]) / (hi - lo)
    return jnp.where(jnp.isfinite(slope), slope, 0.0), jnp.where(jnp.isfinite(mu_slope), mu_slope, 0.0)


def nu_slopes(points, gamma, nu, mask, alpha0, config, delta, tol):
    """:func:`slopes` in nu."""
    return slopes(points, gamma, nu, mask, alpha0, config, delta, tol, "nu")


@partial(jax.custom_jvp, nondiff_argnums=(8, 9, 10, 11))
def _secant_identity(alpha, mu, gamma, nu, points, mask, tol, max_iter, config, params, deltas, iterations):
    """(alpha, mu) unchanged; their tangents in the parameters ``params`` are the secant slopes.
    ``tol``, ``max_iter``: the end solves' stopping numbers (arguments, so that they may be traced;
    not differentiated)."""
    return alpha, mu


@partial(_secant_identity.defjvp, symbolic_zeros=True)
def _secant_identity_jvp(config, params, deltas, iterations, primals, tangents):
    from jax.custom_derivatives import SymbolicZero

    alpha, mu, gamma, nu, points, mask, tol, max_iter = primals
    dalpha, dmu, dgamma, dnu = tangents[:4]
    zero = lambda t: isinstance(t, SymbolicZero)
    da = jnp.zeros_like(alpha) if zero(dalpha) else dalpha
    dm = jnp.zeros_like(mu) if zero(dmu) else dmu
    for name, d, delta in zip(PARAMS, (dgamma, dnu), deltas):
        if name not in params or zero(d):  # no solve for a parameter that is not perturbed
            continue
        s_alpha, s_mu = slopes(points, gamma, nu, mask, alpha, config, delta, tol, name, iterations, max_iter)
        da = da + d.astype(alpha.dtype) * s_alpha
        dm = dm + d.astype(alpha.dtype) * s_mu
    return (alpha, mu), (da, dm)


def with_secants(svdd, gamma, nu, config, params=PARAMS, deltas=(0.015, 0.015), tol=1e-6, iterations=None,
                 max_iter=None):
    """The same SVDD values whose derivatives in the parameters ``params`` are secant slopes.

    Args:
      svdd: the solution at (gamma, nu) with those parameters under ``stop_gradient`` (its alpha
        may carry other derivatives: in the points, or the implicit one in a parameter not in
        ``params``); gamma, nu: () the traced parameters; config: SolverConfig (static);
      params: (static) a subset of ("gamma", "nu"); deltas: (static) relative half-widths
        (gamma's, nu's); tol, iterations, max_iter: how the ends are solved (:func:`slopes`;
        ``iterations`` static, ``tol`` and ``max_iter`` may be traced; ``max_iter`` None:
        ``config.max_iter``).

    Returns:
      SVDD with alpha and offset whose tangents along ``params`` are the secant slopes (module
      docs) and ``gamma`` the traced gamma (f's explicit dependence on it is differentiated as
      usual). The values are unchanged; the solves run only when a tangent is taken.
    """
    dtype = svdd.alpha.dtype
    gamma, nu = jnp.asarray(gamma, dtype), jnp.asarray(nu, dtype)
    mask = jnp.ones(svdd.alpha.shape, bool) if svdd.mask is None else svdd.mask
    alpha, mu = _secant_identity(svdd.alpha, svdd.offset, gamma, nu, jax.lax.stop_gradient(svdd.points), mask,
                                 tol, config.max_iter if max_iter is None else max_iter,
                                 config, tuple(params), tuple(float(d) for d in deltas),
                                 None if iterations is None else int(iterations))
    return svdd._replace(alpha=alpha, offset=mu, gamma=gamma)


def with_nu_secant(svdd, nu, config, delta, tol):
    """:func:`with_secants` in nu only; the gamma-derivative stays that of ``svdd`` (implicit)."""
    return with_secants(svdd, svdd.gamma, nu, config, ("nu",), (delta, delta), tol)
