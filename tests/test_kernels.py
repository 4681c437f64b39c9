"""Gaussian kernel, blocked products and the power iteration against direct NumPy."""
import jax.numpy as jnp
import numpy as np

from jaxpose.occupancy.kernels import gaussian_kernel, kernel_matvec_blocked, map_blocks, power_iteration


def test_kernel_and_blocked_products_match_numpy(x64):
    rng = np.random.default_rng(0)
    a, b, v = rng.normal(size=(37, 3)) + 50.0, rng.normal(size=(53, 3)) + 50.0, rng.normal(size=53)
    direct = np.exp(-0.7 * ((a[:, None] - b[None]) ** 2).sum(-1))
    np.testing.assert_allclose(np.asarray(gaussian_kernel(jnp.asarray(a), jnp.asarray(b), 0.7)), direct, atol=1e-13)
    K = np.exp(-0.7 * ((b[:, None] - b[None]) ** 2).sum(-1))
    for block in (1, 7, 53, 100):
        np.testing.assert_allclose(np.asarray(kernel_matvec_blocked(jnp.asarray(b), jnp.asarray(v), 0.7, block)),
                                   K @ v, atol=1e-12)
    lam = float(power_iteration(lambda x: jnp.asarray(K) @ x, 53, jnp.float64, iterations=200))
    assert abs(lam - np.linalg.eigvalsh(K)[-1]) <= 1e-8 * lam


def test_map_blocks_count_skips_trailing_blocks(x64):
    x = jnp.arange(10.0)[:, None]
    out = map_blocks(lambda xb: 2.0 * xb, x, 3, count=jnp.asarray(4))
    np.testing.assert_array_equal(np.asarray(out)[:, 0], [0, 2, 4, 6, 8, 10, 0, 0, 0, 0])
