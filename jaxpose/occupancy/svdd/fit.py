"""``fit_svdd``: validate, pick a solver, solve, and attach the implicit derivative."""
from __future__ import annotations

import dataclasses
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from ... import _validate
from ...config import SolverConfig
from ...host import check_cast
from .implicit import implicit_alpha
from .pg import solve_pg
from .polish import polish
from .problem import SVDD, caps as point_caps, kernel_ops, offset, parameters_in_range, upper_bound
from .smo import solve_smo

__all__ = ["fit_svdd", "solve_svdd", "pick_solver", "PG_MAX_M", "SMO_BUDGET"]

PG_MAX_M = 2500  # solver=None: "pg" up to this many points (on CPU), "auto" above
SMO_BUDGET = 10  # "auto": SMO pair updates per point before projected gradient takes over


def pick_solver(solver, m):
    """The solver that ``solver=None`` stands for at m points (static).

    On CPU, projected gradient up to ``PG_MAX_M`` points (its kernel products are fast while K
    stays in cache, and at equal tol it stops at a more even point than SMO, whose pair choices
    flip with rounding), "auto" above (SMO first: O(m) per update and no K needed). On other
    backends kernel products are cheap and thousands of sequential updates are not: "pg".
    """
    if solver is not None:
        return solver
    return "pg" if m <= PG_MAX_M or jax.default_backend() != "cpu" else "auto"


