"""Derivatives of the pose in gamma and nu.

Two derivatives are checked, each against what it claims to be:

* ``derivative="exact"`` (the implicit KKT derivative of the computed solution) against central
  finite differences of the production function itself (``pose.pose_pipeline``) at the largest
  step in (1e-3, 1e-4, 1e-5, 1e-6) whose interval is certified free of switches (``_state``:
  same solver iterations, SVDD status, cells, refinement and occupancy class at both ends): the
  function is piecewise smooth, with a switch every ~1e-4 to 1e-3 relative change of gamma at
  m = 400, and a difference across one is a secant over two pieces, not a derivative;
* the default ``derivative="trend"`` against central finite differences of ``jaxpose.normalize``
  at steps of 1 % of gamma and of nu, the trend it is meant to follow.

The acceptance sweep (FAUST and synthetic shapes, three (gamma, nu), steps of 1 and 2 %, and the
cost against a forward call) is ``benchmarks/gradients.py``; its table is in docs/performance.md.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import trimesh

import jaxpose
from jaxpose import moments
from jaxpose.mesh import example_shape, sample_surface
from jaxpose.pose.sensitivity import pose, pose_sensitivity

OPTS = dict(resolution=16, refine=2, band=2048, tol=1e-7, max_iter=200_000)


pytestmark = pytest.mark.usefixtures("x64_module")  # every test in float64


def _vec(p):
    return np.concatenate([np.asarray(p.center), [float(p.scale)]])


def _fn(points, **opts):
    """(gamma, nu) -> [center, scale] of the production pipeline (``pose.pose_pipeline``), exact derivative."""
    from jaxpose.config import PoseConfig
    from jaxpose.pose.pose import pose_pipeline

    config = PoseConfig.create(**{"derivative": "exact", **opts})

    def f(g, n):
        p = pose_pipeline(points, None, jnp.asarray(g, points.dtype), jnp.asarray(n, points.dtype), config)
        return jnp.concatenate([p.center, p.scale[None]])

    return f


def _rel(a, b):
    """Relative error of the center (vector norm) and the scale, against FD b."""
    ec = np.linalg.norm(a[:3] - b[:3]) / max(np.linalg.norm(b[:3]), 1e-300)
    es = abs(a[3] - b[3]) / max(abs(b[3]), 1e-300)
    return ec, es


def _ok(a, b, rel, atol=1e-6):
    ec, es = _rel(a, b)
    return (ec <= rel or np.linalg.norm(a[:3] - b[:3]) <= atol) and (es <= rel or abs(a[3] - b[3]) <= atol)


def _state(points, **opts):
    """(gamma, nu) -> the discrete state the production function branches on: solver
    iterations, SVDD status of each point (0 zero, 1 free, 2 at the cap), the cells (centers
    and constant factors: box and refinement) and each cell's occupancy class (0, ramp, 1).
    Traceable: ``gamma_check`` compiles it with the JVP (one program)."""
    from jaxpose.config import PoseConfig
    from jaxpose.pose.frame import prescale
    from jaxpose.occupancy.svdd import solve_svdd

    config = PoseConfig.create(**{"derivative": "exact", **opts})

    def state(g, n):
        y, _, _ = prescale(points)
        s = solve_svdd(y, g, n, None, None, config.svdd)
        x, occ, fac, _, _, _ = moments.discretize(s, config.grid)
        status = (s.alpha > 0).astype(int) + (s.alpha >= s.cap).astype(int)
        return dict(iterations=s.iterations, status=status, x=x, fac=fac,
                    ramp=(occ > 0).astype(int) + (occ >= 1).astype(int))

    return state


def _canonical(st):
    """The cells of a state in a fixed order: top_k lists the refined cells by score, and scores
    reorder continuously; the moments are sums over cells and do not depend on the order."""
    o = np.lexsort((st["fac"], st["x"][:, 2], st["x"][:, 1], st["x"][:, 0]))
    return st["x"][o], st["fac"][o], st["ramp"][o]


def _switches(a, b):
    """Counts of what differs between two states of ``_state``; all 0: no switch between
    (cells: cells not in both; ramp: cells whose occupancy class differs; -1 if the cells differ)."""
    (xa, fa, ra), (xb, fb, rb) = _canonical(a), _canonical(b)
    same = np.array_equal(xa, xb) and np.array_equal(fa, fb)
    cells = 0 if same else len({tuple(r) for r in np.c_[xa, fa]} ^ {tuple(r) for r in np.c_[xb, fb]})
    return dict(status=int(np.sum(a["status"] != b["status"])), cells=cells,
                ramp=int(np.sum(ra != rb)) if same else -1,
                iterations=int(b["iterations"]) - int(a["iterations"]))


STEPS = (1e-3, 1e-4, 1e-5, 1e-6)


def gamma_check(points, g, n, opts=None, steps=STEPS):
    """jacfwd in gamma of the production function against central FD at the largest step of
    ``steps`` certified free of switches. -> dict(J, fd, step, rel, ok, per_step=[(e, fd, rel, switches)])."""
    opts = OPTS if opts is None else opts
    f, state = _fn(points, **opts), _state(points, **opts)
    # one compiled program gives all three: the JVP in gamma (the derivative), as its primal output
    # the production function's value (the FD ends), and the discrete state at that gamma (the
    # certificate): separate programs would compute the same solve again (and compile for as long)
    jvp = jax.jit(lambda g_, n_: (*jax.jvp(lambda x: f(x, n_), (g_,), (jnp.ones_like(g_),)), state(g_, n_)))
    at = lambda g_: jax.tree_util.tree_map(np.asarray, jvp(jnp.asarray(g_, points.dtype), jnp.asarray(n, points.dtype)))
    J = at(g)[1]
    per_step, chosen = [], None
    for e in steps:
        lo, hi = g * (1 - e), g * (1 + e)
        (f_lo, _, st_lo), (f_hi, _, st_hi) = at(lo), at(hi)
        fd = (f_hi - f_lo) / (hi - lo)
        sw = _switches(st_lo, st_hi)
        per_step.append((e, fd, _rel(J, fd), sw))
        if chosen is None and not any(sw.values()):
            chosen = per_step[-1]
    clean = chosen is not None
    if chosen is None:  # no certified step: report the smallest
        chosen = per_step[-1]
    e, fd, rel, _ = chosen
    return dict(J=J, fd=fd, step=e, rel=rel, ok=_ok(J, fd, 0.05), certified=clean, per_step=per_step)


@pytest.fixture(scope="module")
def shape_points(x64_module):
    return jnp.asarray(sample_surface(example_shape(), 400, seed=1))


@pytest.fixture(scope="module")
def small_points(x64_module):
    return jnp.asarray(sample_surface(example_shape(), 200, seed=2))


SMALL = dict(resolution=8, refine=2, band=256, tol=1e-4)


def test_gamma_derivative_matches_fd(shape_points):
    """jacfwd of the production function vs its central FD, on an interval certified free of
    switches (module docs); the grid box is the same at both ends."""
    r = gamma_check(shape_points, 47.0, 0.5, steps=(1e-5,))
    assert r["certified"], r["per_step"]
    assert r["ok"], (r["J"], r["fd"], r["rel"])


def test_forward_reverse_jit_vmap_agree(small_points):
    shape_points, opts = small_points, SMALL

    def cs(t):
        p = pose(shape_points, t[0], t[1], **opts)
        return jnp.concatenate([p.center, p.scale[None]])

    t = jnp.asarray([47.0, 0.5])
    Jf, Jr = jax.jacfwd(cs)(t), jax.jacrev(cs)(t)  # op by op
    # compiled (both in one program: compiled together they share their primal work and compile in
    # about 3/4 of the time of one program each)
    Jjf, Jjr = jax.jit(lambda t: (jax.jacfwd(cs)(t), jax.jacrev(cs)(t)))(t)
    np.testing.assert_allclose(Jf, Jr, rtol=1e-6, atol=1e-10)  # forward = reverse
    np.testing.assert_allclose(Jjf, Jjr, rtol=1e-6, atol=1e-10)
    assert np.all(np.isfinite(Jf)) and np.any(Jf[:, 1] != 0)
    # Op by op against compiled: the secant ends (SMO, below) see the kernel products rounded
    # differently and may stop at other points within the tolerance, so each column agrees to about
    # tol / (2 delta) = 5e-4 of its largest entry (identical with some XLA versions; measured up to
    # 7e-4 with others): the bound of the vmap comparison below.
    for k in range(2):
        assert np.abs(Jf[:, k] - Jjr[:, k]).max() <= 1e-3 * np.abs(Jjr[:, k]).max(), (k, Jf, Jjr)
    # vmap over point sets (forward mode inside; reverse mode of the core under vmap is
    # covered by jax.grad in test_core_normalize_differentiable_in_gamma and tuning's jacfwd(vmap))
    # On CPU the secant ends are solved by SMO, whose pair choices follow the rounding of the
    # kernel products, and batched products round differently: under vmap the ends stop at
    # other points within the tolerance (1e-5), and the slopes, differences of ends 2 % apart,
    # agree to about tol / (2 delta) = 5e-4 (measured 2.6e-4).
    P = jnp.stack([shape_points, shape_points + 1.0])
    gs = jax.vmap(lambda p: jax.jacfwd(lambda t: pose(p, t[0], t[1], **opts).scale)(t))(P)
    # the same bound as the compiled comparison above: 1e-3 of the row's largest entry
    bound = 1e-3 * np.abs(Jf[3]).max()
    np.testing.assert_allclose(gs[0], Jf[3], rtol=0, atol=bound)
    np.testing.assert_allclose(gs[1], Jf[3], rtol=0, atol=bound)  # translation invariance


def test_core_normalize_differentiable_in_gamma(small_points):
    """jax.grad and jax.jacfwd agree with derivative="exact" too (the trend: the test above)."""
    shape_points, opts = small_points, {**SMALL, "derivative": "exact"}
    f = lambda g: jaxpose.normalize(shape_points, method="ocsvm", gamma=g, nu=0.5, **opts).scale
    a = jax.grad(f)(47.0)
    # the gamma column of the (gamma, nu) Jacobian: the program of pose_sensitivity's exact jacfwd
    # (test_derivatives_do_not_depend_on_the_solver) instead of a one-column one of its own
    b = jax.jacfwd(lambda t: jaxpose.normalize(shape_points, method="ocsvm", gamma=t[0], nu=t[1], **opts).scale)(
        jnp.asarray([47.0, 0.5]))[0]
    np.testing.assert_allclose(a, b, rtol=1e-6)
    # pose() has the same forward values and the same gamma-derivative as normalize()
    p, q = pose(shape_points, 47.0, 0.5, **opts), jaxpose.normalize(shape_points, method="ocsvm", gamma=47.0, nu=0.5, **opts)
    # (normalize pre-centers concrete points in float64 NumPy: equal up to rounding)
    np.testing.assert_allclose(np.asarray(p.center), np.asarray(q.center), rtol=1e-12, atol=1e-12)


def test_reverse_mode_in_points_still_works(small_points):
    """Gradients in the points bypass the forward-column rule (_hyper.hyper_jvp): plain reverse
    mode, equal to the JVP along a random direction; and jointly with gamma (exact mode: the
    points' derivative is the implicit one in every mode). Identical points (a flagged
    DEGENERATE_INPUT pose) have finite derivatives (the reference size's sqrt at 0 made them NaN,
    which a masked loss over a batch would carry into every gradient)."""
    opts = {**SMALL, "derivative": "exact"}
    f = lambda p, g: jaxpose.normalize(p, method="ocsvm", gamma=g, nu=0.5, **opts).scale
    v = jnp.asarray(np.random.default_rng(0).normal(size=small_points.shape))
    # reverse and forward mode in the points in one compiled program (the points traced, as under
    # grad alone): compiled together they share their primal work
    both = jax.jit(lambda p, g, v: (jax.grad(f, argnums=(0, 1))(p, g), jax.jvp(lambda q: f(q, g), (p,), (v,))))
    (gp, gg), (_, jv) = both(small_points, 47.0, v)
    np.testing.assert_allclose(float(jnp.vdot(gp, v)), float(jv), rtol=1e-8)
    np.testing.assert_allclose(float(gg), float(jax.grad(f, argnums=1)(small_points, 47.0)), rtol=1e-8)
    same = jnp.broadcast_to(small_points[0], small_points.shape)  # the same program
    (gp, gg), (_, jv) = both(same, 47.0, v)
    assert np.all(np.isfinite(gp)) and np.isfinite(float(gg)) and np.isfinite(float(jv))


def _fd(points, g, n, param, eps, **opts):
    """Central difference quotient of normalize's [center, scale] at a relative step eps."""
    if param == "gamma":
        hi, lo, h = (g * (1 + eps), n), (g * (1 - eps), n), g * eps
    else:
        hi, lo, h = (g, n * (1 + eps)), (g, n * (1 - eps)), n * eps
    at = lambda g_, n_: _vec(jaxpose.normalize(points, method="ocsvm", gamma=g_, nu=n_, **opts))
    return (at(*hi) - at(*lo)) / (2 * h)


