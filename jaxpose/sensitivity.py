"""Derivatives of the OCSVM pose (center, scale) in gamma and nu.

gamma: the exact derivative of the core pipeline (``jaxpose.normalize``): the SVDD
solution is differentiated through its KKT system on the active set
(``svdd._implicit_alpha``), the region moments through the coarea boundary term
(``moments``), with the grid held fixed (``grid.domain`` snaps it to a lattice, so
it is piecewise constant in gamma). The computed pose is smooth in gamma between
switches (a point changing status in the SVDD solution, a cell entering the refined
band or the occupancy ramp; every ~1e-4 to 1e-3 relative change of gamma at m = 400),
and this derivative agrees with central finite differences of the production
function on intervals certified free of switches (``sweep`` in
tests/test_gradients.py: within 0.1 % on 5 shapes x 3 (gamma, nu) at m = 400).
Reverse mode (jax.grad, jacrev) in (gamma, nu) is computed by forward-mode columns
(``_hyper.hyper_jvp``): same values, ~1.6-1.9x a forward pass at m = 2000.

nu: what is delivered is a *secant* derivative, the slope of the SVDD solution over
the interval [nu (1 - delta), nu (1 + delta)] (``nu_delta``, default 1.5 %):

    d alpha / d nu  :=  (alpha*(nu (1 + delta)) - alpha*(nu (1 - delta))) / (2 nu delta),

and likewise for the offset mu (the secant of the two solutions' offsets), propagated
analytically through the region moments. Why: with
C = 1 / (nu m), the dual solution is a continuous, *piecewise linear* function of C
(a parametric QP whose parameter enters only the box constraints); every time a
point moves between "free", "at the cap" and "zero" the slope jumps, and at
m ~ 400-1000 points such breakpoints are ~0.1 % of nu apart (14 status changes
over +-2 % at m = 400). The exact one-sided derivative (which the core's KKT rule
gives, and which we verified against finite differences with steps of 1e-5) is
the slope of one tiny piece and misses the trend by 20-90 % at the scale a user
or an optimizer moves nu. The secant over a few percent is the expected slope
over the pieces it spans: what a 1-2 % change of nu really does, which is what
tuning needs. It costs two extra warm-started SVDD solves (at a tighter
tolerance ``nu_tol`` so that the solver error is small against the change).
The geometric part (how the region's centroid and mean distance respond to a
change of f) stays the analytic coarea term, which is accurate because f itself
changes smoothly over such an interval.

Everything is pure JAX: ``pose(points, gamma, nu, ...)`` can be jitted, vmapped
and differentiated with jax.grad / jacfwd / jacrev in both gamma and nu;
``pose_sensitivity`` returns the four derivatives as NumPy values.
"""
from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from . import _validate
from ._hyper import hyper_jvp
from .pose import DEFAULTS, Pose, _options, _pose_of, prescale
from .svdd import _caps, _fit, _make_matvec, _offset

__all__ = ["pose", "pose_sensitivity", "NU_DELTA"]

NU_DELTA = 0.015  # relative half-width of the nu interval of the secant derivative


def _nu_slope(nu, y, gamma, alpha0, cfg):
    """Secant slopes of (alpha, mu) in nu over [nu (1 - delta), nu (1 + delta)], no derivatives.
    -> (m,), ()"""
    delta, tol, max_iter, check_every, kernel, block, solver = cfg
    sg = jax.lax.stop_gradient
    nu, y, gamma, alpha0 = sg(nu), sg(y), sg(gamma), sg(alpha0)
    lo = nu * (1.0 - delta)
    hi = jnp.minimum(nu * (1.0 + delta), 1.0)

    def solve(n):  # warm-started from the solution at nu
        s = _fit(y, gamma, n, None, alpha0, tol=tol, max_iter=max_iter, check_every=check_every,
                 kernel=kernel, block=block, solver=solver)
        return s.alpha, s.offset

    (a_hi, mu_hi), (a_lo, mu_lo) = solve(hi), solve(lo)
    slope, mu_slope = (a_hi - a_lo) / (hi - lo), (mu_hi - mu_lo) / (hi - lo)
    return jnp.where(jnp.isfinite(slope), slope, 0.0), jnp.where(jnp.isfinite(mu_slope), mu_slope, 0.0)


def _pose(points, gamma, nu, resolution, refine, band, tol, max_iter, check_every, kernel, block,
          solver=None, nu_delta=NU_DELTA, nu_tol=None):
    """Like ``pose._normalize`` (no mask), with the secant nu-derivative. Same forward values.

    Derivatives in (gamma, nu) alone come from forward-mode columns, also under jax.grad /
    jacrev (``_hyper.hyper_jvp``: same derivatives, reverse mode at the cost of forward mode)."""
    impl = partial(_pose_impl, resolution=resolution, refine=refine, band=band, tol=tol, max_iter=max_iter,
                   check_every=check_every, kernel=kernel, block=block, solver=solver, nu_delta=nu_delta,
                   nu_tol=nu_tol)
    return hyper_jvp(impl, (1, 2))(points, gamma, nu)


