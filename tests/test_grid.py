"""Grids that cover the SVDD region and the evaluation of f on them (jaxpose.occupancy.grid)."""
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxpose.occupancy.grid import cell_centers, domain, evaluate_on_grid
from jaxpose.occupancy.grid import CHILD_OFFSETS, first_true
from jaxpose.occupancy.runs import running_sum
from jaxpose.errors import InvalidInputError
from jaxpose.occupancy.svdd import SVDD, decision_function, fit_svdd
from conftest import box_surface, clusters, sphere_with_arm


def manual_svdd(points, alpha, gamma, offset):
    points = jnp.asarray(points, float)
    m = len(points)
    return SVDD(points, jnp.asarray(alpha, float), jnp.asarray(gamma, float), jnp.asarray(1.0), jnp.asarray(offset, float),
                jnp.asarray(0.0), jnp.asarray(0), jnp.asarray(0.0), jnp.asarray(True), jnp.ones(m, bool))


@jax.jit
def _autodiff_gradient(svdd, x):
    """The oracle: grad f at each row of x by autodiff of decision_function, one compiled program
    (op by op it compiled each operation of the vmapped gradient on its own)."""
    return jax.vmap(jax.grad(lambda p: decision_function(svdd, p[None])[0]))(x)


def test_decision_function_refuses_a_bad_block_by_name():
    # it was clamped silently (0 and -1 ran as 1, 2.5 as 2, True as 1) or raised int()'s TypeError (None)
    svdd = manual_svdd(np.zeros((2, 3)), [0.5, 0.5], 1.0, 1.0)
    for block in (0, -1, 2.5, None, True):
        with pytest.raises(InvalidInputError, match="block"):
            decision_function(svdd, np.zeros((4, 3)), block=block)


@pytest.mark.parametrize("make", [sphere_with_arm, clusters, box_surface])
def test_domain_contains_region(x64, make):
    pts = make(300)  # the size is incidental: the solver program of the tests below (300 points)
    svdd = fit_svdd(pts, 47.0, 0.2)
    lo, hi = (np.asarray(v) for v in domain(svdd))
    rng = np.random.default_rng(0)
    # points just outside the domain box, on all sides: f must be negative there
    far = rng.uniform(lo - 0.5, hi + 0.5, size=(20000, 3))
    outside = far[np.any((far < lo) | (far > hi), axis=1)]
    assert np.all(np.asarray(decision_function(svdd, outside)) < 0)
    # and the region touches the box interior only: some inside points positive
    assert np.any(np.asarray(decision_function(svdd, pts)) > 0)


def test_grid_gradient_matches_autodiff(x64):
    import jax

    svdd = fit_svdd(clusters(300), 47.0, 0.5)  # 300 points (incidental): the solver program of the tests here
    x = jnp.asarray(np.random.default_rng(0).uniform(-0.5, 0.5, size=(50, 3)))
    f, g = evaluate_on_grid(svdd, x, block=16)
    np.testing.assert_allclose(np.asarray(f), np.asarray(decision_function(svdd, x)), atol=1e-12)
    g_ad = _autodiff_gradient(svdd, x)
    np.testing.assert_allclose(np.asarray(g), np.asarray(g_ad), atol=1e-10)


def test_grid_tangent_in_one_pass_matches_autodiff(x64):
    """evaluate_on_grid_jvp: f, grad f and their tangents in (alpha, gamma, offset), against
    jax.jvp of evaluate_on_grid, with the terms of every point or of the support only."""
    import jax

    from jaxpose.occupancy.grid import evaluate_on_grid_jvp

    svdd = fit_svdd(clusters(300), 47.0, 0.5)
    rng = np.random.default_rng(1)
    x = jnp.asarray(rng.uniform(-0.6, 0.6, size=(70, 3)))
    da = jnp.asarray(rng.normal(size=300)) * 1e-2
    for support in (jnp.ones(300, bool), svdd.alpha != 0):
        da_s = jnp.where(support, da, 0.0)  # evaluate_on_grid drops the terms (and tangents) off the support
        def f(a, g, o):
            return evaluate_on_grid(svdd._replace(alpha=a, gamma=g, offset=o), x, 16, None, support)
        ref_v, ref_t = jax.jvp(f, (svdd.alpha, svdd.gamma, svdd.offset), (da_s, jnp.asarray(0.7), jnp.asarray(-0.2)))
        out = evaluate_on_grid_jvp(svdd, (da, jnp.asarray(0.7), jnp.asarray(-0.2)), x, 16, None, support)
        for got, want in zip(out, ref_v + ref_t):
            np.testing.assert_allclose(np.asarray(got), np.asarray(want), rtol=1e-10, atol=1e-12)
        assert float(jnp.max(jnp.abs(out[2]))) > 1e-3  # a tangent that is not zero


