"""SVDD dual against scikit-learn's OneClassSVM (libsvm) as the oracle.

Mapping (see jaxpose/occupancy/svdd/): libsvm's b = dual_coef_ at support_, b = nu m alpha;
rho = offset_ = nu m mu / 2; decision_function = (nu m / 2) f.
"""
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxpose
from jaxpose.config import SolverConfig
from jaxpose.occupancy.svdd import fit_svdd, decision_function
from conftest import clusters, faust_points, sphere_with_arm

sklearn_svm = pytest.importorskip("sklearn.svm")

GAMMA = 47.0


def libsvm(points, nu):
    oc = sklearn_svm.OneClassSVM(kernel="rbf", gamma=GAMMA, nu=nu, tol=1e-6, cache_size=500).fit(points)
    m = len(points)
    b = np.zeros(m)
    b[oc.support_] = oc.dual_coef_[0]
    return oc, b / (nu * m)


def kernel(p):
    d = p[:, None, :] - p[None]
    return np.exp(-GAMMA * (d * d).sum(-1))


@pytest.mark.parametrize("solver", ["pg", "auto"])
@pytest.mark.parametrize("shape", ["sphere_with_arm", "clusters", "faust"])
@pytest.mark.parametrize("nu", [0.1, 0.5, 0.9])
def test_dual_and_signs_match_libsvm(x64, shape, nu, solver):
    # 400 points: the float64 "pg" program of test_hard_margin_nu_zero_all_points_inside. At 1000
    # the sphere with an arm at nu = 0.1 took 34,610 projected-gradient steps ("auto": 40,230) of a
    # 1000 x 1000 float64 kernel product to reach tol 1e-6 (~20 CPU s a test); at 400, 2,660
    # (5,510). Each shape and nu keeps its kind of solution: the sphere at nu = 0.1 still has most
    # support vectors free (184 of 400), the others hold capped ones (nu = 0.5 and 0.9 all shapes,
    # clusters and faust at nu = 0.1).
    m = 400
    pts = {"sphere_with_arm": sphere_with_arm, "clusters": clusters, "faust": faust_points}[shape](m)
    svdd = fit_svdd(pts, GAMMA, nu, tol=1e-6, max_iter=200_000, solver=solver)
    assert bool(svdd.converged)
    oc, a_sk = libsvm(pts, nu)
    K = kernel(pts)
    ours, theirs = float(svdd.alpha @ K @ svdd.alpha), float(a_sk @ K @ a_sk)
    assert ours <= theirs * (1 + 1e-6), (ours, theirs)
    a = np.asarray(svdd.alpha)
    assert abs(a.sum() - 1) < 1e-12 and a.min() >= 0 and a.max() <= 1 / (nu * m) * (1 + 1e-12)
    rng = np.random.default_rng(1)
    lo, hi = pts.min(0) - 0.2, pts.max(0) + 0.2
    test = rng.uniform(lo, hi, size=(10_000, 3))
    near = pts[rng.choice(m, 2_000)] + rng.normal(size=(2_000, 3)) * 0.05  # the boundary region
    test = np.concatenate([test[:8_000], near])
    f = np.asarray(decision_function(svdd, test))
    f_sk = oc.decision_function(test) * 2 / (nu * m)
    keep = np.abs(f) > 1e-6
    agree = np.mean(np.sign(f[keep]) == np.sign(f_sk[keep]))
    assert agree >= 0.999, agree
    # the two decision functions are the same function up to solver accuracy
    assert np.max(np.abs(f - f_sk)) < 1e-3 * np.ptp(f)
    # R^2 = 1 - mu + a^T K a, mu = 2 rho / (nu m)
    np.testing.assert_allclose(float(svdd.offset), 2 * oc.offset_[0] / (nu * m), rtol=1e-3)


def test_hard_margin_nu_zero_all_points_inside(x64):
    pts = sphere_with_arm(400)
    svdd = fit_svdd(pts, GAMMA, 0.0, tol=1e-8, max_iter=100_000)
    assert float(svdd.cap) == 1.0
    f = np.asarray(decision_function(svdd, pts))
    assert f.min() > -1e-6 * float(svdd.offset)  # every training point in the ball


def test_nu_one_uniform(x64):
    pts = clusters(300)
    svdd = fit_svdd(pts, GAMMA, 1.0)
    np.testing.assert_allclose(np.asarray(svdd.alpha), 1 / 300, rtol=1e-12)
    assert np.isfinite(float(svdd.offset))


