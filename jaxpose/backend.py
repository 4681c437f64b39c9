"""The array backend of a computation, chosen from its inputs, without importing JAX.

Functions written once for both backends (:mod:`jaxpose.weighted`) take
their namespace from their arguments: concrete NumPy values (and Python numbers, and lists of them) compute in NumPy
on the host; a JAX array or a tracer (under ``jit``, ``vmap``, ``grad``) computes in
``jax.numpy``. JAX is imported only when a JAX value is given (it is then imported already).

Example::

    >>> import jax.numpy as jnp
    >>> array_namespace(np.ones(3), 2.0) is np
    True
    >>> array_namespace([1e4 + 0.1, 0.0, 0.0]) is np   # a list of floats: float64 on the host
    True
    >>> array_namespace(jnp.ones(3)) is jnp
    True
"""
from __future__ import annotations

import numpy as np

__all__ = ["array_namespace"]

_HOST = (np.ndarray, np.generic, bool, int, float)


def array_namespace(*values):
    """``numpy`` when every given value (None skipped) is a NumPy array or scalar, a Python number,
    or a list or tuple of those (nested), else ``jax.numpy``. A list is concrete and holds Python
    floats (float64), so it computes on the host as its NumPy array would: float64 whatever JAX's
    default float (it went to ``jax.numpy``, float32 with x64 off: a [1e4 + 0.1, 0, 0] origin beside
    float64 arrays gave a float32 center 10001.099609); one holding a JAX value goes to JAX."""
    if all(_is_host(value) for value in values):
        return np
    import jax.numpy as jnp  # a JAX value was given: JAX is imported already

    return jnp


def _is_host(value):
    if value is None or isinstance(value, _HOST):
        return True
    return isinstance(value, (list, tuple)) and all(v is not None and _is_host(v) for v in value)
