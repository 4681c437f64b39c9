"""The SVDD problem: the fitted model, its box constraint, stopping rule, offset and decision function.

Dual (eq. 2 of the paper) with a Gaussian kernel, so that k(x, x) = 1:

    min_a  a^T K a   s.t.  0 <= a_i <= C = 1 / (nu m),  sum a = 1.

With the free support vectors F = {0 < a_i < C}, the KKT conditions give 2 (K a)_i = mu on F and

    f(x) = R^2 - ||Phi(x) - c||^2 = 2 k(x)^T a - mu,   R^2 = 1 - mu + a^T K a   (eq. 3),

positive inside the region.

Mapping to scikit-learn / libsvm (``OneClassSVM(kernel="rbf", gamma, nu)``): libsvm solves
min 1/2 b^T K b, 0 <= b_i <= 1, sum b = nu m, so b = nu m a; ``dual_coef_[0]`` holds b at
``support_``; libsvm's rho = (K b)_i on free points = nu m mu / 2 = ``offset_``; and its
``decision_function(x)`` = k(x)^T b - rho = (nu m / 2) f(x).
"""
from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ... import _validate
from ...config import BLOCK
from ..kernels import gaussian_kernel, kernel_matvec_blocked, map_blocks

__all__ = ["SVDD", "parameters_in_range", "check_svdd", "upper_bound", "caps", "kernel_ops", "kkt_violation", "offset", "decision_function",
           "decision_value_and_grad", "DENSE_LIMIT"]

DENSE_LIMIT = 12_000  # kernel="auto": above this many points K is never stored (memory O(m * block))


def parameters_in_range(gamma, nu):
    """() bool (batched: the parameters' shape), traced: gamma finite and > 0, nu in [0, 1], the
    concrete values' rule (:func:`jaxpose._validate.check_gamma`, ``check_nu``). A traced value
    cannot be refused; :func:`jaxpose.occupancy.svdd.solve_svdd` reports one out of range as
    ``converged=False`` (so do :func:`jaxpose.occupancy.svdd.fit_svdd` and the OCSVM pose's
    ``converged``, which it computes) and :func:`jaxpose.normalize` as ``Status.BAD_PARAMETERS``."""
    g, n = jnp.asarray(gamma), jnp.asarray(nu)
    return jnp.isfinite(g) & (g > 0) & jnp.isfinite(n) & (n >= 0) & (n <= 1)


class SVDD(NamedTuple):
    """A fitted SVDD; a pytree (jit and vmap friendly).

    Attributes:
      points: (m, 3) training points, in the units given.
      alpha: (m,) dual solution, sum 1, 0 <= alpha <= cap.
      gamma: () kernel parameter, 1 / units^2.
      cap: () the upper bound C = min(1, 1 / (nu m)).
      offset: () mu, so that f(x) = 2 k(x)^T alpha - mu.
      objective: () alpha^T K alpha.
      iterations: () solver iterations (pair updates plus gradient steps).
      kkt_violation: () relative KKT violation at the end (:func:`kkt_violation`).
      converged: () bool, kkt_violation <= tol.
      mask: (m,) bool, the points that take part (padding in batches is False).

    Example::

        svdd = jaxpose.fit_svdd(points, gamma=47.0, nu=0.5)
        float(svdd.alpha.sum()), int(svdd.support.sum())   # 1.0, the number of support vectors
    """

    points: jax.Array
    alpha: jax.Array
    gamma: jax.Array
    cap: jax.Array
    offset: jax.Array
    objective: jax.Array
    iterations: jax.Array
    kkt_violation: jax.Array
    converged: jax.Array
    mask: jax.Array

    @property
    def radius2(self):
        """R^2 of the feature-space ball (eq. 1)."""
        return 1.0 - self.offset + self.objective

    @property
    def support(self):
        """(m,) bool, the support vectors (alpha > 0)."""
        return self.alpha > 0


def check_svdd(svdd, use: str):
    """``svdd`` as one fitted :class:`SVDD` (points (m, 3), alpha (m,)); InvalidInputError otherwise,
    a batch of models (``jax.vmap(fit_svdd)``'s) pointed to ``use``, the call that maps over it."""
    if not isinstance(svdd, SVDD):
        raise _validate.InvalidInputError(f"svdd must be an SVDD from fit_svdd, got {type(svdd).__name__}")
    shape = tuple(jnp.shape(svdd.points))
    if len(shape) != 2 or shape[1] != 3:
        batch = (f": a batch of {shape[0]} models (jax.vmap(fit_svdd)'s)? map over it too, {use}"
                 if len(shape) == 3 else "")
        raise _validate.InvalidInputError(f"svdd.points must have shape (m, 3), got {shape}{batch}")
    if tuple(jnp.shape(svdd.alpha)) != shape[:1]:  # (its message named the points, of the right shape)
        raise _validate.InvalidInputError(f"svdd.alpha must have shape {shape[:1]}, one weight per point of svdd.points, "
                                          f"got {tuple(jnp.shape(svdd.alpha))}")
    return svdd


