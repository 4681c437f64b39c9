"""The secant derivative of the SVDD solution in nu.

With C = 1 / (nu m) the dual solution is a continuous, piecewise linear function of C (a
parametric QP whose parameter enters only the box constraints). Each time a point moves between
zero, free and bounded the slope jumps, and on a few hundred to a few thousand samples such
breakpoints lie ~0.1 % of nu apart, so the exact one-sided derivative is the slope of one tiny
piece. The secant over nu (1 +- delta),

    d alpha / d nu := (alpha*(nu (1 + delta)) - alpha*(nu (1 - delta))) / (2 nu delta),

and likewise for the offset mu, is the slope of the trend over the pieces it spans: what a
change of nu by a few percent really does. It costs two warm-started solves at a tighter
tolerance (so that the solver error is small against the change).
"""
from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp

from .fit import solve_svdd
from .problem import caps as point_caps, kernel_ops, offset

__all__ = ["nu_slopes", "with_nu_secant"]


def nu_slopes(points, gamma, nu, mask, alpha0, config, delta, tol):
    """Secant slopes of (alpha, mu) in nu over [nu (1 - delta), min(nu (1 + delta), 1)].

    Args:
      points: (m, 3); gamma, nu: (); mask: (m,) bool or None; alpha0: (m,) warm start (the
      solution at nu); config: SolverConfig of the solves (its tol replaced by ``tol``);
      delta: relative half-width.

    Returns:
      (m,) and () slopes, without derivatives (non-finite slopes are 0).
    """
    sg = jax.lax.stop_gradient
    nu, points, gamma, alpha0 = sg(nu), sg(points), sg(gamma), sg(alpha0)
    lo = nu * (1.0 - delta)
    hi = jnp.minimum(nu * (1.0 + delta), 1.0)
    tight = dataclasses.replace(config, tol=tol)

    def solve(n):
        s = solve_svdd(points, gamma, n, mask, alpha0, tight)
        return s.alpha, s.offset

    (a_hi, mu_hi), (a_lo, mu_lo) = solve(hi), solve(lo)
    slope, mu_slope = (a_hi - a_lo) / (hi - lo), (mu_hi - mu_lo) / (hi - lo)
    return jnp.where(jnp.isfinite(slope), slope, 0.0), jnp.where(jnp.isfinite(mu_slope), mu_slope, 0.0)


def with_nu_secant(svdd, nu, config, delta, tol):
    """The same SVDD values whose derivative in ``nu`` is the secant slope (module docs).

    Args:
      svdd: the solution at ``stop_gradient(nu)`` (its alpha carries the implicit gamma-derivative);
      nu: () the traced nu; config: SolverConfig; delta, tol: secant half-width and solve tolerance.

    Returns:
      SVDD with alpha + (nu - sg(nu)) slope and offset + (nu - sg(nu)) mu_slope: the values are
      unchanged (the difference is exactly 0), the nu-tangent is the secant's. The offset gets its
      own secant: the derivative of the free-set average at nu misses points that change status
      within the interval.
    """
    sg = jax.lax.stop_gradient
    slope, mu_slope = sg(nu_slopes(svdd.points, svdd.gamma, nu, svdd.mask, svdd.alpha, config, delta, tol))
    dn = nu - sg(nu)
    caps = point_caps(sg(nu), svdd.mask)
    Ka = kernel_ops(svdd.points, svdd.gamma, config.kernel, config.block)[0](svdd.alpha)
    mu = offset(svdd.alpha, Ka, caps, svdd.mask) + dn * mu_slope
    return svdd._replace(alpha=svdd.alpha + dn * slope, offset=mu)
