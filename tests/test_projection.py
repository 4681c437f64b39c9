import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxpose.occupancy.svdd.projection import projection_capped_simplex


def oracle(y, cap):
    """Exact projection by sorting the breakpoints {y_i - C, y_i} (independent of the library)."""
    y = np.asarray(y, float)
    bps = np.sort(np.concatenate([y - cap, y]))
    s = lambda t: np.clip(y - t, 0, cap).sum()
    # s is piecewise linear decreasing; find the segment where it crosses 1
    vals = np.array([s(t) for t in bps])
    i = np.nonzero(vals >= 1)[0].max()
    t0, t1 = bps[i], bps[min(i + 1, len(bps) - 1)]
    if t1 == t0 or vals[i] == 1:
        return np.clip(y - t0, 0, cap)
    v0, v1 = vals[i], s(t1)
    t = t0 + (v0 - 1) * (t1 - t0) / (v0 - v1)
    return np.clip(y - t, 0, cap)


@pytest.mark.parametrize("m,cap", [(10, 0.3), (50, 0.05), (200, 1.0), (100, 0.0101)])
def test_matches_oracle(x64, m, cap):
    rng = np.random.default_rng(m)
    for _ in range(5):
        y = rng.normal(size=m) * rng.uniform(0.01, 3)
        a = np.asarray(projection_capped_simplex(jnp.asarray(y), cap))
        np.testing.assert_allclose(a, oracle(y, cap), atol=1e-12)
        assert abs(a.sum() - 1) < 1e-13
        assert a.min() >= 0 and a.max() <= cap + 1e-15


def test_float32_sum_exact():
    y = jnp.asarray(np.random.default_rng(0).normal(size=1000), jnp.float32)
    a = projection_capped_simplex(y, 1.0 / 300)
    assert a.dtype == jnp.float32
    assert abs(float(a.sum()) - 1) < 1e-5


def test_vector_cap_pins_masked_coordinates(x64):
    y = jnp.asarray(np.random.default_rng(1).normal(size=20))
    cap = jnp.where(jnp.arange(20) < 15, 0.1, 0.0)
    a = projection_capped_simplex(y, cap)
    assert np.all(np.asarray(a)[15:] == 0)
    np.testing.assert_allclose(np.asarray(a)[:15], oracle(np.asarray(y)[:15], 0.1), atol=1e-12)


def test_jacobian_matches_finite_differences(x64):
    rng = np.random.default_rng(3)
    y = jnp.asarray(rng.normal(size=30))
    cap = 0.08
    J = jax.jacfwd(projection_capped_simplex)(y, cap)
    Jr = jax.jacrev(projection_capped_simplex)(y, cap)
    eps = 1e-7
    fd = np.stack([(oracle(y + eps * e, cap) - oracle(y - eps * e, cap)) / (2 * eps) for e in np.eye(30)], axis=1)
    np.testing.assert_allclose(J, fd, atol=1e-6)
    np.testing.assert_allclose(Jr, fd, atol=1e-6)
    dcap = jax.grad(lambda c: projection_capped_simplex(y, c) @ jnp.arange(30.0))(cap)
    fdc = (oracle(y, cap + eps) - oracle(y, cap - eps)) @ np.arange(30.0) / (2 * eps)
    np.testing.assert_allclose(dcap, fdc, rtol=1e-5, atol=1e-7)


@pytest.mark.parametrize("kind", ["outlier", "ties", "constant", "tiny", "all_at_cap"])
def test_hard_inputs_match_oracle(x64, kind):
    """Issue 5: tau is found by safeguarded Newton steps (not 64 bisection steps); inputs where the
    sum is flat, has ties, spans 10 orders of magnitude, or is solved with every coordinate at the cap."""
    rng = np.random.default_rng(0)
    m, cap = 300, 0.01
    y = rng.normal(size=m) * 1e-3
    if kind == "outlier":
        y[7] = 1e4
    elif kind == "ties":
        y = np.round(y * 1e3) / 1e3
    elif kind == "constant":
        y = np.full(m, 0.3)
    elif kind == "tiny":
        y = y * 1e-9
    else:
        cap = 1.0 / m
    a = np.asarray(projection_capped_simplex(jnp.asarray(y), cap))
    np.testing.assert_allclose(a, oracle(y, cap), atol=1e-12 * max(1.0, cap / 1e-2))
    assert abs(a.sum() - 1) < 1e-12
    assert a.min() >= 0 and a.max() <= cap * (1 + 1e-12)


def test_search_takes_few_steps(x64):
    """The steps the tau search takes on a solver-like input (a feasible point plus a small step)."""
    from jaxpose.occupancy.svdd.projection import _find_tau

    rng = np.random.default_rng(2)
    m, cap = 2000, 1e-3
    a = np.asarray(projection_capped_simplex(jnp.asarray(rng.uniform(0, 1, m)), cap))
    y = jnp.asarray(a - 2e-3 * rng.uniform(0, 1, m))
    steps = []
    for limit in range(1, 65):
        tau = _find_tau(y, jnp.full(m, cap), limit)
        steps.append(float(jnp.sum(jnp.clip(y - tau, 0, cap))))
        if abs(steps[-1] - 1) < 1e-13:
            break
    assert len(steps) <= 12, steps  # 64 bisection steps before issue 5