def fit_svdd(points, gamma, nu, *, mask=None, init_alpha=None, config: SolverConfig | None = None, throw=False,
             **options) -> SVDD:
    """Fit the SVDD dual (eq. 2) on points.

    Args:
      points: (m, 3) float32 or float64 (the result follows; float16, bfloat16 and integers are
        promoted as :func:`jaxpose.normalize` promotes them, :func:`jaxpose._validate.compute_dtype`).
      gamma: () > 0, the kernel parameter in 1 / units of ``points`` squared (as scikit-learn's).
      nu: () in [0, 1]; C = 1 / (nu m); nu = 0 is the hard-margin minimum enclosing ball.
      mask: optional (m,) bool; False rows are padding and get alpha = 0.
      init_alpha: optional (m,) warm start (projected onto the feasible set).
      config: a :class:`jaxpose.config.SolverConfig`; or its fields as keywords (``tol``,
        ``max_iter``, ``check_every``, ``kernel``, ``block``, ``solver``).
      throw: raise ConvergenceError if the iteration cap is hit. Concrete calls only: refused
        (InvalidInputError, while tracing) where the result is traced (traced inputs, or a call
        inside ``jit``): read ``SVDD.converged`` there.

    Returns:
      :class:`SVDD`, with ``converged``, ``iterations`` and ``kkt_violation`` as diagnostics. A
      traced ``gamma`` or ``nu`` cannot be refused: one out of range (gamma not finite and > 0, nu
      not in [0, 1]; :func:`jaxpose.occupancy.svdd.problem.parameters_in_range`) gives ``converged=False``, whatever the solver
      did (its other fields are no solution, NaN possible), as :func:`jaxpose.normalize` reports
      ``Status.BAD_PARAMETERS``; read ``converged`` (``jnp.where`` on it) there.

    Solvers: "pg" (accelerated projected gradient, one kernel product per step), "smo" (libsvm's
    pair updates), "auto" (SMO for at most min(SMO_BUDGET m, max_iter // 2) updates, then projected
    gradient from there); ``None`` picks by size (:func:`pick_solver`). Same problem, stopping
    rule (:func:`jaxpose.occupancy.svdd.kkt_violation` <= tol) and derivatives. Where at most
    ``polish.MAX_FREE`` points are free at the end, the solution is then polished: solved exactly
    on its active set, kept if that lowers the violation (:mod:`jaxpose.occupancy.svdd.polish`).

    Differentiation: jittable (options static), vmappable over same-size point sets, and
    differentiable in points, gamma and nu by the implicit KKT derivative
    (:mod:`jaxpose.occupancy.svdd.implicit`), in forward and reverse mode, without unrolling iterations.

    Raises:
      InvalidInputError: bad points, gamma, nu, mask, init_alpha or option; concrete points that
        their compute dtype cannot resolve (float64 points far from the origin, relative to their
        spread, with x64 off: :func:`jaxpose.host.check_cast`; the fit is in the frame given, so
        move them near the origin first).

    Example::

        svdd = jaxpose.fit_svdd(points, gamma=5.0, nu=0.3)
        bool(svdd.converged), svdd.alpha.sum()   # True, 1.0
    """
    if config is None:
        config = SolverConfig.create(**options)
    elif options:
        raise _validate.InvalidInputError(f"give either config or options, not both (got {sorted(options)})")
    elif not isinstance(config, SolverConfig):
        raise _validate.InvalidInputError(f"config must be a SolverConfig, got {type(config).__name__}")
    points = _validate.check_points(points)
    # NumPy's longdouble (JAX has no such dtype): as float64, as the points (compute_dtype's rule)
    gamma, nu, mask, init_alpha = (_validate.jax_value(v) for v in (gamma, nu, mask, init_alpha))
    _validate.check_gamma(gamma)
    _validate.check_nu(nu)
    throw = _validate.check_throw(throw, "SVDD.converged", points=points, gamma=gamma, nu=nu, mask=mask,
                                  init_alpha=init_alpha)
    m = points.shape[0] if hasattr(points, "shape") else len(points)
    if mask is not None:
        if tuple(getattr(mask, "shape", (len(mask),))) != (m,):
            raise _validate.InvalidInputError(f"mask must have shape ({m},), got {tuple(np.shape(mask))}")
        kind = np.dtype(mask.dtype if hasattr(mask, "dtype") else np.asarray(mask).dtype)  # (a tracer's too)
        if kind != bool and not _validate.is_real_dtype(kind):  # strings: NumPy's ValueError in the cast to bool
            raise _validate.InvalidInputError(f"mask must be (m,) bools, got dtype {kind}")
    if not _validate.is_traced(points) and (mask is None or not _validate.is_traced(mask)):
        chosen = points if mask is None else np.asarray(points)[np.asarray(mask, bool)]
        if mask is not None:
            _validate.check_points(chosen, name="points selected by mask")
        check_cast(chosen)
    if init_alpha is not None:
        if tuple(np.shape(init_alpha)) != (m,):
            raise _validate.InvalidInputError(f"init_alpha must have shape ({m},), got {tuple(np.shape(init_alpha))}")
        kind = np.dtype(init_alpha.dtype if hasattr(init_alpha, "dtype") else np.asarray(init_alpha).dtype)  # (a tracer's too)
        if not _validate.is_real_dtype(kind):  # strings: float()'s ValueError; complex: its real part
            raise _validate.InvalidInputError(f"init_alpha must be (m,) real numbers, got dtype {kind}")
        if not _validate.is_traced(init_alpha) and not np.all(np.isfinite(np.asarray(init_alpha, np.float64))):
            raise _validate.InvalidInputError("init_alpha has NaN or inf entries")
    points = jnp.asarray(points, _validate.compute_dtype(points))  # (NumPy's longdouble: JAX's TypeError in jnp.asarray)
    result = solve_svdd(points, gamma, nu, mask, init_alpha, config)
    if throw and not _validate.is_traced(result.converged) and not bool(result.converged):
        raise _validate.ConvergenceError(
            f"SVDD solver hit max_iter={config.max_iter} with relative KKT violation "
            f"{float(result.kkt_violation):.3g} > tol={config.tol}"
        )
    return result