def test_default_derivative_follows_fd_at_one_percent(shape_points):
    """The default jacfwd (derivative="trend") of normalize's center and scale agrees with central
    differences of normalize at steps of 1 % of gamma and of nu, within 20 % (or 1e-6), at
    (20, 0.3). On the default grid: at 16^3-32^3 the grid's own switches (cells entering the band
    or the occupancy ramp) move the center by as much as 1 % of gamma does, and the derivative
    holds the grid fixed (measured here: 28 % at 32^3, 5 % at 64^3)."""
    g, n = 20.0, 0.3
    opts = dict(tol=1e-7, max_iter=200_000)
    J = np.asarray(jax.jacfwd(lambda t: jnp.asarray(_vec_j(jaxpose.normalize(shape_points, method="ocsvm", gamma=t[0], nu=t[1], **opts))))(
        jnp.asarray([g, n])))
    for k, param in enumerate(("gamma", "nu")):
        fd = _fd(shape_points, g, n, param, 0.01, **opts)
        assert _ok(J[:, k], fd, 0.20), (param, J[:, k], fd, _rel(J[:, k], fd))


def _vec_j(p):
    return jnp.concatenate([p.center, p.scale[None]])


def test_trend_where_points_enter_the_support():
    """The secant slope is nonzero at points with alpha = 0 that enter the support within the
    interval; without their terms in the boundary integral the scale's nu-derivative came out
    -0.188 against FD +0.043 (box, (25, 0.3); -0.156 against +0.025 on the 16^3 grid). The offset's
    slope is the secant of the offsets."""
    pts = jnp.asarray(sample_surface(trimesh.creation.box([1.0, 0.6, 0.3]), 400, seed=1))
    g, n = 25.0, 0.3
    # the default grid (incidental; tol and max_iter are traced): the programs of
    # test_default_derivative_follows_fd_at_one_percent (its jacfwd, and normalize's values)
    opts = dict(tol=1e-7, max_iter=200_000)
    S = pose_sensitivity(pts, g, n, **opts)
    J = np.concatenate([S["dcenter_dnu"], [S["dscale_dnu"]]])
    fd = _fd(pts, g, n, "nu", 0.01, **opts)
    assert _ok(J, fd, 0.10), (J, fd, _rel(J, fd))


