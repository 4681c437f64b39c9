"""The JAX Euclidean distance transform against scipy.ndimage.distance_transform_edt (exact)."""
from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy import ndimage

from jaxpose.depth import MAX_SQUARED, depth_weights, distance, from_bucket, host_distance, squared_distance, to_bucket
from jaxpose.errors import InvalidInputError

# a few shapes (each compiles once): 1-D to 3-D, anisotropic, unit axes
SHAPES = [(17,), (6, 11), (9, 4, 7), (1, 12, 5), (23, 3, 1), (16, 16, 16)]


def scipy_squared(inside):
    """scipy's squared distances as exact integers (its float64 squares of small integers are exact)."""
    d = ndimage.distance_transform_edt(inside)
    d2 = np.rint(d * d).astype(np.int64)
    assert np.array_equal(np.sqrt(d2.astype(np.float64)), d)  # scipy's distances are square roots of integers
    return d2


@settings(max_examples=40, deadline=None, derandomize=True, suppress_health_check=list(HealthCheck))
@given(shape=st.sampled_from(SHAPES), density=st.sampled_from([0.02, 0.3, 0.7, 0.95, 0.995]),
       seed=st.integers(0, 2**31 - 1))
def test_random_grids_equal_scipy_exactly(shape, density, seed):
    inside = np.random.default_rng(seed).random(shape) < density
    got = np.asarray(squared_distance(inside))
    assert got.dtype == np.int32
    np.testing.assert_array_equal(got, scipy_squared(inside))
    np.testing.assert_array_equal(host_distance(inside), ndimage.distance_transform_edt(inside))


@pytest.mark.parametrize("shape", [(40, 3, 9), (2, 31, 5), (8, 8, 50)])
def test_anisotropic_blobs_equal_scipy(shape):
    # a deep blob (long lines with no False cell along several axes) with a few holes
    rng = np.random.default_rng(1)
    inside = np.ones(shape, bool)
    inside[tuple(rng.integers(0, s, 4) for s in shape)] = False
    inside[0] = False  # one face outside, the rest of the border is not
    np.testing.assert_array_equal(np.asarray(squared_distance(inside)), scipy_squared(inside))


@pytest.mark.parametrize("shape, extent", [((16, 16, 16), (9, 4, 7)), ((16, 16, 16), (16, 3, 11)), ((6, 11), (1, 5))])
def test_extent_pads_without_changing_the_grid(shape, extent):
    rng = np.random.default_rng(sum(extent))
    padded = rng.random(shape) < 0.5  # padding of either value: neither inside nor outside
    grid = tuple(slice(0, e) for e in extent)
    padded[grid] = rng.random(extent) < 0.95
    got = np.asarray(squared_distance(padded, np.array(extent)))
    np.testing.assert_array_equal(got[grid], scipy_squared(padded[grid]))
    rest = np.ones(shape, bool)
    rest[grid] = False
    assert not got[rest].any()
    padded[grid] = True  # no False cell within the extent: scipy's full-grid convention
    np.testing.assert_array_equal(np.asarray(squared_distance(padded, np.array(extent)))[grid],
                                  scipy_squared(padded[grid]))


def test_lines_without_false_cells_take_distances_from_other_lines():
    inside = np.ones((7, 9, 5), bool)
    inside[3, 4, 2] = False  # the only outside cell: every other axis-0 line has none
    d2 = np.asarray(squared_distance(inside))
    idx = np.indices(inside.shape)
    expected = (idx[0] - 3) ** 2 + (idx[1] - 4) ** 2 + (idx[2] - 2) ** 2
    np.testing.assert_array_equal(d2, expected)  # closed form, independent of scipy
    np.testing.assert_array_equal(d2, scipy_squared(inside))


@pytest.mark.parametrize("shape", [(5,), (3, 4), (2, 3, 4)])
def test_empty_and_full_grids(shape):
    empty = np.zeros(shape, bool)
    np.testing.assert_array_equal(np.asarray(squared_distance(empty)), 0)
    full = np.ones(shape, bool)  # scipy's convention: distance to the virtual cell (-1, 0, ..., 0)
    idx = np.indices(shape)
    expected = (idx[0] + 1) ** 2 + sum(i**2 for i in idx[1:])
    np.testing.assert_array_equal(np.asarray(squared_distance(full)), expected)
    np.testing.assert_array_equal(np.asarray(squared_distance(full)), scipy_squared(full))


def test_zero_size_and_scalar_grids():
    assert squared_distance(np.zeros((0, 3), bool)).shape == (0, 3)
    with pytest.raises(InvalidInputError, match="at least one axis"):
        squared_distance(np.array(True))


