"""Support vector data description (the one-class SVM of the paper, eqs. 1-3).

Dual (eq. 2), with a Gaussian kernel so that k(x, x) = 1:

    min_a  a^T K a   s.t.  0 <= a_i <= C = 1 / (nu m),  sum a = 1,

solved by one of two solvers (``fit_svdd(solver=)``):

- "smo": sequential minimal optimization, libsvm's algorithm: move mass between the
  most violating pair (second-order selection), keeping G = K a up to date with two
  kernel columns, O(m) per update; started from alpha = C on the lowest-density points
  (the likely outliers). On sampled meshes it needs ~0.05-0.2 m updates.
- "pg": accelerated projected gradient (``jaxopt.ProjectedGradient``, FISTA) with a
  fixed step 1 / (2 lambda_max(K)) and an exact capped-simplex projection: one kernel
  product per step, the better tail where most support vectors are free and tol is tight.
- "auto": SMO up to ``SMO_BUDGET * m`` updates, then PG from there if needed.
- None (the default): "pg" up to ``PG_MAX_M`` points, "auto" above, on CPU; "pg" on other backends.

Why by size (issue 5): PG's cost is its kernel products, and on CPU they are fast while K stays in
cache (m = 2000: 16 MB, 0.12 ms a product; m = 4000: 64 MB, 2 ms). SMO's updates cost ~8 us at
m = 2000 (the stopping rule is checked every ``SMO_GROUP`` updates: checked after each, an update
cost 28 us). On FAUST samples (tol 1e-3, 2 CPU cores) PG fits 2000 points in 28-30 ms (44 ms before the
projection's Newton search, issue 5), SMO in 10-15 ms; at 4000, PG 0.37 s, SMO 52 ms; at 8000, 2.1 s
against 0.2 s (``jaxpose bench --sections solver --m 8000``). Up to ``PG_MAX_M`` PG is kept for its
solution: at the same tol SMO stops at a less even point of the tolerance ball (5 FAUST shapes of
2000 samples through ``normalize``: center up to 5e-4 of the scale off a tol-1e-6 solution, against
1.6e-4 for PG), its pair choices flip with rounding, so its stopping point jumps with tiny changes
of the input (500 points pre-centered in float32 or in float64: centers 4.6e-4 apart, about 1e-3 of
the scale; PG 1.8e-6), and on collinear points, where many dual solutions are nearly as good, it
can land far from the symmetric one (300 points on a segment of length 2.2: center 0.079 off, scale
8 % low; PG: 5e-12). It was as fast as PG or up to 20x faster on every shape tried at m = 2000, tol
1e-3 (FAUST, procedural human, chair, tree, guitar, box, sphere, the example shape; nu 0.05-0.5).
Above it, the end-to-end center error of SMO at tol 1e-3 is still 3e-5 (m = 4000) and 8e-5
(m = 8000) of the object's size, against 1e-5 and 3e-5 for PG, with fits in a ninth of PG's time at
m = 8000. On accelerators kernel products are cheap and SMO's thousands of sequential pair updates
are not (not measured: no device here), so None means "pg" there.

This is the only module that imports jaxopt.

Decision function (eq. 3): with the free support vectors F = {0 < a_i < C},
KKT gives 2 (K a)_i = mu on F, and

    f(x) = R^2 - ||Phi(x) - c||^2 = 2 k(x)^T a - mu,   R^2 = 1 - mu + a^T K a.

Mapping to scikit-learn / libsvm (``OneClassSVM(kernel="rbf", gamma, nu)``):
libsvm solves min 1/2 b^T K b, 0 <= b_i <= 1, sum b = nu m. So b = nu m a,
``dual_coef_[0]`` holds b at ``support_``, libsvm's rho = (K b)_i on free points
= nu m mu / 2, ``offset_`` = rho, and its ``decision_function(x)`` =
k(x)^T b - rho = (nu m / 2) f(x).

Stopping rule: libsvm-like maximal KKT violation on the gradient 2 K a,
``max_{a_j > 0} (Ka)_j - min_{a_i < C} (Ka)_i``, divided by a^T K a (the
a-weighted mean of Ka) so it is scale-free; f at the training points is then
within about 2 tol a^T K a ~ tol mu of its exact value.

Derivatives: the solution a*(points, gamma, nu) is differentiated implicitly
through the KKT system on the active set (Chapelle et al. 2002) in a
``custom_jvp``, so forward and reverse mode both work without unrolling the
iterations (jaxopt's own implicit diff is reverse-mode only).
"""
from __future__ import annotations