def test_float32_and_jit_and_vmap():
    pts = jnp.asarray(np.stack([sphere_with_arm(300, seed=s) for s in range(3)]), jnp.float32)
    fit = jax.jit(lambda p, g, n: fit_svdd(p, g, n))
    batched = jax.vmap(fit, in_axes=(0, None, None))(pts, GAMMA, 0.5)
    assert batched.alpha.shape == (3, 300) and batched.alpha.dtype == jnp.float32
    for i in range(3):
        single = fit_svdd(pts[i], GAMMA, 0.5)
        f1 = decision_function(single, pts[i])
        fb = decision_function(jax.tree_util.tree_map(lambda v: v[i], batched), pts[i])
        assert np.max(np.abs(np.asarray(f1 - fb))) < 2e-3 * float(single.offset)
    assert bool(jnp.all(batched.converged))
    # float16 points are fitted as their float32 values (they raised a NotImplementedError: eigh and
    # the solver in float16)
    half = np.asarray(pts[0], np.float16)
    np.testing.assert_array_equal(fit_svdd(half, GAMMA, 0.5).alpha, fit_svdd(half.astype(np.float32), GAMMA, 0.5).alpha)


def test_blocked_kernel_matches_dense(x64):
    # 400 points (incidental): the dense fit is test_pinned.py's float64 solver program (448 rows)
    pts = clusters(400)
    d = fit_svdd(pts, GAMMA, 0.3, kernel="dense", tol=1e-7)
    b = fit_svdd(pts, GAMMA, 0.3, kernel="blocked", block=128, tol=1e-7)
    np.testing.assert_allclose(np.asarray(d.alpha), np.asarray(b.alpha), atol=1e-7)


def test_decision_function_blocks_and_far_offsets(x64):
    pts = sphere_with_arm(300) + 1e6
    svdd = fit_svdd(pts, GAMMA, 0.5)
    x = pts[:50] + 0.01
    f_small_blocks = decision_function(svdd, x, block=7)
    d = x[:, None] - pts[None]
    direct = 2 * np.exp(-GAMMA * (d * d).sum(-1)) @ np.asarray(svdd.alpha) - float(svdd.offset)
    np.testing.assert_allclose(np.asarray(f_small_blocks), direct, atol=1e-12)


@pytest.mark.parametrize("shape", ["clusters", "faust"])
def test_smo_alone_matches_libsvm(x64, shape):
    """Pure SMO (no PG fallback) to a tight tol: libsvm's objective, to its float32 floor."""
    m = 1000
    pts = {"clusters": clusters, "faust": faust_points}[shape](m)
    svdd = fit_svdd(pts, GAMMA, 0.5, tol=1e-6, max_iter=200_000, solver="smo")
    assert bool(svdd.converged) and int(svdd.iterations) < 20 * m
    _, a_sk = libsvm(pts, 0.5)
    K = kernel(pts)
    ours, theirs = float(svdd.alpha @ K @ svdd.alpha), float(a_sk @ K @ a_sk)
    assert ours <= theirs * (1 + 1e-6), (ours, theirs)
    a = np.asarray(svdd.alpha)
    assert abs(a.sum() - 1) < 1e-12 and a.min() >= 0 and a.max() <= 1 / (0.5 * m) * (1 + 1e-12)


def test_smo_masks_and_blocked_kernel(x64):
    """Padding rows (mask False) take no part in SMO; the blocked (matrix-free) kernel gives the
    same solution as the stored one."""
    # 300 points (incidental): the reference is the float64 SMO program of
    # test_small_gamma_nu_zero_is_the_minimum_enclosing_ball[smo]
    pts = faust_points(300)
    ref = fit_svdd(pts, GAMMA, 0.5, tol=1e-8, max_iter=100_000, solver="smo")
    padded = np.concatenate([pts, np.repeat(pts[:1], 50, axis=0)])
    mask = np.r_[np.ones(300, bool), np.zeros(50, bool)]
    s = fit_svdd(padded, GAMMA, 0.5, mask=mask, tol=1e-8, max_iter=100_000, solver="smo")
    assert bool(s.converged) and np.all(np.asarray(s.alpha)[300:] == 0)
    np.testing.assert_allclose(np.asarray(s.alpha)[:300], np.asarray(ref.alpha), atol=1e-7 / 200)
    b = fit_svdd(pts, GAMMA, 0.5, tol=1e-8, max_iter=100_000, solver="smo", kernel="blocked", block=128)
    np.testing.assert_allclose(float(b.objective), float(ref.objective), rtol=1e-9)


