"""normalize_batch: equals normalize per object, compiles once, rejects bad input."""
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxpose
from jaxpose.pose import pose as pose_module
from jaxpose._validate import InvalidInputError

from conftest import box_surface, clusters, sphere_with_arm

# small grid: equality per object does not depend on the resolution, only the runtime does
OPTS = dict(resolution=16, refine=2, band=512)


def _sets():
    """Four sets of different sizes (padded in a batch), scales and offsets. The sizes are
    incidental within one bucket (:func:`jaxpose.pose.sizes.bucket`: 193..224 points, 224 rows):
    the per-object ``normalize`` calls, the oracle, share one compiled program per option set
    (padding amounts that differ between calls: test_pad_to_does_not_change_results)."""
    return [
        sphere_with_arm(200, seed=1),
        box_surface(209, seed=2) + np.array([3.0, -1.0, 0.5]),  # offset: pre-scaling must be per object
        2.5 * clusters(217, seed=3),  # another size and scale
        sphere_with_arm(224, seed=4) * 0.1,
    ]


@pytest.fixture(scope="module")
def batch_and_single():
    sets = _sets()
    batch = jaxpose.normalize_batch(sets, method="ocsvm", gamma=47.0, nu=0.5, **OPTS)
    single = [jaxpose.normalize(p, method="ocsvm", gamma=47.0, nu=0.5, **OPTS) for p in sets]
    return sets, batch, single


def test_batch_shapes(batch_and_single):
    sets, batch, _ = batch_and_single
    n = len(sets)
    assert batch.center.shape == (n, 3)
    assert batch.scale.shape == (n,)
    assert batch.converged.shape == (n,) and bool(jnp.all(batch.converged))
    assert bool(jnp.all(batch.valid))


def test_batch_equals_normalize_per_object(batch_and_single):
    sets, batch, single = batch_and_single
    for i, s in enumerate(single):
        scale = float(s.scale)
        assert scale > 0
        np.testing.assert_allclose(np.asarray(batch.center[i]), np.asarray(s.center), atol=1e-3 * scale, rtol=0)
        assert abs(float(batch.scale[i]) - scale) <= 1e-3 * scale
        assert bool(batch.converged[i]) == bool(s.converged)


def test_batch_order_does_not_matter(batch_and_single):
    sets, batch, _ = batch_and_single
    order = [2, 0, 3, 1]
    again = jaxpose.normalize_batch([sets[i] for i in order], method="ocsvm", gamma=47.0, nu=0.5, **OPTS)
    for j, i in enumerate(order):
        np.testing.assert_allclose(np.asarray(again.center[j]), np.asarray(batch.center[i]),
                                   atol=1e-4 * float(batch.scale[i]), rtol=0)


PADDED = dict(OPTS, strategy="vmap")


@pytest.fixture(scope="module")
def padded_batch():
    """The sets padded to 260 rows (a padded size no other test uses: a fresh cache entry), with
    the number of compiled batch functions before and after the call. One program for
    test_one_compilation_for_different_sizes, test_pad_to_does_not_change_results and
    test_strategies_agree_with_normalize[vmap]: the vmap strategy (incidental to the padding; the
    map strategy's unpadded program is the module fixture's), so the vmap test compiles nothing."""
    sets = _sets()
    before = pose_module._batched._cache_size()
    padded = jaxpose.normalize_batch(sets, method="ocsvm", gamma=47.0, nu=0.5, pad_to=260, **PADDED)
    return sets, padded, before, pose_module._batched._cache_size()


def test_one_compilation_for_different_sizes(padded_batch):
    """Different point counts share one compiled function (same padded size and batch)."""
    sets, _, before, after_first = padded_batch
    assert after_first == before + 1
    # other sizes (all <= pad_to), other values of gamma and nu: no new compilation
    other = [sphere_with_arm(120 + 17 * i, seed=10 + i) for i in range(4)]
    jaxpose.normalize_batch(other, method="ocsvm", gamma=30.0, nu=0.3, pad_to=260, **PADDED)
    jaxpose.normalize_batch(sets[::-1], method="ocsvm", gamma=47.0, nu=0.5, pad_to=260, **PADDED)
    assert pose_module._batched._cache_size() == after_first


