"""The JAX robust solid of a point cloud against SciPy (morphology, labels, distances) and against
the NumPy solid it replaces (jaxpose.occupancy.solid), voxel for voxel."""
from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import ndimage
from scipy.spatial import cKDTree

from jaxpose.occupancy import bits
from jaxpose.occupancy import points as po
from jaxpose.occupancy import solid as host_solid
from jaxpose.config import RobustConfig

CONFIG = RobustConfig(resolution=48, coarse=24)  # small grids (79^3, 55^3): the same algorithm


def _random_solid(shape=(40, 36, 30), seed=0, density=0.45):
    rng = np.random.default_rng(seed)
    return ndimage.binary_opening(rng.random(shape) < density)


def _ellipsoid_with_stray(m=3000, seed=0):
    """Samples of an ellipsoid's surface (semi-axes 1, 0.6, 0.4), a small far blob (a stray part)
    and a thin rod touching the body (kept with it)."""
    rng = np.random.default_rng(seed)
    u = rng.normal(size=(m, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    body = u * np.array([1.0, 0.6, 0.4])
    k = m // 40
    blob = rng.normal(size=(k, 3)) * 0.03 + np.array([2.2, 0.0, 0.0])
    return np.concatenate([body, blob])


@pytest.mark.parametrize("seed", [0, 1])
def test_exterior_fill_equals_scipy(seed):
    s = _random_solid(seed=seed)
    s[5:25, 5:25, 5:25] |= ~ndimage.binary_erosion(np.ones((20, 20, 20), bool))  # a hollow box: one cavity
    out = np.asarray(jax.jit(po.exterior_fill)(jnp.asarray(s)))
    assert np.array_equal(out, ndimage.binary_fill_holes(s))


@pytest.mark.parametrize("shape", [(9, 7, 5), (12, 10, 33), (20, 18, 70), (6, 5, 130)])
def test_exterior_fill_equals_scipy_across_word_counts(shape):
    """Lines of 1 to 5 packed words (partial last words); 35 % free cells, just above 3-D site
    percolation: winding open channels and many enclosed pockets."""
    s = np.random.default_rng(sum(shape)).random(shape) < 0.65
    filled = np.asarray(jax.jit(po.exterior_fill)(jnp.asarray(s)))
    ref = ndimage.binary_fill_holes(s)
    assert ref.sum() > s.sum() and (~ref).sum() > 0  # pockets filled, channels open: the test means something
    assert np.array_equal(filled, ref)


def test_exterior_fill_vmapped_equals_each():
    grids = np.random.default_rng(5).random((3, 14, 12, 40)) < 0.65
    out = np.asarray(jax.jit(jax.vmap(po.exterior_fill))(jnp.asarray(grids)))
    assert all(np.array_equal(out[k], ndimage.binary_fill_holes(grids[k])) for k in range(3))


@pytest.mark.parametrize("c", [5, 32, 45, 100])
def test_bits_pack_unpack_and_shift(c):
    x = np.random.default_rng(c).random((3, 4, c)) < 0.5
    w = bits.pack(jnp.asarray(x))
    assert w.shape == (3, 4, -(-c // 32)) and w.dtype == jnp.uint32
    assert np.array_equal(np.asarray(bits.unpack(w, c)), x)
    for s in (1, -1, 7, -13, 31, -32, 33, 64, -70):
        ref = np.zeros_like(x)
        if s > 0:
            ref[..., s:] = x[..., : max(c - s, 0)]
        else:
            ref[..., : max(c + s, 0)] = x[..., -s:]
        assert np.array_equal(np.asarray(bits.unpack(bits.shift_bits(w, s), c)), ref), s


@pytest.mark.parametrize("seed", [0, 1])
def test_components_partition_equals_scipy(seed):
    s = _random_solid(seed=seed)
    labels = np.asarray(jax.jit(po.components)(jnp.asarray(s)))
    ref, n = ndimage.label(s, structure=np.ones((3, 3, 3), bool))
    assert n > 20  # many components: the test means something
    pairs = set(zip(labels[s].tolist(), ref[s].tolist()))
    assert len(pairs) == n and len(set(labels[s].tolist())) == n  # one label per component, and only one
    for lab in set(labels[s].tolist()):  # the label is the smallest flat index of its component
        assert lab == np.flatnonzero((labels == lab).reshape(-1))[0]
    assert np.all(labels[~s] == po._BIG)


@pytest.mark.parametrize("ratio", [0.5, 0.05])
def test_keep_main_equals_numpy(ratio):
    # the shape of _blobs below: one compiled keep_main for this module's grids (the ratio is traced)
    s = _random_solid(shape=(24, 22, 40), seed=2, density=0.5)
    kept, count, dropped = jax.jit(po.keep_main)(jnp.asarray(s), ratio)
    ref, n, d = host_solid.keep_main(s, ratio)
    assert np.array_equal(np.asarray(kept), ref) and int(count) == n and int(dropped) == d


def _blobs(count, shape=(24, 22, 40), seed=0):
    """``count`` separate boxes of random sizes, two of them touching only at a corner (one
    26-connected component)."""
    rng = np.random.default_rng(seed)
    s = np.zeros(shape, bool)
    s[1:4, 1:4, 1:4] = True
    s[4:6, 4:6, 4:6] = True  # corner contact with the first box: the same component
    for k in range(count - 1):
        a, b, c = 1 + 5 * (k % 4), 8 + 5 * (k // 4 % 3), 8 + 6 * (k // 12)
        s[a:a + rng.integers(1, 4), b:b + rng.integers(1, 4), c:c + rng.integers(1, 5)] = True
    return s


@pytest.mark.parametrize("count", [0, 1, 2, 7, 8, 9, 13])
@pytest.mark.parametrize("ratio", [0.5, 0.05])
def test_keep_main_few_and_many_components(count, ratio):
    """None, one, a few and many components (corner contacts joined): as the NumPy keep_main."""
    s = _blobs(count, seed=count) if count else np.zeros((24, 22, 40), bool)  # one shape: one program
    ref, n, d = host_solid.keep_main(s, ratio) if count else (s, 0, 0)
    assert n == count
    kept, found, dropped = jax.jit(po.keep_main)(jnp.asarray(s), ratio)
    assert np.array_equal(np.asarray(kept), ref) and int(found) == n and int(dropped) == d


def test_keep_main_vmapped():
    # on test_runs.py's (130, 130, 40) grids, three of them: its vmapped keep_main program
    grids = np.stack([_blobs(k, shape=(130, 130, 40), seed=s) for k, s in ((3, 1), (12, 2), (1, 3))])
    kept, found, dropped = jax.jit(jax.vmap(lambda g: po.keep_main(g, 0.5)))(jnp.asarray(grids))
    for k in range(3):
        ref, n, d = host_solid.keep_main(grids[k], 0.5)
        assert np.array_equal(np.asarray(kept[k]), ref) and int(found[k]) == n and int(dropped[k]) == d


def test_erode6_is_scipy_binary_erosion():
    s = _random_solid(seed=3, density=0.7)
    assert np.array_equal(np.asarray(jax.jit(po.erode6)(jnp.asarray(s))), ndimage.binary_erosion(s))


@pytest.mark.parametrize("r2", [0, 1, 2, 4, 9, 16, 27, 36])
def test_dilate_ball_equals_scipy_distances(r2):
    """Cells within sqrt(r2) of a feature (squared Euclidean distance <= r2), packed lines of 2
    words (the last one partial); the grid's border counts as no feature."""
    feature = np.random.default_rng(4).random((30, 28, 45)) < 0.004
    out = bits.unpack(jax.jit(bits.dilate_ball, static_argnums=2)(bits.pack(jnp.asarray(feature)), r2, 6), 45)
    ref = ndimage.distance_transform_edt(~feature) ** 2 <= r2 + 1e-9
    assert 0 < ref.sum() < ref.size and np.array_equal(np.asarray(out), ref)


def test_dilate_ball_vmapped_radii():
    feature = np.random.default_rng(5).random((3, 16, 15, 20)) < 0.01
    r2 = jnp.array([1, 5, 12])
    out = jax.jit(jax.vmap(lambda f, r: bits.unpack(bits.dilate_ball(bits.pack(f), r, 4), 20)))(jnp.asarray(feature), r2)
    for k in range(3):
        ref = ndimage.distance_transform_edt(~feature[k]) ** 2 <= int(r2[k]) + 1e-9
        assert np.array_equal(np.asarray(out[k]), ref)


def test_spacing_quantile_equals_kdtree():
    pts = _ellipsoid_with_stray(1500)
    queries = po.spacing_subset(len(pts), 1000, seed=0)  # a subset: queried against every point
    q = po.spacing_quantile(jnp.asarray(pts, jnp.float32), jnp.ones(len(pts), bool), jnp.asarray(queries),
                            jnp.ones(len(queries), bool))
    ref = np.quantile(host_solid.neighbour_distances(pts, 4, samples=1000, seed=0)[:, 3], 0.9)
    dist, _ = cKDTree(pts).query(pts[queries], k=5)
    assert ref == pytest.approx(np.quantile(dist[:, 4], 0.9), rel=1e-12)
    assert float(q) == pytest.approx(ref, rel=1e-5)


@pytest.mark.parametrize("seed", (1.5, True, -1, "a", np.float64(2.0)))
def test_spacing_subset_refuses_a_seed_that_is_not_an_int(seed):
    """A bad seed is refused by name, as at every entry point (1.5 and "a" were NumPy's TypeError,
    -1 its ValueError; True was taken as 1), also where every point is measured (n <= samples)."""
    from jaxpose import InvalidInputError

    for n in (3000, 10):
        with pytest.raises(InvalidInputError, match="^seed must be"):
            po.spacing_subset(n, 1000, seed)
    np.testing.assert_array_equal(po.spacing_subset(3000, 1000, np.int64(3)), po.spacing_subset(3000, 1000, 3))


def test_spacing_quantile_ignores_padding():
    pts = _ellipsoid_with_stray(800)
    padded = np.concatenate([pts, np.repeat(pts[:1], 200, axis=0)])  # copies of a point: 0 distances
    mask = np.arange(len(padded)) < len(pts)
    queries = np.arange(len(padded))
    q = po.spacing_quantile(jnp.asarray(padded, jnp.float32), jnp.asarray(mask), jnp.asarray(queries),
                            jnp.asarray(mask))
    ref = np.quantile(host_solid.neighbour_distances(pts, 4)[:, 3], 0.9)
    assert float(q) == pytest.approx(ref, rel=1e-5)


def test_spacing_quantile_of_a_few_points_ignores_padding():
    """A set of k = 4 points has no 4th other point: padded (as normalize_batch pads a small set
    beside larger ones) it measured the padding's infinite distance, and the pose came out NaN;
    it is the farthest other point, padded or not (scipy's 3rd neighbour)."""
    pts = _ellipsoid_with_stray(800)[:4]
    ref = np.quantile(cKDTree(pts).query(pts, k=4)[0][:, 3], 0.9)
    for rows in (4, 16):
        padded = np.concatenate([pts, np.zeros((rows - 4, 3))])
        mask = np.arange(rows) < 4
        q = po.spacing_quantile(jnp.asarray(padded, jnp.float32), jnp.asarray(mask), jnp.arange(rows),
                                jnp.asarray(mask))
        assert float(q) == pytest.approx(ref, rel=1e-5), rows


def _x64(body):
    """body() with JAX in float64 (restored after)."""
    before = jax.config.jax_enable_x64
    jax.config.update("jax_enable_x64", True)
    try:
        return body()
    finally:
        jax.config.update("jax_enable_x64", before)


def test_nearest_is_top_k_in_float64():
    """The float64 selection (argmin passes) returns lax.top_k's indices, in its order: ties to
    the lower index, +inf padding, negative rounding residues, rows with fewer finite entries than k."""
    def check():
        rng = np.random.default_rng(0)
        d = rng.random((64, 300)) - 0.01
        d[:, ::7] = d[:, 3:4]  # ties
        d[:8] = np.round(d[:8], 1)  # many ties
        d[:, 250:] = np.inf
        d[10, 5:] = np.inf  # 5 finite entries, 8 chosen
        d[11, :] = np.inf
        d = jnp.asarray(d, jnp.float64)
        for k in (1, 4, 8):
            got = jax.jit(po._nearest, static_argnums=1)(d, k)
            ref = jax.lax.top_k(-d, k)[1]
            np.testing.assert_array_equal(np.asarray(got), np.asarray(ref))

    _x64(check)


def test_spacing_quantile_in_float64_takes_no_top_k():
    """float64 selects neighbours without lax.top_k (XLA:CPU sorts each float64 row for it: 2.5 s
    against 0.04 s in float32 for 4096 points); float32 keeps top_k; float64 still measures the
    k-d tree's spacing."""
    pts = _ellipsoid_with_stray(1500)
    queries = po.spacing_subset(len(pts), 1000, seed=0)
    ref = np.quantile(cKDTree(pts).query(pts[queries], k=5)[0][:, 4], 0.9)

    def run(dtype):
        args = (jnp.asarray(pts, dtype), jnp.ones(len(pts), bool), jnp.asarray(queries), jnp.ones(len(queries), bool))
        return str(jax.make_jaxpr(po.spacing_quantile)(*args)), float(po.spacing_quantile(*args))

    text64, q64 = _x64(lambda: run(jnp.float64))
    assert "top_k" not in text64
    assert q64 == pytest.approx(ref, rel=1e-12)
    text32, _ = run(jnp.float32)
    assert "top_k" in text32


def _jax_solid(points, config=CONFIG):
    x = jnp.asarray(points, jnp.float32)
    return jax.jit(po.point_solid, static_argnames="config")(
        x, None, jnp.asarray(po.spacing_subset(len(points), config.spacing_samples)), config=config)


def test_point_solid_equals_the_numpy_solid():
    """The same voxels as jaxpose.occupancy.solid.robust_solid (float64 NumPy), the same components, pitch,
    closing radius; the stray blob dropped in both."""
    pts = _ellipsoid_with_stray()
    ref = host_solid.robust_solid(pts, resolution=CONFIG.resolution, coarse=CONFIG.coarse)
    sol = _jax_solid(pts)
    assert float(sol.pitch) == pytest.approx(ref.pitch, rel=1e-6)
    np.testing.assert_allclose(np.asarray(sol.origin), ref.origin, atol=1e-5 * ref.pitch)
    inside = np.asarray(sol.inside)
    nx, ny, nz = ref.inside.shape
    assert not inside[nx:].any() and not inside[:, ny:].any() and not inside[:, :, nz:].any()
    mismatch = np.sum(inside[:nx, :ny, :nz] != ref.inside)
    assert mismatch <= 1e-3 * ref.inside.sum()  # float32 against float64 voxel assignment
    assert int(sol.components) == ref.components and int(sol.dropped) == ref.dropped
    assert int(sol.radius) == solid_radius(pts, ref.pitch)
    # the blob at x = 2.2 is gone: nothing kept beyond x = 1.3
    x = np.asarray(sol.origin)[0] + float(sol.pitch) * (np.nonzero(inside)[0] + 0.5)
    assert x.max() < 1.3


def solid_radius(points, pitch):
    r4 = host_solid.neighbour_distances(points, 4, samples=host_solid.SPACING_SAMPLES)[:, 3]
    return host_solid.closing_radius(r4, pitch)


def test_point_solid_of_an_open_sheet_has_no_depth():
    """A sheet closes to a layer one voxel thick (as in NumPy): no voxel is deeper than the surface."""
    rng = np.random.default_rng(5)
    m = len(_ellipsoid_with_stray())  # the row count of the test above: its compiled solid is reused
    sheet = np.c_[rng.uniform(-1, 1, (m, 2)), np.zeros(m)]
    sol = _jax_solid(sheet)
    ref = host_solid.robust_solid(sheet, resolution=CONFIG.resolution, coarse=CONFIG.coarse)
    assert not bool(jnp.any(po.erode6(sol.inside))) and not ndimage.binary_erosion(ref.inside).any()
    assert int(jnp.sum(sol.inside)) == pytest.approx(ref.inside.sum(), rel=1e-2)


def test_vmap_equals_single():
    # the size of the tests above: the single solids reuse their compiled program
    a, b = _ellipsoid_with_stray(3000, seed=1), 0.5 * _ellipsoid_with_stray(3000, seed=2)[:, ::-1]
    q = jnp.asarray(po.spacing_subset(3000, CONFIG.spacing_samples))
    x = jnp.asarray(np.stack([a, b]), jnp.float32)
    batched = jax.jit(jax.vmap(lambda p: po.point_solid(p, None, q, CONFIG)))(x)
    for i, p in enumerate((a, b)):
        single = _jax_solid(p)
        assert np.array_equal(np.asarray(batched.inside[i]), np.asarray(single.inside))
        assert float(batched.pitch[i]) == float(single.pitch)