from functools import partial
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from . import _validate
from .kernels import gaussian_kernel, kernel_matvec_blocked, map_blocks, power_iteration
from .projection import projection_capped_simplex

__all__ = ["SVDD", "fit_svdd", "decision_function", "decision_value_and_grad", "upper_bound", "pick_solver"]

PG_MAX_M = 2500  # solver=None: "pg" up to this many points (on CPU), "auto" above (module docs)
_DENSE_LIMIT = 12_000  # m above which K is never stored (O(m * block) memory)
# "auto": SMO pair updates per point before PG takes over. Real meshes at the paper's (47, 0.5)
# need ~0.05-0.2 m; nearly uniform densities with many free support vectors (a sphere, small nu,
# tol <= 1e-4) need 10-20 m, where PG's kernel products are cheaper (measured, m = 1000-4000).
SMO_BUDGET = 10
SMO_GROUP = 8  # SMO updates between two checks of the stopping rule


class SVDD(NamedTuple):
    """A fitted SVDD. A pytree: jit/vmap friendly.

    points : (m, 3) training points (same units as given)
    alpha : (m,) dual solution, sum 1, 0 <= alpha <= cap
    gamma : () kernel parameter in 1 / units^2
    cap : () upper bound C = min(1, 1 / (nu m))
    offset : () mu, so that f(x) = 2 k(x)^T alpha - mu
    objective : () alpha^T K alpha
    iterations : () solver iterations
    kkt_violation : () relative KKT violation at the end (see module docs)
    converged : () bool, kkt_violation <= tol
    mask : (m,) bool, points that take part (padding in batches is False)
    """

    points: jax.Array
    alpha: jax.Array
    gamma: jax.Array
    cap: jax.Array
    offset: jax.Array
    objective: jax.Array
    iterations: jax.Array
    kkt_violation: jax.Array
    converged: jax.Array
    mask: jax.Array

    @property
    def radius2(self):
        """R^2 of the feature-space ball (eq. 1)."""
        return 1.0 - self.offset + self.objective

    @property
    def support(self):
        """(m,) bool, the support vectors (alpha > 0)."""
        return self.alpha > 0


def upper_bound(nu, m):
    """C = 1 / (nu m), capped at 1 (nu = 0: no upper bound), safe to differentiate."""
    nm = nu * m
    return jnp.where(nm > 1.0, 1.0 / jnp.where(nm > 1.0, nm, 1.0), 1.0)


def _caps(nu, mask):
    m_valid = jnp.sum(mask)
    return jnp.where(mask, upper_bound(nu, m_valid), 0.0)


def _kernel_ops(points, gamma, kernel, block):
    """(v -> K v, i -> K[i]) with K stored (dense) or computed in blocks / per column."""
    m = points.shape[0]
    dense = kernel == "dense" or (kernel == "auto" and m <= _DENSE_LIMIT)
    if dense:
        K = gaussian_kernel(points, points, gamma)
        return (lambda v: K @ v), (lambda i: K[i])
    return ((lambda v: kernel_matvec_blocked(points, v, gamma, block)),
            (lambda i: gaussian_kernel(points[i][None], points, gamma)[0]))


def _make_matvec(points, gamma, kernel, block):
    return _kernel_ops(points, gamma, kernel, block)[0]


def _kkt(alpha, Ka, caps, mask):
    """Relative maximal KKT violation (>= 0) and the objective a^T K a."""
    inf = jnp.asarray(jnp.inf, Ka.dtype)
    obj = jnp.vdot(alpha, Ka)
    up = jnp.max(jnp.where(mask & (alpha > 0), Ka, -inf))
    low = jnp.min(jnp.where(mask & (alpha < caps), Ka, inf))
    viol = jnp.maximum(up - low, 0.0)
    viol = jnp.where(jnp.isfinite(viol), viol, 0.0)
    return viol / jnp.maximum(obj, jnp.finfo(Ka.dtype).tiny), obj