@pytest.mark.parametrize("strategy", ["vmap", "map"])
def test_strategies_agree_with_normalize(batch_and_single, strategy):
    """lax.map and vmap batches both equal per-object normalize (up to solver tolerance)."""
    sets, _, single = batch_and_single
    # vmap padded to 260 rows (incidental): the program of the padded_batch fixture
    pad = {"pad_to": 260} if strategy == "vmap" else {}
    batch = jaxpose.normalize_batch(sets, method="ocsvm", gamma=47.0, nu=0.5, strategy=strategy, **pad, **OPTS)
    for i, s in enumerate(single):
        np.testing.assert_allclose(np.asarray(batch.center[i]), np.asarray(s.center), atol=1e-3 * float(s.scale), rtol=0)
        assert abs(float(batch.scale[i]) - float(s.scale)) <= 1e-3 * float(s.scale)


@pytest.mark.parametrize("strategy", ["map", "vmap"])
def test_smo_solver_in_batches(batch_and_single, strategy):
    """solver="smo" through padding + masks, both strategies: per-object normalize with the same
    solver, and the default solver's pose within what tol 1e-4 allows."""
    sets, batch, _ = batch_and_single
    opts = {**OPTS, "solver": "smo", "tol": 1e-4}
    b = jaxpose.normalize_batch(sets, method="ocsvm", gamma=47.0, nu=0.5, strategy=strategy, **opts)
    assert bool(np.all(np.asarray(b.converged)))
    for i, p in enumerate(sets):
        s = jaxpose.normalize(p, method="ocsvm", gamma=47.0, nu=0.5, **opts)
        np.testing.assert_allclose(np.asarray(b.center[i]), np.asarray(s.center), atol=1e-3 * float(s.scale), rtol=0)
        np.testing.assert_allclose(np.asarray(b.center[i]), np.asarray(batch.center[i]), atol=2e-3 * float(s.scale), rtol=0)
        assert abs(float(b.scale[i]) - float(batch.scale[i])) <= 2e-3 * float(s.scale)


def test_pad_to_does_not_change_results(batch_and_single, padded_batch):
    _, batch, _ = batch_and_single
    _, padded, _, _ = padded_batch
    np.testing.assert_allclose(np.asarray(padded.center), np.asarray(batch.center),
                               atol=1e-3 * float(jnp.min(batch.scale)), rtol=0)
    np.testing.assert_allclose(np.asarray(padded.scale), np.asarray(batch.scale), rtol=1e-3)


def test_single_object_batch():
    p = _sets()[0]  # its single call: the program the module fixture compiled
    batch = jaxpose.normalize_batch([p], method="ocsvm", **OPTS)
    single = jaxpose.normalize(p, method="ocsvm", **OPTS)
    assert batch.center.shape == (1, 3)
    np.testing.assert_allclose(np.asarray(batch.center[0]), np.asarray(single.center), atol=1e-3 * float(single.scale))


@pytest.mark.parametrize(
    "bad",
    [
        [],  # empty list
        [np.zeros((50, 2))],  # wrong number of coordinates
        [sphere_with_arm(100), np.ones((80, 4))],  # mismatched shapes
        [sphere_with_arm(100), np.ones(30)],  # 1-D
        [sphere_with_arm(100), np.full((60, 3), np.nan)],  # non-finite
        [sphere_with_arm(100), np.ones((60, 3))],  # all identical
    ],
)
def test_bad_input_is_rejected(bad):
    with pytest.raises(InvalidInputError):
        jaxpose.normalize_batch(bad, method="ocsvm", **OPTS)