def test_derivative_modes_share_values_and_tolerance_mode_agrees(small_points):
    """Every derivative mode computes the same pose (the secant solves run only under
    differentiation); the lock-step secant and the secant of two solutions solved to a tight
    tolerance (secant_iterations=None) agree."""
    opts = {**SMALL, "tol": 1e-6}
    vals = {mode: _vec(jaxpose.normalize(small_points, method="ocsvm", gamma=30.0, nu=0.4, derivative=mode, **opts))
            for mode in ("trend", "exact", "secant")}
    np.testing.assert_array_equal(vals["trend"], vals["exact"])
    np.testing.assert_array_equal(vals["trend"], vals["secant"])
    f = lambda it: np.asarray(jax.jacfwd(lambda t: _vec_j(jaxpose.normalize(
        small_points, method="ocsvm", gamma=t[0], nu=t[1], secant_iterations=it, nu_tol=1e-9, **opts)))(jnp.asarray([30.0, 0.4])))
    a, b = f(None), f(400)
    assert np.max(np.abs(a - b)) <= 0.05 * np.max(np.abs(b)), (a, b)


def test_derivatives_do_not_depend_on_the_solver(small_points):
    """The exact derivatives come from the KKT system at the solution, not from the iterations: SMO
    ("auto") and FISTA (the default "pg" up to 2500 points) at a tight tol give the same values and derivatives."""
    # the small grid (incidental; tol and max_iter are traced): the "pg" program is the one of
    # test_core_normalize_differentiable_in_gamma's jacfwd
    opts = {**SMALL, "tol": 1e-7, "max_iter": 200_000, "derivative": "exact"}
    a = pose_sensitivity(small_points, 30.0, 0.4, **{**opts, "solver": "auto"})
    b = pose_sensitivity(small_points, 30.0, 0.4, **opts)
    for k in ("center", "scale", "dcenter_dgamma", "dscale_dgamma", "dcenter_dnu", "dscale_dnu"):
        np.testing.assert_allclose(a[k], b[k], rtol=2e-4, atol=1e-7, err_msg=k)