def test_domain_is_snapped_and_piecewise_constant(x64):
    # issue 3: the grid must not follow gamma continuously (derivatives hold it fixed)
    from jaxpose.occupancy.grid import LATTICE, region_radius

    svdd = fit_svdd(box_surface(300), 47.0, 0.5, tol=1e-6)
    lo, hi = (np.asarray(v) for v in domain(svdd))
    sv = np.asarray(svdd.points)[np.asarray(svdd.alpha) > 0]
    r = float(region_radius(svdd))
    assert np.all(lo <= sv.min(0) - r) and np.all(hi >= sv.max(0) + r)
    q = 2.0 ** np.floor(np.log2(np.max(hi - lo))) / LATTICE
    assert np.all(np.max(hi - lo) / q <= 2 * LATTICE)
    np.testing.assert_array_equal(np.round(lo / q), lo / q)
    np.testing.assert_array_equal(np.round(hi / q), hi / q)
    assert np.all(lo >= sv.min(0) - r - q) and np.all(hi <= sv.max(0) + r + q)
    nearby = svdd._replace(gamma=svdd.gamma * (1 + 1e-6))
    for a, b in zip(domain(svdd), domain(nearby)):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))


def test_morton_order_matches_codes_of_cell_centers():
    from jaxpose.occupancy.grid import morton_codes, morton_order

    codes_of = jax.jit(morton_codes)  # compiled, as the grids use it (one program per shape, not per operation)
    for n in (4, 8, 32):
        lo, hi = jnp.array([-1.0, -1.0, -1.0]), jnp.array([1.0, 1.0, 1.0])
        x, _ = jax.jit(cell_centers, static_argnums=2)(lo, hi, n)
        perm = morton_order(n)
        assert sorted(perm.tolist()) == list(range(n**3))
        codes = np.asarray(codes_of(x, lo, hi))
        assert np.all(np.diff(codes[perm]) > 0)  # the static order is the order of the codes
    # bit interleaving against a direct construction: x bits at 3b + 2, y at 3b + 1, z at 3b
    q = np.array([[5, 3, 1], [1023, 0, 512]])
    expect = [sum(((int(v[a]) >> b) & 1) << (3 * b + 2 - a) for b in range(10) for a in range(3)) for v in q]
    got = codes_of(jnp.asarray(q + 0.5, jnp.float32), jnp.zeros(3), jnp.full(3, 1024.0))
    assert np.asarray(got).tolist() == expect


def test_far_chunks_are_skipped_without_changing_f(x64):
    """Support points along a segment 4 long, cells in blocks along it: each block skips the
    chunks of points beyond the cutoff (~1 in float64); f and grad f still equal the dense sums
    (a cutoff 3x shorter fails this)."""
    import jax

    rng = np.random.default_rng(1)
    t = rng.uniform(0.0, 4.0, 1200)
    pts = np.c_[t, 0.05 * rng.normal(size=1200), 0.05 * rng.normal(size=1200)]
    svdd = fit_svdd(pts, 47.0, 0.5)
    s = np.sort(rng.uniform(-0.3, 4.3, 2000))
    x = jnp.asarray(np.c_[s, 0.2 * rng.uniform(-1, 1, size=(2000, 2))])
    f, g = evaluate_on_grid(svdd, x, block=128)
    np.testing.assert_allclose(np.asarray(f), np.asarray(decision_function(svdd, x)), atol=1e-13)
    g_ad = _autodiff_gradient(svdd, x)
    np.testing.assert_allclose(np.asarray(g), np.asarray(g_ad), atol=1e-11)