def test_bad_options_are_rejected():
    sets = [sphere_with_arm(100), sphere_with_arm(120, seed=1)]
    with pytest.raises(InvalidInputError):
        jaxpose.normalize_batch(sets, method="ocsvm", pad_to=110)  # smaller than the largest set
    with pytest.raises(InvalidInputError):
        jaxpose.normalize_batch(sets, method="ocsvm", not_an_option=3)
    with pytest.raises(InvalidInputError):
        jaxpose.normalize_batch(sets, method="ocsvm", gamma=-1.0)
    with pytest.raises(InvalidInputError):
        jaxpose.normalize_batch(sets, method="ocsvm", nu=1.5)
    with pytest.raises(InvalidInputError):
        jaxpose.normalize_batch(sets, method="ocsvm", strategy="pmap")
    with pytest.raises(InvalidInputError, match="solver"):
        jaxpose.normalize_batch(sets, method="ocsvm", solver="newton")


@pytest.mark.parametrize("chains", [1, 2, 3, 7])
def test_chained_map_equals_lax_map(chains):
    """The batch cut into independent lax.map chains: the same values in the same order (a pytree
    with a None leaf, as Pose has), also with more chains than objects."""
    xs = (jnp.arange(5.0), jnp.arange(10.0).reshape(5, 2))
    fn = lambda a: {"s": a[0] * 2 + a[1].sum(), "none": None, "v": a[1][::-1]}
    got = jax.jit(lambda x: pose_module.chained_map(fn, x, chains))(xs)
    ref = jax.lax.map(fn, xs)
    assert got["none"] is None
    assert np.array_equal(got["s"], ref["s"]) and np.array_equal(got["v"], ref["v"])


def test_robust_map_in_chains_equals_one_chain(monkeypatch):
    """normalize_batch's map strategy on CPU runs one chain per core: forced to 1 and to 2 chains,
    the robust poses are identical. Two chains over three sets are uneven (two objects, then one):
    both a chain that loops and one of a single object are checked (each chain is one more copy
    of the pipeline to compile: three chains cost a copy more and checked one-object chains only)."""
    # three clouds of 897..1024 points (1024 rows) at resolution 48 / coarse 24: the two-chain
    # program is test_normalize_methods.py's three-cloud map (the sizes and grid are incidental)
    sets = [sphere_with_arm(1024, seed=1), box_surface(960, seed=2) + np.array([3.0, -1.0, 0.5]),
            0.1 * sphere_with_arm(1000, seed=4)]
    monkeypatch.setattr(pose_module, "_cores", lambda: 1)
    one = jaxpose.normalize_batch(sets, strategy="map", resolution=48, coarse=24)
    monkeypatch.setattr(pose_module, "_cores", lambda: 2)
    two = jaxpose.normalize_batch(sets, strategy="map", resolution=48, coarse=24)
    assert np.array_equal(one.center, two.center) and np.array_equal(one.scale, two.scale)
    assert np.array_equal(np.asarray(one.status), np.asarray(two.status))


@pytest.mark.parametrize("cores, batch, expected", [(1, 4, 1), (3, 4, 3), (64, 4, 4), (64, 9, pose_module.MAX_CHAINS),
                                                   (2, 1, 1)])
def test_map_chains_are_bounded_by_cores_batch_and_max_chains(monkeypatch, cores, batch, expected):
    """Each chain is one more copy of the pipeline to compile: at most MAX_CHAINS, whatever the cores."""
    seen = []

    class Stop(Exception):
        pass

    def record(*args, chains, **kwargs):
        seen.append(chains)
        raise Stop

    monkeypatch.setattr(pose_module, "_cores", lambda: cores)
    monkeypatch.setattr(pose_module, "_robust_batched", record)
    sets = [sphere_with_arm(100, seed=i) for i in range(batch)]
    with pytest.raises(Stop):
        jaxpose.normalize_batch(sets, strategy="map")
    expected = expected if jax.default_backend() == "cpu" else 1
    assert seen == [min(expected, pose_module.MAX_CHAINS)]