def test_pose_sensitivity_types(small_points):
    shape_points = small_points
    S = pose_sensitivity(np.asarray(shape_points), 30.0, 0.4, resolution=8, refine=2, band=256, tol=1e-4)
    for k in ("dcenter_dgamma", "dcenter_dnu", "center"):
        assert isinstance(S[k], np.ndarray) and S[k].shape == (3,) and np.all(np.isfinite(S[k]))
    for k in ("dscale_dgamma", "dscale_dnu", "scale"):
        assert np.shape(S[k]) == () and np.isfinite(S[k])
    assert S["converged"] and S["valid"]
    # a host function: traced inputs are refused by name before any work (a TracerArrayConversionError
    # came out of np.asarray after tracing the whole jacfwd)
    for call, name in ((lambda g: pose_sensitivity(np.asarray(shape_points), g, 0.4), "gamma"),
                       (lambda p: pose_sensitivity(p, 30.0, 0.4), "points")):
        with pytest.raises(jaxpose.InvalidInputError, match=f"traced {name}.*jax.jacfwd"):
            jax.jit(call)(30.0 if name == "gamma" else shape_points)


def test_pose_rejects_bad_options(shape_points):
    with pytest.raises(jaxpose.InvalidInputError):
        pose(shape_points, 47.0, 0.5, nu_delta=0.0)
    with pytest.raises(jaxpose.InvalidInputError):
        pose(shape_points, 47.0, 0.5, bogus=1)
    for bad in (dict(gamma_delta=0.5), dict(secant_iterations=0), dict(derivative="fd")):
        with pytest.raises(jaxpose.InvalidInputError, match=next(iter(bad))):
            pose(shape_points, 47.0, 0.5, **bad)
    # a method was normalize's TypeError "got multiple values for keyword argument 'method'"
    for call in (pose, pose_sensitivity):
        with pytest.raises(jaxpose.InvalidInputError, match="method='robust': the pose in gamma and nu is the OCSVM's"):
            call(shape_points, 47.0, 0.5, method="robust")


def test_float32_gradients_are_finite(small_points):
    shape_points = small_points
    """Regression: moments.occupancy gave NaN tangents in float32 (width^2 underflow)."""
    p32 = np.asarray(shape_points, np.float32)
    opts = SMALL
    g = jax.grad(lambda t: (lambda q: jnp.sum(q.center) + q.scale)(pose(p32, t[0], t[1], **opts)))(jnp.asarray([47.0, 0.5], jnp.float32))
    assert g.dtype == jnp.float32 and np.all(np.isfinite(np.asarray(g)))


