"""The array backend of a computation, chosen from its inputs, without importing JAX.

Functions written once for both backends (:mod:`jaxpose.weighted`) take
their namespace from their arguments: concrete NumPy values (and Python numbers) compute in NumPy
on the host; a JAX array or a tracer (under ``jit``, ``vmap``, ``grad``) computes in
``jax.numpy``. JAX is imported only when a JAX value is given (it is then imported already).

Example::

    >>> import jax.numpy as jnp
    >>> array_namespace(np.ones(3), 2.0) is np
    True
    >>> array_namespace(jnp.ones(3)) is jnp
    True
"""
from __future__ import annotations

import numpy as np

__all__ = ["array_namespace"]

_HOST = (np.ndarray, np.generic, bool, int, float)


def array_namespace(*values):
    """``numpy`` when every given value (None skipped) is a NumPy array or scalar or a Python
    number, else ``jax.numpy``."""
    if all(value is None or isinstance(value, _HOST) for value in values):
        return np
    import jax.numpy as jnp  # a JAX value was given: JAX is imported already

    return jnp