def _offset(alpha, Ka, caps, mask):
    """mu = 2 (K a)_i averaged on free support vectors; libsvm's midpoint rule if none."""
    g = 2.0 * Ka
    free = mask & (alpha > 0) & (alpha < caps)
    n_free = jnp.sum(free)
    mean_free = jnp.sum(jnp.where(free, g, 0.0)) / jnp.maximum(n_free, 1)
    inf = jnp.asarray(jnp.inf, g.dtype)
    lb = jnp.max(jnp.where(mask & (alpha >= caps) & (alpha > 0), g, -inf))  # f <= 0 there
    ub = jnp.min(jnp.where(mask & (alpha <= 0), g, inf))  # f >= 0 there
    mid = jnp.where(jnp.isfinite(lb) & jnp.isfinite(ub), 0.5 * (lb + ub), jnp.where(jnp.isfinite(lb), lb, ub))
    return jnp.where(n_free > 0, mean_free, mid)


def _solve(points, gamma, caps, mask, init_alpha, tol, max_iter, check_every, kernel, block, restart=True):
    """Forward solve (no derivatives). Returns alpha, Ka, iterations, violation."""
    import jaxopt  # deferred: jaxopt warns on import

    dtype = points.dtype
    matvec = _make_matvec(points, gamma, kernel, block)
    m = points.shape[0]
    # Gershgorin (max row sum) is a guaranteed bound; the Rayleigh quotient a close lower one
    # (10 power steps from the ones vector land within ~1.5 % of lambda_max on kernel matrices).
    lam = power_iteration(matvec, m, dtype, iterations=10)
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
    viol0, _ = _kkt(a0, matvec(a0), caps, mask)

    def cond(carry):
        _, _, it, viol = carry
        return (viol > tol) & (it < max_iter)

    def body(carry):
        a, state, it, _ = carry

        def inner(_, c):
            a, state = c
            nxt = pg.update(a, state, caps)
            if restart:  # O'Donoghue & Candes gradient restart: drop momentum when it points uphill
                up = jnp.vdot(state.velocity - nxt.params, nxt.params - a) > 0
                st = nxt.state
                st = st._replace(t=jnp.where(up, 1.0, st.t), velocity=jnp.where(up, nxt.params, st.velocity))
                return nxt.params, st
            return nxt.params, nxt.state

        a, state = jax.lax.fori_loop(0, check_every, inner, (a, state))
        viol, _ = _kkt(a, matvec(a), caps, mask)
        return a, state, it + check_every, viol

    a, _, it, viol = jax.lax.while_loop(cond, body, (a0, state0, jnp.asarray(0), viol0))
    return a, matvec(a), it, viol


def _density_start(matvec, caps, mask):
    """A feasible start for SMO: alpha = C on the lowest-density points (kernel density K 1),
    which are the likely bounded support vectors (outside the ball), until the mass is 1."""
    dtype = caps.dtype
    dens = jnp.where(mask, matvec(mask.astype(dtype)), jnp.inf)
    order = jnp.argsort(dens)
    c = jnp.max(caps)
    before = jnp.arange(caps.shape[0], dtype=dtype) * c  # mass given to the lower-density points
    a = jnp.zeros_like(caps).at[order].set(jnp.clip(1.0 - before, 0.0, c))
    return jnp.where(mask, a, 0.0)


def _first_index(x, value):
    """The first i with x[i] == value (as argmin / argmax of x break ties). Two vectorized
    reductions: XLA's CPU argmin / argmax (a variadic reduce) is a scalar loop."""
    return jnp.min(jnp.where(x == value, jnp.arange(x.shape[0]), x.shape[0] - 1))