def upper_bound(nu, m):
    """C = 1 / (nu m), capped at 1 (nu = 0: no upper bound); safe to differentiate. () float."""
    nm = _validate.jax_value(nu) * _validate.jax_value(m)  # (longdouble: float64)
    return jnp.where(nm > 1.0, 1.0 / jnp.where(nm > 1.0, nm, 1.0), 1.0)


def caps(nu, mask):
    """Per-point upper bounds (m,): C on the points that take part, 0 on padding."""
    m_valid = jnp.sum(mask)
    return jnp.where(mask, upper_bound(nu, m_valid), 0.0)


def kernel_ops(points, gamma, kernel, block=BLOCK):
    """(v -> K v, i -> K[i]) with K stored (dense) or computed in blocks and per column.

    kernel: "dense", "blocked" or "auto" (dense up to ``DENSE_LIMIT`` points).
    """
    m = points.shape[0]
    dense = kernel == "dense" or (kernel == "auto" and m <= DENSE_LIMIT)
    if dense:
        K = gaussian_kernel(points, points, gamma)
        return (lambda v: K @ v), (lambda i: K[i])
    return ((lambda v: kernel_matvec_blocked(points, v, gamma, block)),
            (lambda i: gaussian_kernel(points[i][None], points, gamma)[0]))


def kkt_violation(alpha, Ka, caps, mask):
    """The stopping rule: libsvm's maximal KKT violation in units of the kernel's own spread.

    Args:
      alpha: (m,) feasible point; Ka: (m,) K alpha; caps: (m,) upper bounds; mask: (m,) bool;
        m >= 1 (other shapes: InvalidInputError, while tracing too).

    Returns:
      (violation, objective): violation = max_{a_j > 0} (Ka)_j - min_{a_i < C} (Ka)_i divided by
      s = min(a^T K a, 1 - a^T K a), >= 0; objective = a^T K a.

    Why that unit: the violation is a difference of values of Ka = <Phi(x_i), c>, and so are the
    decision values f = 2 Ka - mu that place the region's boundary. Their spread is bounded by
    a^T K a, the squared norm of the feature-space center c (the scale at large gamma, where K
    tends to I and every value of Ka is small), and by 1 - a^T K a = sum_i a_i ||Phi(x_i) - c||^2,
    the spread of the features around c (the scale at small gamma, where K = 1 1^T - gamma D +
    O(gamma^2), Ka tends to 1 and the informative differences are O(gamma)). Relative to the
    smaller of the two the rule is scale-free in gamma at both ends: as gamma -> 0 it becomes
    (differences of squared distances to the weighted mean) / (2 weighted variance), the
    minimum enclosing ball's own rule at nu = 0. At the exact solution the violation is 0, and
    f at the training points is then within about 2 tol s of its exact value.
    """
    # NumPy input as JAX arrays (longdouble as float64: _validate.jax_value); JAX's and tracers as they are
    alpha, Ka, caps, mask = (v if isinstance(v, jax.Array) else jnp.asarray(_validate.jax_value(v))
                             for v in (alpha, Ka, caps, mask))
    shapes = [tuple(v.shape) for v in (alpha, Ka, caps, mask)]  # (known while tracing)
    if len(shapes[0]) != 1 or not shapes[0][0] or any(s != shapes[0] for s in shapes):
        raise _validate.InvalidInputError(f"alpha, Ka, caps and mask must have one shape (m,) with m >= 1, got "
                                          f"{', '.join(map(str, shapes))}")
    inf = jnp.asarray(jnp.inf, Ka.dtype)
    obj = jnp.vdot(alpha, Ka)
    up = jnp.max(jnp.where(mask & (alpha > 0), Ka, -inf))
    low = jnp.min(jnp.where(mask & (alpha < caps), Ka, inf))
    viol = jnp.maximum(up - low, 0.0)
    viol = jnp.where(jnp.isfinite(viol), viol, 0.0)
    unit = jnp.minimum(obj, 1.0 - obj)
    return viol / jnp.maximum(unit, jnp.finfo(Ka.dtype).tiny), obj


def offset(alpha, Ka, caps, mask):
    """mu = 2 (K a)_i averaged over the free support vectors; libsvm's midpoint rule if none. ()"""
    g = 2.0 * Ka
    free = mask & (alpha > 0) & (alpha < caps)
    n_free = jnp.sum(free)
    mean_free = jnp.sum(jnp.where(free, g, 0.0)) / jnp.maximum(n_free, 1)
    inf = jnp.asarray(jnp.inf, g.dtype)
    lb = jnp.max(jnp.where(mask & (alpha >= caps) & (alpha > 0), g, -inf))  # f <= 0 there
    ub = jnp.min(jnp.where(mask & (alpha <= 0), g, inf))  # f >= 0 there
    mid = jnp.where(jnp.isfinite(lb) & jnp.isfinite(ub), 0.5 * (lb + ub), jnp.where(jnp.isfinite(lb), lb, ub))
    return jnp.where(n_free > 0, mean_free, mid)