def test_auto_solver_caps_total_iterations():
    """"auto" gives SMO half of max_iter, then PG the rest: max_iter bounds the sum."""
    pts = clusters(300)
    svdd = fit_svdd(pts, GAMMA, 0.5, tol=1e-12, max_iter=20, solver="auto")
    assert not bool(svdd.converged) and int(svdd.iterations) == 20
    with pytest.raises(jaxpose.InvalidInputError, match="solver"):
        fit_svdd(pts, GAMMA, 0.5, solver="newton")


@pytest.mark.parametrize("max_iter", [1, 13, 17])
def test_smo_stops_at_max_iter_between_checks(max_iter):
    """SMO checks its stopping rule every SMO_GROUP updates, yet never runs past max_iter (nor
    stops short of it), and the updates past the smaller cap lower the objective."""
    from jaxpose.occupancy.svdd import SMO_GROUP

    assert SMO_GROUP > 1 and max_iter % SMO_GROUP  # the cap falls between two checks
    pts = clusters(300)
    s = fit_svdd(pts, GAMMA, 0.5, tol=1e-12, max_iter=max_iter, solver="smo")
    longer = fit_svdd(pts, GAMMA, 0.5, tol=1e-12, max_iter=max_iter + 5, solver="smo")
    assert not bool(s.converged) and int(s.iterations) == max_iter and int(longer.iterations) == max_iter + 5
    assert float(longer.objective) < float(s.objective)


@pytest.mark.parametrize("solver", ["smo", "pg", "auto"])
def test_tol_and_max_iter_share_one_program(solver):
    """The stopping rule's numbers are traced values: fits that differ only in tol or max_iter
    reuse one compiled program per solver, and still stop by them (SMO at the cap, projected
    gradient at the first check past it: SolverConfig.max_iter)."""
    from jaxpose.occupancy.svdd.fit import _solve_svdd

    pts = clusters(300)
    fit_svdd(pts, GAMMA, 0.5, tol=1e-12, max_iter=1, solver=solver)
    programs = _solve_svdd._cache_size()
    capped = fit_svdd(pts, GAMMA, 0.5, tol=1e-12, max_iter=7, solver=solver)
    loose = fit_svdd(pts, GAMMA, 0.5, tol=1e-1, max_iter=2000, solver=solver)
    tight = fit_svdd(pts, GAMMA, 0.5, tol=1e-12, max_iter=2000, solver=solver)
    assert _solve_svdd._cache_size() == programs
    cap = 7 if solver == "smo" else 7 + SolverConfig().check_every - 1
    assert 7 <= int(capped.iterations) <= cap and not bool(capped.converged)
    assert bool(loose.converged) and float(loose.kkt_violation) <= 1e-1
    assert not bool(tight.converged) and int(loose.iterations) < 2000 <= int(tight.iterations)


def test_default_solver_is_chosen_by_size():
    """solver=None: "pg" up to PG_MAX_M points, "auto" above (on CPU): the same solution as asking
    for that solver by name, bit for bit (both sides of the threshold, float32), by one program."""
    from jaxpose.occupancy.svdd import PG_MAX_M, pick_solver
    from jaxpose.occupancy.svdd.fit import _solve_svdd

    assert pick_solver("smo", 10) == "smo" and pick_solver(None, PG_MAX_M) == "pg"
    expected = "auto" if jax.default_backend() == "cpu" else "pg"
    assert pick_solver(None, PG_MAX_M + 1) == expected
    for m, name in ((400, "pg"), (PG_MAX_M + 100, expected)):
        pts = jnp.asarray(sphere_with_arm(m), jnp.float32)
        default = fit_svdd(pts, GAMMA, 0.5)
        programs = _solve_svdd._cache_size()
        named = fit_svdd(pts, GAMMA, 0.5, solver=name)
        assert _solve_svdd._cache_size() == programs  # None and the solver it stands for share it
        np.testing.assert_array_equal(np.asarray(default.alpha), np.asarray(named.alpha))
        assert int(default.iterations) == int(named.iterations)

def test_throw_on_iteration_cap():
    pts = clusters(300)
    with pytest.raises(jaxpose.ConvergenceError):
        fit_svdd(pts, GAMMA, 0.5, tol=1e-12, max_iter=20, throw=True)
    svdd = fit_svdd(pts, GAMMA, 0.5, tol=1e-12, max_iter=20)
    assert not bool(svdd.converged) and int(svdd.iterations) == 20