def test_separable_subgrids_equal_direct_evaluation(x64):
    """evaluate_subgrids (products of per-axis factors, one batched matrix product per block) gives
    the same f and grad f as the direct sums at the same cell centers, with far chunks skipped
    per block of boxes along a segment 4 long (cutoff ~0.9 in float64)."""
    import jax

    from jaxpose.occupancy.grid import evaluate_subgrids

    rng = np.random.default_rng(2)
    t = rng.uniform(0.0, 4.0, 1200)
    pts = np.c_[t, 0.05 * rng.normal(size=1200), 0.05 * rng.normal(size=1200)]
    svdd = fit_svdd(pts, 47.0, 0.5)
    corners = jnp.asarray(np.c_[np.sort(rng.uniform(-0.3, 4.3, 300)), rng.uniform(-0.3, 0.1, size=(300, 2))])
    h = jnp.asarray([0.3, 0.05, 0.04])  # boxes 1.2 long in x, beyond the cutoff: a box bound of the
    # corner alone (not the whole box) fails this
    n = 4
    f, g = evaluate_subgrids(svdd, corners, h, n, block=8 * n**3)
    i = np.arange(n) + 0.5
    local = np.stack(np.meshgrid(i, i, i, indexing="ij"), axis=-1).reshape(-1, 3) * np.asarray(h)
    x = (np.asarray(corners)[:, None, :] + local).reshape(-1, 3)
    np.testing.assert_allclose(np.asarray(f).reshape(-1), np.asarray(decision_function(svdd, x)), atol=1e-13)
    g_ad = _autodiff_gradient(svdd, jnp.asarray(x))
    np.testing.assert_allclose(np.asarray(g).reshape(-1, 3), np.asarray(g_ad), atol=1e-11)
    # count: boxes of the blocks past it are not evaluated (zeros)
    f2, _ = evaluate_subgrids(svdd, corners, h, n, block=8 * n**3, count=jnp.asarray(16))
    np.testing.assert_array_equal(np.asarray(f2)[:16], np.asarray(f)[:16])
    assert np.all(np.asarray(f2)[16:] == 0)


@pytest.mark.parametrize("resolution", [16, 33, 40, 64])
def test_grid_layout_matches_cell_centers(x64, resolution):
    """evaluate_grid: the coarse grid in boxes of at most 32^3 cells (resolution 33: 2 x 17 per
    axis, cells past the grid dropped), rows in Morton order, equal to the direct sums."""
    from jaxpose.occupancy.grid import cell_centers, evaluate_grid, morton_order

    svdd = fit_svdd(clusters(300), 47.0, 0.5)
    lo, hi = domain(svdd)
    x, h, f, g = evaluate_grid(svdd, lo, hi, resolution)
    x0, h0 = cell_centers(lo, hi, resolution)
    np.testing.assert_array_equal(np.asarray(x), np.asarray(x0)[morton_order(resolution)])
    np.testing.assert_array_equal(np.asarray(h), np.asarray(h0))
    f0, g0 = evaluate_on_grid(svdd, x, block=4096)
    np.testing.assert_allclose(np.asarray(f), np.asarray(f0), atol=1e-13)
    np.testing.assert_allclose(np.asarray(g), np.asarray(g0), atol=1e-11)


def _segment_svdd():
    """An SVDD along a segment 4 long (far chunks skipped per block; cutoff ~0.9 in float64)."""
    rng = np.random.default_rng(2)
    t = rng.uniform(0.0, 4.0, 1200)
    return fit_svdd(np.c_[t, 0.05 * rng.normal(size=1200), 0.05 * rng.normal(size=1200)], 47.0, 0.5), rng


