"""Reverse mode in a few scalar hyperparameters, computed by forward mode.

The pose depends on two scalars (gamma, nu) through a pipeline whose reverse mode is
expensive: JAX's transpose of the grid evaluation stores or replays a (cells x points)
kernel matrix per block, while forward mode carries the tangents along with the values. With
k <= 2 inputs, the Jacobian's columns by forward mode are cheaper than one reverse pass.

``hyper_jvp(fn, hyper)`` returns a function with the same values and the same derivatives
as ``fn`` (a custom_jvp with symbolic zeros). When only arguments listed in ``hyper`` are
perturbed (the usual case: jax.grad / jacfwd / jacrev in gamma and nu), its JVP rule
computes the Jacobian columns of the perturbed ones with ``jax.jvp`` from the primal
values alone (vmapped over the columns; the primal is computed once) and returns
J @ dtheta. The rule is linear in the tangents only through that small product, so
``jax.grad`` keeps J as a residual and transposes a matrix-vector product: reverse mode
costs what forward mode does. When any other argument is perturbed (gradients with respect
to the points), the rule is the plain ``jax.jvp`` of ``fn``, exactly as without the wrapper.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from jax.custom_derivatives import SymbolicZero

__all__ = ["hyper_jvp", "is_zero", "instantiate"]


def is_zero(t):
    """Whether a custom-JVP tangent is a symbolic zero."""
    return isinstance(t, SymbolicZero)


def instantiate(t):
    """A custom-JVP tangent as an array (zeros for a symbolic zero; float0 stays float0)."""
    if not is_zero(t):
        return t
    if t.dtype == jax.dtypes.float0:
        return np.zeros(t.shape, jax.dtypes.float0)
    return jnp.zeros(t.shape, t.dtype)


def hyper_jvp(fn, hyper):
    """``fn(*args) -> pytree`` wrapped so that derivatives in the scalar arguments ``hyper``
    (a tuple of positions) come from forward-mode columns (module docs). Same values,
    same derivatives; other arguments are differentiated as by ``fn`` itself."""
    hyper = tuple(hyper)

    @jax.custom_jvp
    def wrapped(*args):
        return fn(*args)

    def rule(primals, tangents):
        others = [t for i, a in enumerate(tangents) if i not in hyper
                  for t in jax.tree_util.tree_leaves(a, is_leaf=is_zero)]
        if not all(is_zero(t) for t in others):  # e.g. d/dpoints: the plain forward mode of fn
            tangents = jax.tree_util.tree_map(instantiate, tangents, is_leaf=is_zero)
            return jax.jvp(fn, primals, tangents)
        active = [i for i in hyper if not is_zero(tangents[i])]
        if not active:  # nothing perturbed (JAX normally skips the rule then)
            tangents = jax.tree_util.tree_map(instantiate, tangents, is_leaf=is_zero)
            return jax.jvp(fn, primals, tangents)
        hp = [jnp.asarray(primals[i]) for i in active]

        def f_h(*h):
            args = list(primals)
            for i, v in zip(active, h):
                args[i] = v
            return fn(*args)

        def column(e):  # jvp along the basis vector e of the active hyperparameters
            return jax.jvp(f_h, tuple(hp), tuple(e[j].astype(hp[j].dtype) for j in range(len(hp))))

        out, cols = jax.vmap(column, out_axes=(None, 0))(jnp.eye(len(hp)))
        dtheta = [tangents[i] for i in active]

        def combine(o, c):
            if c.dtype == jax.dtypes.float0:
                return np.zeros(np.shape(o), jax.dtypes.float0)
            return sum(c[k] * jnp.asarray(dtheta[k]).astype(c.dtype) for k in range(len(dtheta)))

        return out, jax.tree_util.tree_map(combine, out, cols)

    wrapped.defjvp(rule, symbolic_zeros=True)
    return wrapped