@pytest.mark.parametrize("bad", [dict(gamma=0.0), dict(gamma=float("nan")), dict(nu=1.5), dict(nu=-0.1)])
def test_bad_hyperparameters(bad):
    args = dict(gamma=GAMMA, nu=0.5) | bad
    with pytest.raises(jaxpose.InvalidInputError):
        fit_svdd(clusters(50), **args)


# --------------------------------------------------------------------------- stop rule across gamma
def _unit_clusters(seed):
    x = clusters(300, seed=seed)
    return x / float(np.max(x.max(0) - x.min(0)))


@pytest.mark.parametrize("solver", ["pg", "smo"])
def test_small_gamma_nu_zero_is_the_minimum_enclosing_ball(x64, solver):
    """As gamma -> 0 at nu = 0 the region is the minimum enclosing ball: its centroid is the
    miniball center (independent oracle) at the default tol, and the solver did not stop at its
    start (a violation relative to a^T K a ~ 1 stopped at iteration 0)."""
    miniball = pytest.importorskip("miniball")
    x = _unit_clusters(0)
    center, _ = miniball.get_bounding_ball(x)
    s = jaxpose.fit_svdd(x, gamma=1e-3, nu=0.0, solver=solver)
    assert bool(s.converged) and int(s.iterations) > 0
    mom = jaxpose.volume_moments(s, resolution=32)
    assert np.linalg.norm(np.asarray(mom.center) - center) < 1e-2


def test_stop_rule_is_scale_free_in_gamma(x64):
    """The violation is measured in units of min(a^T K a, 1 - a^T K a): at small gamma the
    differences of K a are O(gamma) and so is 1 - a^T K a, so the rule's value at a fixed
    non-optimal alpha does not vanish with gamma (it did, relative to a^T K a -> 1)."""
    from jaxpose.occupancy.kernels import gaussian_kernel
    from jaxpose.occupancy.svdd import kkt_violation

    x = jnp.asarray(_unit_clusters(1))
    a = jnp.full((x.shape[0],), 1.0 / x.shape[0])
    mask = jnp.ones(x.shape[0], bool)
    caps = jnp.ones(x.shape[0])
    v = [float(kkt_violation(a, gaussian_kernel(x, x, g) @ a, caps, mask)[0]) for g in (1e-2, 1e-3, 1e-4)]
    np.testing.assert_allclose(v[1:], v[0], rtol=0.02)  # O(gamma) numerator over O(gamma) unit
    assert v[0] > 0.1
    # at large gamma a^T K a is the smaller unit: the rule is libsvm's gap relative to the objective
    Ka = gaussian_kernel(x, x, 200.0) @ a
    viol, obj = kkt_violation(a, Ka, caps, mask)
    assert float(obj) < 0.5
    np.testing.assert_allclose(float(viol), float((jnp.max(Ka) - jnp.min(Ka)) / obj), rtol=1e-12)


@pytest.mark.parametrize("gamma", [1e-3, 0.1])
def test_default_tol_is_close_to_a_tight_solution_at_small_gamma(x64, gamma):
    """normalize at the default tol against tol 1e-9 on a sphere with an arm at nu = 0, where the
    region is held by a few points (polishing solves their active set exactly)."""
    # 400 points at resolution 32 (incidental): the float64 program of test_pose.py's
    # test_translation_is_exact_at_any_offset and test_pinned.py (gamma, nu, tol, max_iter are traced)
    pts = sphere_with_arm(400, seed=1)
    a = jaxpose.normalize(pts, method="ocsvm", gamma=gamma, nu=0.0, resolution=32)
    b = jaxpose.normalize(pts, method="ocsvm", gamma=gamma, nu=0.0, resolution=32, tol=1e-9, max_iter=100_000)
    assert bool(b.converged)
    scale = float(b.scale)
    assert np.linalg.norm(np.asarray(a.center) - np.asarray(b.center)) <= 1e-3 * scale
    assert abs(float(a.scale) - scale) <= 1e-3 * scale


