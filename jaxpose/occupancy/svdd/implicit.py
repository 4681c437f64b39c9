"""The implicit derivative of the SVDD solution through its KKT system on the active set.

With the free points F (0 < a < C) and the bounded points B (a = C), the solution satisfies
2 K_FF a_F + 2 K_FB a_B = mu 1 and 1^T a = 1 (Chapelle et al. 2002; Keerthi et al. 2006), so a
perturbation (dK, dC) moves it by

    [2 K_FF  -1] [da_F]   [-2 (dK a)_F - 2 K_FB da_B]
    [1^T      0] [dmu ] = [-1^T da_B               ],   da_B = dC on B, da = 0 off the support.

It is solved at full size (free rows kept, the others pinned to 0) with a Tikhonov ridge of
10 eps max_i sum_j K_ij on the free block: K_FF is numerically singular on dense samples (its
condition number reaches ~1e13), and the directions the ridge damps barely move f. This is the
exact one-sided derivative of the computed solution: the solution is piecewise smooth in
(gamma, nu), with a kink each time a point changes between zero, free and bounded.
"""
from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp

from ..kernels import gaussian_kernel

__all__ = ["implicit_alpha"]


@jax.custom_jvp
def implicit_alpha(alpha, points, gamma, caps, mask):
    """Identity on a solution alpha (m,); its JVP is the KKT implicit derivative (module docs)."""
    return alpha


@partial(implicit_alpha.defjvp, symbolic_zeros=True)
def _implicit_alpha_jvp(primals, tangents):
    from jax.custom_derivatives import SymbolicZero  # tangents arrive with symbolic zeros

    alpha, points, gamma, caps, mask = primals
    _, dpoints, dgamma, dcaps, _ = tangents
    alpha = jax.lax.stop_gradient(alpha)
    dtype = alpha.dtype
    m = alpha.shape[0]
    zero = lambda t: isinstance(t, SymbolicZero)
    # K and dK a, linear in (dpoints, dgamma); the points' tangent only when they are perturbed
    # (a zero (m, 3) tangent would cost a second (m, m) kernel tangent per column).
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
    ridge = 10.0 * jnp.finfo(dtype).eps * jnp.max(jnp.sum(K, axis=1))
    A = 2.0 * K * fm[:, None] * fm[None, :] + jnp.diag(1.0 - fm) + ridge * jnp.diag(fm)
    M = jnp.zeros((m + 1, m + 1), dtype)
    M = M.at[:m, :m].set(A).at[:m, m].set(fm).at[m, :m].set(fm)
    M = jnp.where(jnp.any(free), M, jnp.eye(m + 1, dtype=dtype))  # no free point: M would be singular
    rhs_top = -fm * (2.0 * dKa + 2.0 * (K @ da_b))
    rhs = jnp.concatenate([rhs_top, -jnp.sum(da_b)[None]])
    da_f = jnp.linalg.solve(M, rhs)[:m]
    dalpha = fm * da_f + da_b
    return alpha, dalpha