def test_too_large_grid_is_refused_before_allocating():
    big = jax.ShapeDtypeStruct((30_000, 30_000), jnp.bool_)
    assert 2 * 30_001**2 >= MAX_SQUARED
    with pytest.raises(InvalidInputError, match="too large"):
        jax.eval_shape(squared_distance, big)


def test_float32_distances_are_scipy_rounded_once():
    inside = np.random.default_rng(2).random((16, 16, 16)) < 0.97
    d = distance(inside)
    assert d.dtype == jnp.float32
    np.testing.assert_array_equal(np.asarray(d), ndimage.distance_transform_edt(inside).astype(np.float32))


def test_float64_distances_equal_scipy(x64):
    inside = np.random.default_rng(3).random((9, 4, 7)) < 0.9
    d = distance(inside)
    assert d.dtype == jnp.float64
    np.testing.assert_array_equal(np.asarray(d), ndimage.distance_transform_edt(inside))
    assert distance(inside, dtype=jnp.float32).dtype == jnp.float32


def test_jit_and_vmap_agree_with_single_calls():
    rng = np.random.default_rng(4)
    batch = rng.random((5, 9, 4, 7)) < np.array([0.1, 0.6, 0.9, 0.99, 1.0])[:, None, None, None]
    batch[3] = True
    batch[3, 4, 2, 3] = False  # deep: the batched loop runs longer for this one than for the others
    got = jax.jit(jax.vmap(squared_distance))(jnp.asarray(batch))
    for b in range(len(batch)):
        np.testing.assert_array_equal(np.asarray(got[b]), scipy_squared(batch[b]))
    inner = jax.jit(lambda g: jnp.sum(distance(g)))(batch[0])  # called inside another jitted function
    np.testing.assert_allclose(float(inner), ndimage.distance_transform_edt(batch[0]).sum(), rtol=1e-6)


# --------------------------------------------------------------------------- weights, buckets
def scipy_weights(inside, power, bias):
    d = np.maximum(ndimage.distance_transform_edt(inside) - bias, 0.0)
    top = d[inside].max() if inside.any() else 0.0
    w = (d / top) ** power if top > 0 else np.ones(inside.shape)
    return np.where(inside, w, 0.0)


@pytest.mark.parametrize("power, bias", [(4.0, 0.5), (1.5, 1.0), (0.0, 0.5), (2.0, 0.0)])
def test_depth_weights_match_the_scipy_formula(x64, power, bias):
    inside = np.zeros((12, 16, 10), bool)
    inside[2:10, 3:14, 2:9] = True
    inside[5, 6, 4] = False  # a cavity
    padded, extent, axes = to_bucket(inside)
    assert padded.shape == (32, 32, 16) and tuple(extent) == (10, 12, 16) and tuple(axes) == (2, 0, 1)
    w = np.asarray(depth_weights(padded, power, bias, extent))
    np.testing.assert_allclose(from_bucket(w, axes, extent), scipy_weights(inside, power, bias), rtol=1e-12, atol=0)
    assert not w[10:].any() and not w[:, 12:].any()
    if power == 0.0:  # 0^0 = 1: the plain solid, outer voxels included
        np.testing.assert_array_equal(from_bucket(w, axes, extent), inside.astype(float))


def test_depth_weights_of_a_solid_no_deeper_than_the_bias_are_uniform():
    inside = np.zeros((5, 5, 5), bool)
    inside[2, 2, 2] = True  # distance 1, depth 1 - 1 = 0 everywhere
    np.testing.assert_array_equal(np.asarray(depth_weights(inside, 4.0, 1.0)), inside.astype(np.float32))


def test_depth_weights_gradient_in_power(x64):
    inside = np.zeros((9, 10, 11), bool)
    inside[1:8, 2:9, 1:10] = True
    grad = jax.grad(lambda p: jnp.sum(depth_weights(inside, p, 0.5) * jnp.arange(990.0).reshape(9, 10, 11)))
    f = lambda p: float(jnp.sum(depth_weights(inside, p, 0.5) * jnp.arange(990.0).reshape(9, 10, 11)))
    for p in (4.0, 0.5):
        g = float(grad(p))
        assert np.isfinite(g)
        assert g == pytest.approx((f(p * 1.01) - f(p * 0.99)) / (0.02 * p), rel=1e-3)


def test_host_distance_pads_to_a_bucket_and_equals_scipy():
    inside = np.random.default_rng(5).random((19, 7, 33)) < 0.9
    np.testing.assert_array_equal(host_distance(inside), ndimage.distance_transform_edt(inside))
    padded, extent, axes = to_bucket(inside, 8, 16)
    assert padded.shape == (8, 24, 48) and padded.dtype == bool and tuple(axes) == (1, 0, 2)
    assert not padded[7:].any() and not padded[:, 19:].any() and not padded[:, :, 33:].any()
    np.testing.assert_array_equal(from_bucket(padded, axes, extent), inside)