def _pose_impl(points, gamma, nu, resolution, refine, band, tol, max_iter, check_every, kernel, block,
               solver=None, nu_delta=NU_DELTA, nu_tol=None):
    y, to_world, size = prescale(points)
    dtype = y.dtype
    gamma = jnp.asarray(gamma, dtype)
    nu = jnp.asarray(nu, dtype)
    s = _fit(y, gamma, jax.lax.stop_gradient(nu), None, None, tol=tol, max_iter=max_iter,
             check_every=check_every, kernel=kernel, block=block, solver=solver)
    if nu_tol is None:
        nu_tol = min(tol, 1e-6 if dtype == jnp.float64 else 1e-5)
    cfg = (float(nu_delta), float(nu_tol), int(max_iter), int(check_every), kernel, int(block), solver)
    # Straight-through: (nu - stop_gradient(nu)) is exactly 0, so the value is alpha; its
    # derivative in nu is the secant slope. (A custom_jvp did not survive grad-of-vmap.)
    # The two secant solves run on every call of ``pose``, differentiated or not.
    # The offset mu gets the secant of the two solves' offsets too: the derivative of the
    # free-set average at nu (what _offset alone would give) misses points that change status
    # within the interval (scale derivative 20 % off on a box at (25, 0.3), issue 3).
    slope, mu_slope = jax.lax.stop_gradient(_nu_slope(nu, y, gamma, s.alpha, cfg))
    dn = nu - jax.lax.stop_gradient(nu)
    mask = jnp.ones(s.alpha.shape, bool)
    caps = _caps(jax.lax.stop_gradient(nu), mask)
    offset = _offset(s.alpha, _make_matvec(y, gamma, kernel, block)(s.alpha), caps, mask) + dn * mu_slope
    s = s._replace(alpha=s.alpha + dn * slope, offset=offset)
    return _pose_of(s, to_world, size, resolution, refine, band, block, outside=True)  # the secant moves alpha = 0 points


_STATIC = tuple(DEFAULTS) + ("nu_delta", "nu_tol")
_pose_jit = jax.jit(_pose, static_argnames=_STATIC)


def pose(points, gamma=47.0, nu=0.5, *, nu_delta=NU_DELTA, nu_tol=None, **options) -> Pose:
    """``jaxpose.normalize`` with the secant nu-derivative (module docs). Same forward values.

    points : (m, 3); gamma, nu : () (traceable); options as ``normalize`` (static).
    nu_delta : relative half-width of the nu interval; nu_tol : solver tol of the two
    secant solves (default min(tol, 1e-6) in float64, min(tol, 1e-5) in float32).
    """
    unknown = set(options) - set(DEFAULTS)
    if unknown:
        raise _validate.InvalidInputError(f"unknown options {sorted(unknown)}; valid: {sorted(DEFAULTS)}")
    if not (0.0 < float(nu_delta) < 1.0):
        raise _validate.InvalidInputError(f"nu_delta must be in (0, 1), got {nu_delta!r}")
    opts = _options(**{**DEFAULTS, **options})
    if not _validate.is_traced(points):
        _validate.check_points(points)
    points = jnp.asarray(points)
    if not jnp.issubdtype(points.dtype, jnp.floating):
        points = points.astype(jnp.result_type(float))
    return _pose_jit(points, gamma, nu, nu_delta=float(nu_delta), nu_tol=None if nu_tol is None else float(nu_tol), **opts)


def pose_sensitivity(points, gamma=47.0, nu=0.5, **options) -> dict:
    """Derivatives of the pose in gamma and nu, as NumPy values.

    points : (m, 3) surface samples; gamma, nu : floats; options as ``pose``.
    Returns {"center", "scale", "dcenter_dgamma" (3,), "dcenter_dnu" (3,),
    "dscale_dgamma" (), "dscale_dnu" ()} (float NumPy arrays, in the units of points;
    d/dnu is the secant slope over nu (1 +- nu_delta), see module docs), plus
    "converged" and "valid" (bools).
    """
    _validate.check_gamma(gamma)
    _validate.check_nu(nu)
    points = jnp.asarray(_validate.check_points(points))
    dtype = points.dtype if jnp.issubdtype(points.dtype, jnp.floating) else jnp.result_type(float)
    theta = jnp.asarray([gamma, nu], dtype)

    def f(t):
        p = pose(points, t[0], t[1], **options)
        return jnp.concatenate([p.center, p.scale[None]]), p

    J, p = jax.jacfwd(f, has_aux=True)(theta)
    J = np.asarray(J)
    return {
        "center": np.asarray(p.center),
        "scale": np.asarray(p.scale),
        "dcenter_dgamma": J[:3, 0],
        "dcenter_dnu": J[:3, 1],
        "dscale_dgamma": J[3, 0],
        "dscale_dnu": J[3, 1],
        "converged": bool(p.converged),
        "valid": bool(p.valid),
    }