def _solve_smo(points, gamma, caps, mask, init_alpha, tol, max_iter, kernel, block, density_start):
    """Forward solve by SMO (libsvm's pair updates with second-order working-set selection,
    Fan, Chen & Lin 2005) on the gradient G = K a, kept up to date with two kernel columns
    per step. Returns alpha, Ka, iterations (pair updates), violation (from an exact K a).

    The stopping rule is checked every ``SMO_GROUP`` updates (issue 5: a loop iteration's fixed cost
    on CPU was most of an update's; SMO updates never raise the objective, so the few after
    convergence only help)."""
    dtype = points.dtype
    inf = jnp.asarray(jnp.inf, dtype)
    matvec, column = _kernel_ops(points, gamma, kernel, block)
    if density_start:
        a0 = _density_start(matvec, caps, mask)
    else:
        a0 = projection_capped_simplex(init_alpha, caps)

    violation = lambda a, G: _kkt(a, G, caps, mask)[0]

    def step(carry):
        a, G, it = carry
        low = jnp.where(mask & (a < caps), G, inf)
        g_i = jnp.min(low)
        i = _first_index(low, g_i)  # most violating pair: i gains mass
        ki = column(i)
        d = G - g_i
        quad = jnp.maximum(2.0 - 2.0 * ki, jnp.finfo(dtype).eps)  # k(x,x) = 1
        score = jnp.where(mask & (a > 0) & (d > 0), d * d / quad, -inf)
        best = jnp.max(score)
        j = _first_index(score, best)  # ... from j, the largest decrease of the objective
        delta = jnp.minimum(jnp.minimum(d[j] / quad[j], caps[i] - a[i]), a[j])
        live = jnp.isfinite(best) & (it < max_iter)
        delta = jnp.where(live, delta, 0.0)
        a = a.at[i].add(delta).at[j].add(-delta)
        G = G + delta * (ki - column(j))
        return a, G, it + live.astype(it.dtype)

    def steps(carry):
        a, G, it, _ = carry
        for _ in range(SMO_GROUP):
            a, G, it = step((a, G, it))
        return a, G, it, violation(a, G)

    def running(carry):
        return (carry[3] > tol) & (carry[2] < max_iter)

    def sweep(carry):  # SMO on the running G, then G recomputed exactly (float32 drift)
        a, _, it, _ = jax.lax.while_loop(running, steps, carry)
        G = matvec(a)
        return a, G, it, violation(a, G)

    G0 = matvec(a0)
    a, G, it, viol = jax.lax.while_loop(running, sweep, (a0, G0, jnp.asarray(0), violation(a0, G0)))
    return a, G, it, viol


@jax.custom_jvp
def _implicit_alpha(alpha, points, gamma, caps, mask):
    """Identity on the solution alpha; its JVP is the KKT implicit derivative."""
    return alpha


@partial(_implicit_alpha.defjvp, symbolic_zeros=True)
def _implicit_alpha_jvp(primals, tangents):
    from jax.custom_derivatives import SymbolicZero  # local: tangents arrive with symbolic zeros

    alpha, points, gamma, caps, mask = primals
    _, dpoints, dgamma, dcaps, _ = tangents
    alpha = jax.lax.stop_gradient(alpha)
    dtype = alpha.dtype
    m = alpha.shape[0]
    zero = lambda t: isinstance(t, SymbolicZero)
    # K and dK a, linear in (dpoints, dgamma); the points' tangent only when they are perturbed
    # (issue 3: a zero (m, 3) tangent cost a second (m, m) kernel tangent per column).
    if zero(dpoints) and zero(dgamma):
        K, dKa = gaussian_kernel(points, points, gamma), jnp.zeros_like(alpha)
    elif zero(dpoints):
        K, dK = jax.jvp(lambda g: gaussian_kernel(points, points, g), (gamma,), (dgamma,))
        dKa = dK @ alpha
    else:
        K, dK = jax.jvp(lambda p, g: gaussian_kernel(p, p, g), (points, gamma),
                         (dpoints, jnp.zeros_like(gamma) if zero(dgamma) else dgamma))
        dKa = dK @ alpha
    K = jax.lax.stop_gradient(K)
    free = mask & (alpha > 0) & (alpha < caps)
    upper = mask & (alpha >= caps) & (alpha > 0) & ~free
    fm = free.astype(dtype)
    da_b = jnp.zeros_like(alpha) if zero(dcaps) else upper.astype(dtype) * dcaps  # bounded points follow the cap
    # Tikhonov term: K_FF is numerically singular (cond ~1e13); directions it damps barely move f.
    ridge = 10.0 * jnp.finfo(dtype).eps * jnp.max(jnp.sum(K, axis=1))
    A = 2.0 * K * fm[:, None] * fm[None, :] + jnp.diag(1.0 - fm) + ridge * jnp.diag(fm)
    M = jnp.zeros((m + 1, m + 1), dtype)
    M = M.at[:m, :m].set(A).at[:m, m].set(fm).at[m, :m].set(fm)
    M = jnp.where(jnp.any(free), M, jnp.eye(m + 1, dtype=dtype))  # no free point: M was singular (NaN)
    rhs_top = -fm * (2.0 * dKa + 2.0 * (K @ da_b))
    rhs = jnp.concatenate([rhs_top, -jnp.sum(da_b)[None]])
    # (Solving at the size of the free set, by lax.switch over a few static sizes, was up to 10x
    # cheaper, but wedged XLA's CPU thread pool under vmap, where a switch runs every branch.)
    da_f = jnp.linalg.solve(M, rhs)[:m]
    dalpha = fm * da_f + da_b
    return alpha, dalpha