def test_polish_solves_the_active_set_exactly(x64):
    """From a projected-gradient iterate stopped at tol 1e-3, the polished solution satisfies the
    KKT conditions to rounding (libsvm at a tight tol as the oracle for the weights)."""
    from jaxpose.occupancy.kernels import gaussian_kernel
    from jaxpose.occupancy.svdd.pg import solve_pg
    from jaxpose.occupancy.svdd.polish import polish
    from jaxpose.occupancy.svdd.problem import caps as point_caps
    from jaxpose.config import SolverConfig

    x = jnp.asarray(_unit_clusters(2))
    m, g = x.shape[0], 2.0
    mask = jnp.ones(m, bool)
    caps = point_caps(jnp.asarray(0.0), mask)
    a, Ka, _, viol = solve_pg(x, jnp.asarray(g), caps, mask, jnp.full((m,), 1.0 / m), SolverConfig())
    K = gaussian_kernel(x, x, g)
    b, vb = polish(x, jnp.asarray(g), caps, mask, a, viol, lambda v: K @ v)
    assert float(vb) < 1e-9 < float(viol)
    np.testing.assert_allclose(float(jnp.sum(b)), 1.0, atol=1e-12)
    sk = pytest.importorskip("sklearn.svm")
    ref = sk.OneClassSVM(kernel="rbf", gamma=g, nu=1.0 / m, tol=1e-10).fit(np.asarray(x))
    want = np.zeros(m)
    want[ref.support_] = ref.dual_coef_[0] / ref.dual_coef_[0].sum()
    np.testing.assert_allclose(np.asarray(b), want, atol=2e-4)


def test_a_traced_gamma_or_nu_out_of_range_is_not_converged():
    """Concrete out-of-range values are refused; traced ones cannot be. jit(fit_svdd)(nu=1.5) returned
    converged=True with alpha summing to 0.67 (no solution of the problem), nu=-0.2 and nu=inf
    converged=True too, with nothing to say they were invalid. Now converged=False for a traced gamma
    or nu outside the concrete rule (normalize flags the same as Status.BAD_PARAMETERS); values in
    range are as before."""
    # 300 points (incidental): the concrete fit is the float32 program of
    # test_float32_and_jit_and_vmap and test_tol_and_max_iter_share_one_program[pg] (300 rows)
    points = np.random.default_rng(0).normal(size=(300, 3)).astype(np.float32)
    fit = jax.jit(lambda g, n: fit_svdd(points, g, n))
    for g, n in [(1.0, 1.5), (1.0, -0.2), (1.0, np.inf), (-1.0, 0.5), (0.0, 0.5), (np.nan, 0.5), (1.0, np.nan)]:
        assert not bool(fit(g, n).converged), (g, n)
    good, concrete = fit(1.0, 0.5), fit_svdd(points, 1.0, 0.5)
    assert bool(good.converged) and bool(concrete.converged)
    np.testing.assert_allclose(good.alpha, concrete.alpha, atol=1e-6)
    batch = jax.vmap(lambda n: fit_svdd(points, 1.0, n))(jnp.asarray([0.5, 1.5, 0.3]))
    assert batch.converged.tolist() == [True, False, True]
    # the rule is normalize's BAD_PARAMETERS rule, one helper
    from jaxpose.occupancy.svdd.problem import parameters_in_range

    assert parameters_in_range(jnp.asarray([1.0, -1.0, 1.0]), jnp.asarray([1.0, 0.5, 1.01])).tolist() == [True, False, False]


def test_solve_svdd_with_gamma_or_nu_out_of_range_is_not_converged():
    """The rule is solve_svdd's (exported, no checks), which fit_svdd and the OCSVM pose call:
    jit(solve_svdd)(P, 1.0, 1.5) gave converged=True (the rule was fit_svdd's only); concrete
    out-of-range values, which solve_svdd does not refuse, too. In range: converged as before."""
    from jaxpose.config import SolverConfig
    from jaxpose.occupancy.svdd import solve_svdd

    points = jnp.asarray(np.random.default_rng(0).normal(size=(120, 3)).astype(np.float32))
    solve = jax.jit(lambda g, n: solve_svdd(points, g, n, None, None, SolverConfig()))
    for g, n in [(1.0, 1.5), (1.0, -0.2), (-1.0, 0.5), (np.nan, 0.5)]:
        assert not bool(solve(g, n).converged), (g, n)
        assert not bool(solve_svdd(points, g, n, None, None, SolverConfig()).converged), (g, n)
    assert bool(solve(1.0, 0.5).converged) and bool(solve_svdd(points, 1.0, 0.5, None, None, SolverConfig()).converged)