def decision_value_and_grad(svdd: SVDD, x, block=BLOCK):
    """f(x) (eq. 3) and its spatial gradient, in blocks of query points.

    Args:
      svdd: a fitted :class:`SVDD`; x: (n, 3) query points; block: rows per block.

    Returns:
      f (n,) and grad f (n, 3) = -4 gamma sum_i alpha_i k(x, x_i) (x - x_i). Memory O(block m).

    Raises:
      InvalidInputError: as :func:`decision_function`'s checks of ``svdd``, ``x`` and ``block``
        (``svdd`` no SVDD was an AttributeError, x of another shape an IndexError), its check of
        the cast of concrete x too (:func:`jaxpose.host.check_query_cast`), against the dtype JAX
        computes x in with the model's points: float64 queries of a float32 model without x64 are
        cast to float32 (they were, silently, where that cast moved them off the model), with x64
        they are computed in float64 and nothing is cast; integer queries of a float32 model are
        float32 either way. x may be a list of points, as for :func:`decision_function`.
    """
    check_svdd(svdd, "jax.vmap(decision_value_and_grad, in_axes=(0, None))(svdd, x)")
    _validate.check_array(x, name="x")
    block = _validate.check_int(block, "block", 1)
    x = _validate.jax_value(x)  # (NumPy's longdouble: its float64 values)
    if not hasattr(x, "dtype"):  # a list of points, as decision_function takes (it was an AttributeError)
        x = np.asarray(x)
    computed = jnp.promote_types(jax.dtypes.canonicalize_dtype(x.dtype), svdd.points.dtype)  # (JAX's promotion:
    _check_cast(svdd, x, computed)  # int64 queries of a float32 model are float32 even with x64)
    p, a, g = svdd.points, svdd.alpha, svdd.gamma

    def one_block(xb):
        d = xb[:, None, :] - p[None, :, :]
        w = a * jnp.exp(-g * jnp.sum(d * d, axis=-1))
        f = 2.0 * jnp.sum(w, axis=1) - svdd.offset
        grad = -4.0 * g * jnp.einsum("nm,nmk->nk", w, d)
        return f, grad

    return map_blocks(one_block, x, block)


def decision_function(svdd: SVDD, x, block=BLOCK):
    """The decision function f(x) = 2 k(x)^T alpha - mu (eq. 3), positive inside the region.

    Args:
      svdd: a fitted :class:`SVDD`.
      x: (n, 3) query points (any real dtype; computed in the model's dtype).
      block: query rows per block, an int >= 1 (memory O(block m)).

    Returns:
      (n,) float.

    Raises:
      InvalidInputError: ``svdd`` is not one SVDD (a batch of them is evaluated under
        ``jax.vmap``), x is not a finite (n, 3) array, or ``block`` is not an int >= 1; concrete
        x that its cast to the model's dtype rounds by more than ``jaxpose.host.MAX_ROUNDING`` of
        the RMS spread of the points the model was fitted on, or beyond that dtype's range
        (float64 queries of a float32 model far from the origin: :func:`jaxpose.host.check_query_cast`,
        :func:`jaxpose.fit_svdd`'s rule for its points). Traced x (under jit, vmap or grad), or a
        traced model, cannot be checked: they are cast as they are.

    Example::

        svdd = jaxpose.fit_svdd(points, gamma=5.0, nu=0.3)
        inside = jaxpose.decision_function(svdd, points) >= 0
    """
    check_svdd(svdd, "jax.vmap(decision_function, in_axes=(0, None))(svdd, x)")
    _validate.check_array(x, name="x")
    block = _validate.check_int(block, "block", 1)
    _check_cast(svdd, x)
    x = jnp.asarray(x, svdd.points.dtype)
    if x.shape[0] == 0:
        return jnp.zeros((0,), x.dtype)
    p, a, g = svdd.points, svdd.alpha, svdd.gamma
    return map_blocks(lambda xb: 2.0 * (gaussian_kernel(xb, p, g) @ a) - svdd.offset, x, block)


def _check_cast(svdd, x, dtype=None):
    """:func:`jaxpose.host.check_query_cast` of concrete x against a concrete model: the model's
    spread is that of its points (the rows its mask keeps); only where the cast to ``dtype`` (None:
    the model's) changes x."""
    from ...host import check_query_cast, host_frame

    dtype = np.dtype(svdd.points.dtype if dtype is None else dtype)
    given = getattr(x, "dtype", None)  # (NumPy and JAX arrays: no copy where nothing is cast)
    if _validate.is_traced(x) or (given is not None and np.dtype(given) == dtype):
        return
    x = np.asarray(x)  # (a list: its float64 values)
    if x.dtype == dtype or any(_validate.is_traced(leaf) for leaf in (svdd.points, svdd.mask)):
        return
    points = np.asarray(svdd.points, np.float64)
    if svdd.mask is not None:
        points = points[np.asarray(svdd.mask, bool)]
    try:
        _, spread = host_frame(points, "the model's points")
    except _validate.InvalidInputError:  # (one distinct point: no spread to measure a rounding against)
        spread = 0.0
    check_query_cast(x, dtype, spread)
