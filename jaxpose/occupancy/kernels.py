"""Gaussian kernel k(a, b) = exp(-gamma * ||a - b||^2) and blocked products with it."""
from __future__ import annotations

import jax
import jax.numpy as jnp

__all__ = ["gaussian_kernel", "kernel_matvec_blocked", "power_iteration"]


def gaussian_kernel(a, b, gamma):
    """K[i, j] = exp(-gamma ||a_i - b_j||^2). a : (n, 3), b : (m, 3) -> (n, m).

    Distances by ||a||^2 + ||b||^2 - 2 a.b after shifting both by b's mean (a matrix
    product: much faster than differences; the shift keeps the expansion accurate).
    """
    shift = jax.lax.stop_gradient(jnp.mean(b, axis=0))
    a, b = a - shift, b - shift
    d2 = jnp.sum(a * a, axis=-1)[:, None] + jnp.sum(b * b, axis=-1)[None, :] - 2.0 * a @ b.T
    return jnp.exp(-gamma * jnp.maximum(d2, 0.0))


def _pad_rows(x, block):
    n = x.shape[0]
    pad = (-n) % block
    if pad:
        x = jnp.concatenate([x, jnp.broadcast_to(x[-1:], (pad,) + x.shape[1:])], axis=0)
    return x, n


def map_blocks(fn, x, block, count=None):
    """Apply fn to row blocks of x (n, ...) with lax.map; returns the first n rows of the result.

    Memory stays at one block's worth of intermediate values.
    count : optional () int: only the blocks holding rows < count are evaluated (``lax.cond``);
    the others give zeros.
    """
    block = max(1, min(int(block), x.shape[0]))
    xp, n = _pad_rows(x, block)
    xb = xp.reshape((-1, block) + x.shape[1:])
    if count is None:
        out = jax.lax.map(fn, xb)
    else:
        shapes = jax.eval_shape(fn, xb[0])
        zeros = lambda _: jax.tree_util.tree_map(lambda s: jnp.zeros(s.shape, s.dtype), shapes)
        starts = jnp.arange(xb.shape[0]) * block
        out = jax.lax.map(lambda args: jax.lax.cond(args[1] < count, fn, zeros, args[0]), (xb, starts))
    return jax.tree_util.tree_map(lambda o: o.reshape((-1,) + o.shape[2:])[:n], out)


def kernel_matvec_blocked(points, v, gamma, block=1024):
    """(K v) without materialising K. points : (m, 3), v : (m,) -> (m,)."""
    return map_blocks(lambda rows: gaussian_kernel(rows, points, gamma) @ v, points, block)


def power_iteration(matvec, m, dtype, iterations=30, start=None):
    """Largest eigenvalue of a symmetric PSD operator (Rayleigh quotient after `iterations`).

    Starts from ``start`` (m,), by default the ones vector, which overlaps the Perron vector of
    a positive kernel.
    """
    v0 = jnp.ones((m,), dtype) if start is None else jnp.asarray(start, dtype)
    v0 = v0 / jnp.maximum(jnp.linalg.norm(v0), jnp.finfo(dtype).tiny)

    def body(_, v):
        w = matvec(v)
        return w / jnp.maximum(jnp.linalg.norm(w), jnp.finfo(dtype).tiny)

    v = jax.lax.fori_loop(0, iterations, body, v0)
    return jnp.vdot(v, matvec(v))