def pick_solver(solver, m):
    """The solver that ``solver=None`` stands for at m points (static; module docs)."""
    if solver is not None:
        return solver
    return "pg" if m <= PG_MAX_M or jax.default_backend() != "cpu" else "auto"


def fit_svdd(
    points,
    gamma,
    nu,
    *,
    mask=None,
    init_alpha=None,
    tol=1e-3,
    max_iter=20_000,
    check_every=10,
    kernel="auto",
    block=1024,
    solver=None,
    throw=False,
) -> SVDD:
    """Fit the SVDD dual (eq. 2) on points.

    points : (m, 3) float (float32 or float64; the result follows)
    gamma : () > 0, kernel parameter in 1 / units of points squared (as scikit-learn)
    nu : () in [0, 1]; C = 1 / (nu m); nu = 0 is the hard-margin ball
    mask : (m,) bool, optional: False rows are padding and get alpha = 0
    init_alpha : (m,) optional warm start (projected onto the feasible set)
    tol : relative KKT violation to stop at (see module docs)
    kernel : "auto" | "dense" | "blocked" (blocked keeps memory O(m * block))
    solver : None | "auto" | "smo" | "pg". None: "pg" up to PG_MAX_M = 2500 points, "auto" above,
        on CPU, "pg" on other backends (module docs). "smo": pair updates (libsvm's algorithm, O(m) per update,
        no kernel matrix needed); "pg": jaxopt's accelerated projected gradient (FISTA, one
        kernel product per step); "auto": SMO for at most min(SMO_BUDGET * m, max_iter // 2)
        updates, then, if not converged, PG from there for the rest of max_iter. Same problem,
        stopping rule and derivatives. ``iterations`` counts pair updates plus gradient steps.
    throw : raise ConvergenceError if the iteration cap is hit (concrete calls only)

    Jittable (with static options), vmappable over same-size point sets,
    differentiable in points, gamma and nu by implicit differentiation.
    """
    points = _validate.check_points(points)
    _validate.check_gamma(gamma)
    _validate.check_nu(nu)
    _validate.check_choices(kernel=kernel, solver=solver)
    # issue 6: check_every = 0 looped forever; mask / init_alpha shapes gave JAX-internal errors
    _validate.check_options(tol, max_iter, check_every, block)
    m = points.shape[0] if hasattr(points, "shape") else len(points)
    if mask is not None:
        if tuple(getattr(mask, "shape", (len(mask),))) != (m,):
            raise _validate.InvalidInputError(f"mask must have shape ({m},), got {tuple(jnp.shape(mask))}")
        if not _validate.is_traced(mask) and not _validate.is_traced(points):
            _validate.check_points(np.asarray(points)[np.asarray(mask, bool)], name="points selected by mask")
    if init_alpha is not None:
        if tuple(jnp.shape(init_alpha)) != (m,):
            raise _validate.InvalidInputError(f"init_alpha must have shape ({m},), got {tuple(jnp.shape(init_alpha))}")
        if not _validate.is_traced(init_alpha) and not np.all(np.isfinite(np.asarray(init_alpha, np.float64))):
            raise _validate.InvalidInputError("init_alpha has NaN or inf entries")
    points = jnp.asarray(points)
    if not jnp.issubdtype(points.dtype, jnp.floating):
        points = points.astype(jnp.result_type(float))
    result = _fit(
        points, gamma, nu, mask, init_alpha,
        tol=float(tol), max_iter=int(max_iter), check_every=int(check_every), kernel=kernel, block=int(block),
        solver=solver,
    )
    if throw and not _validate.is_traced(result.converged) and not bool(result.converged):
        raise _validate.ConvergenceError(
            f"SVDD solver hit max_iter={max_iter} with relative KKT violation {float(result.kkt_violation):.3g} > tol={tol}"
        )
    return result