def solve_svdd(points, gamma, nu, mask, init_alpha, config: SolverConfig, tol=None, max_iter=None) -> SVDD:
    """:func:`fit_svdd` without input checks, compiled per shape and per the solver's static options
    (``check_every``, ``kernel``, ``block``, and the solver ``solver=None`` stands for at this size,
    :func:`pick_solver`); the stopping numbers ``config.tol`` and ``config.max_iter`` are traced
    values, so configs that differ only in them share one program.

    Args as :func:`fit_svdd`; ``mask`` and ``init_alpha`` may be None; ``tol``, ``max_iter``:
    the stopping numbers in place of ``config.tol`` and ``config.max_iter`` (None: those; may be
    traced). Pure JAX; NumPy's longdouble arrays are taken as their float64 values
    (:func:`jaxpose._validate.jax_value`).

    Returns:
      :class:`SVDD`; ``converged`` is False where ``gamma`` or ``nu`` is out of range
      (:func:`jaxpose.occupancy.svdd.problem.parameters_in_range`; nothing is refused here, traced
      or not), as :func:`fit_svdd`'s and the OCSVM pose's (``Pose.converged``).
    """
    points, gamma, nu, mask, init_alpha, tol, max_iter = (  # (longdouble: as float64, jax_value)
        _validate.jax_value(v) for v in (points, gamma, nu, mask, init_alpha, tol, max_iter))
    static = dataclasses.replace(config, tol=SolverConfig.tol, max_iter=SolverConfig.max_iter,
                                 solver=pick_solver(config.solver, jnp.shape(points)[0]))
    return _solve_svdd(points, gamma, nu, mask, init_alpha, config.tol if tol is None else tol,
                       config.max_iter if max_iter is None else max_iter, static)


@partial(jax.jit, static_argnames=("config",))
def _solve_svdd(points, gamma, nu, mask, init_alpha, tol, max_iter, config: SolverConfig) -> SVDD:
    """:func:`solve_svdd` with the stopping rule's ``tol`` (() float) and ``max_iter`` (() int)
    traced, apart from ``config`` (whose own tol and max_iter are not read)."""
    dtype = points.dtype
    m = points.shape[0]
    solver = pick_solver(config.solver, m)
    in_range = parameters_in_range(gamma, nu)  # (as given: the rule of the concrete checks)
    gamma = jnp.asarray(gamma, dtype)
    nu = jnp.asarray(nu, dtype)
    mask = jnp.ones((m,), bool) if mask is None else jnp.asarray(mask, bool)
    caps = point_caps(nu, mask)
    cold = init_alpha is None
    if cold:
        init_alpha = jnp.where(mask, 1.0, 0.0).astype(dtype) / jnp.sum(mask)
    tol = jnp.asarray(tol, dtype)  # as a literal tol would be: compared in the points' precision
    sg = jax.lax.stop_gradient
    args = (sg(points), sg(gamma), sg(caps), mask, sg(jnp.asarray(init_alpha, dtype)))
    if solver == "pg":
        a, _, it, viol = solve_pg(*args, config, tol=tol, max_iter=max_iter)
    else:
        budget = max_iter if solver == "smo" else jnp.minimum(max_iter // 2, SMO_BUDGET * m)
        a, _, it, viol = solve_smo(*args, config, tol, budget, density_start_=cold)
        if solver == "auto":  # SMO's tail is slow where most support vectors are free: finish by PG
            def finish(a):
                r = solve_pg(args[0], args[1], args[2], mask, a, config, tol=tol, max_iter=max_iter - budget)
                return r[0], it + r[2], r[3]

            a, it, viol = jax.lax.cond(viol > tol, finish, lambda a: (a, it, viol), a)
    matvec = lambda v: kernel_ops(args[0], args[1], config.kernel, config.block)[0](v)  # built only if used
    a, viol = polish(args[0], args[1], args[2], mask, a, viol, matvec)
    a = implicit_alpha(a, points, gamma, caps, mask)
    # recomputed with the differentiable alpha, so that offset and objective carry derivatives
    Ka = kernel_ops(points, gamma, config.kernel, config.block)[0](a)
    return SVDD(
        points=points,
        alpha=a,
        gamma=gamma,
        cap=upper_bound(nu, jnp.sum(mask)),
        offset=offset(a, Ka, caps, mask),
        objective=jnp.vdot(a, Ka),
        iterations=it,
        kkt_violation=viol,
        converged=(viol <= tol) & in_range,
        mask=mask,
    )