def _lattice_cells(rng, lo, h, n, k):
    """k distinct cells of a lattice lo + (i + 1/2) h, i < n / 2 per axis, in Z-order: 3/4 of them
    within 0.15 of the segment's axis (where the boundary is), the rest anywhere."""
    from jaxpose.occupancy.grid import morton_codes

    ijk = np.stack(np.unravel_index(np.arange((n // 2) ** 3), (n // 2,) * 3), -1)
    x = lo + (ijk + 0.5) * h
    near = np.flatnonzero(np.max(np.abs(x[:, 1:]), axis=1) < 0.15)
    i = rng.choice(near, size=3 * k // 4, replace=False)
    i = np.r_[i, rng.choice(np.setdiff1d(np.arange(len(x)), i), size=k - len(i), replace=False)]
    cells = jnp.asarray(x[i])
    return cells[np.argsort(np.asarray(morton_codes(cells, lo, lo + h * n / 2)))]


def test_children_from_tables_equal_direct_evaluation(x64, monkeypatch):
    """evaluate_children (per-axis factor tables on the children's lattice, no exponential per child)
    gives f and grad f of the direct sums at every child, in ``CHILD_OFFSETS`` order; count in cells; the
    direct fallback when the tables would be too big gives the same."""
    import jax

    from jaxpose.occupancy import grid

    svdd, rng = _segment_svdd()
    lo, hi = domain(svdd)
    n = 64  # children per axis: cells of 32 per axis
    h = (hi - lo) / (n // 2)
    cells = _lattice_cells(rng, np.asarray(lo), np.asarray(h), n, 700)
    f, g = grid.evaluate_children(svdd, lo, h, cells, n, block=64)
    assert f.shape == (700, 8) and g.shape == (700, 8, 3)
    x = (cells[:, None, :] + CHILD_OFFSETS * h).reshape(-1, 3)
    np.testing.assert_allclose(np.asarray(f).reshape(-1), np.asarray(decision_function(svdd, x)), atol=1e-13)
    g_ad = _autodiff_gradient(svdd, x)
    np.testing.assert_allclose(np.asarray(g).reshape(-1, 3), np.asarray(g_ad), atol=1e-11)
    assert np.mean(np.asarray(f) > 0) > 0.05 and np.mean(np.asarray(f) < 0) > 0.5  # inside and outside
    f2, _ = grid.evaluate_children(svdd, lo, h, cells, n, block=64, count=jnp.asarray(100))  # blocks of 64 cells
    np.testing.assert_array_equal(np.asarray(f2)[:128], np.asarray(f)[:128])
    assert np.all(np.asarray(f2)[128:] == 0)
    monkeypatch.setattr(grid, "TABLE_BYTES", 0)
    f3, g3 = grid.evaluate_children(svdd, lo, h, cells, n, block=64)
    np.testing.assert_allclose(np.asarray(f3), np.asarray(f), atol=1e-13)
    np.testing.assert_allclose(np.asarray(g3), np.asarray(g), atol=1e-11)


def test_children_from_tables_are_accurate_in_float32():
    """In float32 the tables take each per-axis difference x_a - p_a directly, where the direct sums
    expand |x - p|^2 = |x|^2 + |p|^2 - 2 x.p and lose digits: f within a few roundings of its float64
    value on the segment (3.1e-8, mu = 0.078), 50x closer than the direct sums (1.5e-6)."""
    import jax

    from jaxpose.occupancy import grid

    with jax.enable_x64(True):
        svdd64, rng = _segment_svdd()
        lo, hi = domain(svdd64)
        h = (hi - lo) / 32
        cells = _lattice_cells(rng, np.asarray(lo), np.asarray(h), 64, 700)
        x = (cells[:, None, :] + CHILD_OFFSETS * h).reshape(-1, 3)
        exact = np.asarray(decision_function(svdd64, x))
    svdd = jax.tree_util.tree_map(lambda a: jnp.asarray(a, jnp.float32) if jnp.issubdtype(a.dtype, jnp.floating) else jnp.asarray(a),
                                  svdd64)
    c32, lo32, h32 = (jnp.asarray(np.asarray(a), jnp.float32) for a in (cells, lo, h))
    f, _ = grid.evaluate_children(svdd, lo32, h32, c32, 64, block=64)
    direct, _ = evaluate_on_grid(svdd, (c32[:, None, :] + CHILD_OFFSETS * h32).reshape(-1, 3))
    err_tables = np.max(np.abs(np.asarray(f, np.float64).reshape(-1) - exact))
    err_direct = np.max(np.abs(np.asarray(direct, np.float64) - exact))
    mu = float(svdd64.offset)  # f = 2 k^T alpha - mu: its rounding is eps * mu
    assert err_tables <= 8 * np.finfo(np.float32).eps * mu, (err_tables, mu)  # measured 3.3 eps mu
    assert err_tables < err_direct / 10, (err_tables, err_direct)  # measured 50x


@pytest.mark.parametrize("n", [1, 2, 5, 33, 1000])
def test_first_true_and_running_sum_equal_numpy(n):
    import jax

    # compiled, as the library runs them (one program per shape, not one per operation)
    counts = jax.jit(running_sum)
    first = jax.jit(first_true, static_argnums=(1, 2))
    rng = np.random.default_rng(n)
    for fill in (0.0, 0.05, 0.5, 1.0):  # empty, sparse, half, full masks
        mask = rng.random(n) < fill
        np.testing.assert_array_equal(np.asarray(counts(jnp.asarray(mask, jnp.int32))), np.cumsum(mask))
        for size in (1, max(1, n // 3), n + 2):  # fewer, about as many and more slots than True entries
            want = np.full(size, -1)
            idx = np.nonzero(mask)[0][:size]
            want[:len(idx)] = idx
            got = np.asarray(first(jnp.asarray(mask), size, -1))
            assert got.dtype == np.int32
            np.testing.assert_array_equal(got, want)