@partial(jax.jit, static_argnames=("tol", "max_iter", "check_every", "kernel", "block", "solver"))
def _fit(points, gamma, nu, mask, init_alpha, tol, max_iter, check_every, kernel, block, solver=None):
    dtype = points.dtype
    m = points.shape[0]
    solver = pick_solver(solver, m)
    gamma = jnp.asarray(gamma, dtype)
    nu = jnp.asarray(nu, dtype)
    mask = jnp.ones((m,), bool) if mask is None else jnp.asarray(mask, bool)
    caps = _caps(nu, mask)
    cold = init_alpha is None
    if cold:
        init_alpha = jnp.where(mask, 1.0, 0.0).astype(dtype) / jnp.sum(mask)
    sg = jax.lax.stop_gradient
    args = (sg(points), sg(gamma), sg(caps), mask, sg(jnp.asarray(init_alpha, dtype)))
    if solver == "pg":
        a, _, it, viol = _solve(*args, tol, max_iter, check_every, kernel, block)
    else:
        budget = max_iter if solver == "smo" else min(max_iter // 2, SMO_BUDGET * m)
        a, _, it, viol = _solve_smo(*args, tol, budget, kernel, block, density_start=cold)
        if solver == "auto":  # SMO's tail is slow where most support vectors are free: finish by PG
            def finish(a):
                r = _solve(args[0], args[1], args[2], mask, a, tol, max_iter - budget, check_every, kernel, block)
                return r[0], it + r[2], r[3]

            a, it, viol = jax.lax.cond(viol > tol, finish, lambda a: (a, it, viol), a)
    a = _implicit_alpha(a, points, gamma, caps, mask)
    # Recomputed with the differentiable alpha so offset and objective carry derivatives.
    Ka = _make_matvec(points, gamma, kernel, block)(a)
    offset = _offset(a, Ka, caps, mask)
    return SVDD(
        points=points,
        alpha=a,
        gamma=gamma,
        cap=upper_bound(nu, jnp.sum(mask)),
        offset=offset,
        objective=jnp.vdot(a, Ka),
        iterations=it,
        kkt_violation=viol,
        converged=viol <= tol,
        mask=mask,
    )


def decision_value_and_grad(svdd: SVDD, x, block=4096):
    """f(x) (eq. 3) and its spatial gradient, in blocks of query points.

    x : (n, 3) -> f : (n,), grad : (n, 3). Memory O(block * m).
    """
    p, a, g = svdd.points, svdd.alpha, svdd.gamma

    def one_block(xb):
        d = xb[:, None, :] - p[None, :, :]
        w = a * jnp.exp(-g * jnp.sum(d * d, axis=-1))
        f = 2.0 * jnp.sum(w, axis=1) - svdd.offset
        grad = -4.0 * g * jnp.einsum("nm,nmk->nk", w, d)
        return f, grad

    return map_blocks(one_block, x, block)


def decision_function(svdd: SVDD, x, block=4096):
    """f(x) = 2 k(x)^T alpha - mu (eq. 3), positive inside. x : (n, 3) -> (n,)."""
    if not isinstance(svdd, SVDD):  # issue 6: clear errors for a wrong model or NaN / non-numeric x
        raise _validate.InvalidInputError(f"svdd must be an SVDD from fit_svdd, got {type(svdd).__name__}")
    _validate.check_array(x, name="x")
    x = jnp.asarray(x, svdd.points.dtype)
    if x.shape[0] == 0:
        return jnp.zeros((0,), x.dtype)
    p, a, g = svdd.points, svdd.alpha, svdd.gamma
    return map_blocks(lambda xb: 2.0 * (gaussian_kernel(xb, p, g) @ a) - svdd.offset, x, block)
