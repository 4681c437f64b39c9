"""Weighted volume moments: of the SVDD region {f >= 0} (centroid, eq. 4; mean distance, eq. 5;
volume; M2) and of any weighted occupancy on a grid (:func:`grid_moments`), one implementation
(:func:`weighted_moments`), and of a depth^p-weighted voxel solid (:func:`robust_moments`,
:func:`solid_moments`: the robust estimator's moments in JAX). :class:`Moments`,
:func:`weighted_moments` and :func:`grid_moments` are :mod:`jaxpose.weighted`'s, written once for
NumPy and JAX.

Quadrature. Each grid cell gets a fractional occupancy from the local signed distance to the
boundary, f / |grad f|, against the cell's width along the normal, sum_k |n_k| h_k:

    w = clip(1/2 + f / sum_k |df/dx_k| h_k, 0, 1),

the hard indicator of eqs. 4-5 integrated to sub-cell accuracy (error O(h^2), against O(h) for
counting cells), and piecewise differentiable in f.

Grid. A coarse grid of ``resolution``^3 cells covers a box that provably holds the region
(:func:`jaxpose.occupancy.grid.domain`); then, log2(``refine``) times, the cells near the boundary are split
into 2 x 2 x 2 children (narrow-band refinement). A level refines the cells the linearised
boundary cuts plus a margin (:func:`band_score`: 1.5 linear cell widths and a curvature allowance,
so that thin parts are caught); the last level takes the cut cells and half the allowance
(``LAST_BAND``), since a cell missed there keeps its own occupancy. At most ``band`` cells are
refined at the first level (doubling per level); ``Moments.unrefined`` counts cut cells left out.

Richardson extrapolation. Every moment is a ratio of integrals linear in the weights, and each
integral's error falls as c h^2 when the boundary cells halve; the integrals with and without the
finest level, I_h and I_2h, are both at hand, so the weights are taken as (4 w_h - w_2h) / 3.

Evaluation of f. Every level lies on a tensor-product lattice where exp(-gamma |x - p|^2) factors
per axis: the coarse grid is evaluated in boxes (:func:`jaxpose.occupancy.grid.evaluate_grid`) and the
children from tables of per-axis factors (:func:`jaxpose.occupancy.grid.evaluate_children`), with the same
values as evaluating each cell directly.

Derivatives. The cells, the refinement and the occupancies are computed without derivatives
(:func:`discretize`); the weights then pass through an identity with a custom JVP that evaluates
the tangent of (f, grad f) only at the cells whose occupancy is strictly between 0 and 1 (the
clipped occupancy has zero derivative elsewhere): the coarea boundary term
d/dtheta int_{f >= 0} g dV = int g (df/dtheta) delta(f) dV, smeared over one cell. With the
points held fixed (derivatives in gamma and nu) that tangent comes from explicit sums, one pass
per kernel block (:func:`jaxpose.occupancy.grid.evaluate_on_grid_jvp`); otherwise from JAX's JVP of the
direct sums. The grid box is snapped to a lattice, so it is piecewise constant in (gamma, nu):
these are the derivatives of the computed moments wherever the discretization does not switch (a
cell entering or leaving the band or the one-cell occupancy ramp).
"""
from __future__ import annotations

from functools import partial
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ._hyper import instantiate, is_zero
from ._validate import InvalidInputError, check_power
from .config import GridConfig
from .depth import depth_weights, to_bucket
from .occupancy.solid import check_solid
from .occupancy.svdd.problem import SVDD, check_svdd
from .occupancy.grid import (CHILD_OFFSETS, domain, evaluate_children, evaluate_grid, evaluate_on_grid, evaluate_on_grid_jvp,
                   first_true, morton_codes)
from .weighted import Moments, check_shape, grid_moments, solid_occupancy, weighted_moments

__all__ = ["Moments", "volume_moments", "region_moments", "discretize", "occupancy", "moments_from_occupancy",
           "weighted_moments", "grid_moments", "robust_moments", "solid_moments", "band_score", "select_cells",
           "LAST_BAND"]


def occupancy(f, grad, h):
    """Fraction of each cell inside {f >= 0}. f : (n,), grad : (n, 3), h : (3,) -> (n,)."""
    width = jnp.sum(jnp.abs(grad) * h, axis=-1)
    # With 0 < width < sqrt(tiny) the tangent of f / width, df / width - f dwidth / width^2,
    # overflows (width^2 underflows to 0 in float32 far from the points, where grad f ~ 1e-25)
    # and 0 * inf would make the whole pose's gradient NaN. Such cells use the indicator, which
    # is the same value unless |f| < width / 2.
    ok = width > jnp.sqrt(jnp.finfo(width.dtype).tiny)
    safe = jnp.where(ok, width, 1.0)
    return jnp.where(ok, jnp.clip(0.5 + f / safe, 0.0, 1.0), (f >= 0).astype(f.dtype))


def moments_from_occupancy(x, w, h):
    """Moments of the weighted cells x : (n, 3), w : (n,) (occupied volume in cells of size h), h : (3,)."""
    mass, c, md, second = weighted_moments((x[:, 0], x[:, 1], x[:, 2]), w)
    return Moments(c, md, mass * jnp.prod(h), second, h, jnp.asarray(0))


# (linear widths, share of the curvature allowance) of the last level's band (module docs); others: (1.5, 1)
LAST_BAND = (0.5, 0.5)


def band_score(f, grad, h, gamma, offset, lin=1.5, curv=1.0):
    """< 1 where a cell may hold part of the boundary: |f| within ``lin`` linear cell widths plus
    ``curv`` times a curvature allowance (|Hess f| <= 2 gamma (f + mu) near x, so thin shells thinner
    than a cell are still refined)."""
    width = lin * jnp.sum(jnp.abs(grad) * h, axis=-1) + curv * gamma * jnp.maximum(f + offset, 0.0) * jnp.sum(h * h) / 2
    return jax.lax.stop_gradient(jnp.where(width > 0, jnp.abs(f) / jnp.where(width > 0, width, 1.0), jnp.inf))


def volume_moments(svdd, grid: GridConfig | None = None, **options) -> Moments:
    """Centroid, mean distance, volume and second moment of the region {f >= 0}.

    Args:
      svdd: a fitted :class:`jaxpose.SVDD` (points in any units; the moments come in the same units).
      grid: a :class:`jaxpose.config.GridConfig`, or its fields as keywords: ``resolution``
        (coarse cells per axis), ``refine`` (a power of 2; 1 means no refinement and nothing to
        extrapolate with: the occupancy's c h^2 error is left), ``band`` (cells refined at the
        first level), ``block``, ``extrapolate`` (Richardson; False gives the plain sub-cell
        estimate of a (resolution * refine)^3 grid).

    Returns:
      :class:`Moments`. ``unrefined`` > 0 says the band was too narrow for the boundary.

    Raises:
      InvalidInputError: ``svdd`` is not one SVDD (a batch of them is mapped with ``jax.vmap``),
        or a bad grid option.

    Cost: resolution^3 evaluations of f plus 8 per refined cell and level. Differentiable in the
    SVDD's fields (module docs); compiled once per grid and shape.

    Example::

        mom = jaxpose.volume_moments(jaxpose.fit_svdd(points, 5.0, 0.3), resolution=32)
        mom.center, mom.mean_distance           # (3,), () in the units of points
    """
    check_svdd(svdd, "jax.vmap(lambda s: volume_moments(s, grid))(svdd)")
    if grid is None:
        grid = GridConfig.create(**options)
    elif options:
        raise InvalidInputError(f"give either grid or options, not both (got {sorted(options)})")
    elif not isinstance(grid, GridConfig):
        raise InvalidInputError(f"grid must be a GridConfig, got {type(grid).__name__}")
    return region_moments(svdd, grid)


class _Field(NamedTuple):
    """The parts of an SVDD that f(x) = 2 k(x)^T alpha - mu depends on (for evaluate_on_grid)."""

    points: jax.Array
    alpha: jax.Array
    gamma: jax.Array
    offset: jax.Array


@partial(jax.custom_jvp, nondiff_argnums=(5, 6))
def _boundary_weights(w, field, x, h, fac, block, outside):
    """Identity on the cell weights w (n,) = occupancy(f(x), grad f(x), h) * fac; its JVP in
    ``field`` is evaluated only where the occupancy is strictly between 0 and 1 (module docs).
    outside (static bool): whether alpha's tangent may be nonzero where alpha = 0."""
    return w


@partial(_boundary_weights.defjvp, symbolic_zeros=True)
def _boundary_weights_jvp(block, outside, primals, tangents):
    w, field, x, h, fac = primals
    dfield = jax.tree_util.tree_map(instantiate, tangents[1], is_leaf=is_zero)
    occ = w / jnp.where(fac != 0, fac, 1.0)
    # the cells whose weight has a nonzero derivative (clip not saturated), compacted to the front
    part = jax.lax.stop_gradient((fac != 0) & (occ > 0) & (occ < 1))
    count = jnp.sum(part)
    sel = first_true(part, w.shape[0])
    xs, hs, fs = x[sel], h[sel], fac[sel]
    # f skips the points with alpha = 0, but their alpha may have a tangent (points entering the
    # support along the secant slopes, or any user tangent): f is linear in alpha, so they are
    # summed too, with value 0 and tangent 2 k(x)^T dalpha. The tangent is not inspected (under
    # jax.grad it is not known when this runs); callers whose alpha tangent is zero off the
    # support by construction (the implicit KKT derivative) pass outside=False and skip them.
    support = jax.lax.stop_gradient(field.alpha != 0)
    every = jnp.ones_like(support) if outside else support
    if is_zero(tangents[1].points):  # the usual case: tangents in alpha, gamma, offset, in one pass
        f, grad, df, dgrad = evaluate_on_grid_jvp(field, (dfield.alpha, dfield.gamma, dfield.offset), xs, block,
                                                  count, every)
        _, dws = jax.jvp(lambda f_, g_: occupancy(f_, g_, hs) * fs, (f, grad), (df, dgrad))
    else:  # the points move too: JAX's JVP of the direct sums
        _, dws = jax.jvp(lambda fd: occupancy(*evaluate_on_grid(fd, xs, block, count, every), hs) * fs,
                         (field,), (dfield,))
    dws = jnp.where(jnp.arange(w.shape[0]) < count, dws, 0.0)
    return w, jnp.zeros_like(w).at[sel].add(dws)


def discretize(svdd, grid: GridConfig):
    """The discretization of {f >= 0} (no derivatives): coarse grid on ``domain(svdd)``, then
    ``log2(grid.refine)`` levels of narrow-band refinement.

    -> x (n, 3) cell centers, occ (n,) occupancy, fac (n,) constant factor (the cell's volume in
    coarse cells, 0 where it was replaced by its children), hc (n, 3) cell sizes, h (3,) coarse
    cell size, unrefined () (see ``Moments``). The weights are occ * fac.
    With ``grid.extrapolate``, fac becomes (4 fac - fac') / 3, fac' the factors without the finest
    level (Richardson extrapolation of every integral, module docs); refined cells of the
    level before then weigh -1/3 of their volume, their children 4/3.
    """
    resolution, block, refine, band, extrapolate = grid.resolution, grid.block, grid.refine, grid.band, grid.extrapolate
    svdd = jax.lax.stop_gradient(svdd)
    lo, hi = domain(svdd)
    # cells in Z-order: blocks of nearby cells, far kernel terms skipped per block
    x, h, f, grad = evaluate_grid(svdd, lo, hi, resolution, block)
    xs, occ, fac, hs = [x], [occupancy(f, grad, h)], [jnp.ones(x.shape[:1], x.dtype)], [h]
    vol, unrefined = 1.0, jnp.asarray(0)
    k, per_axis = band, resolution
    while refine > 1 and k > 0:
        k = min(k, x.shape[0])
        w = occ[-1] * fac[-1]
        partial_ = (w > 0) & (w < vol)  # cut by the linearised boundary: must be refined
        # partial cells first, the most evenly cut first (not index order: no spatial bias on overflow);
        # only cells that count (fac > 0: not the unevaluated children of unrefined cells)
        lin, curv = LAST_BAND if refine == 2 else (1.5, 1.0)
        score = jnp.where(partial_, -1.5 + jnp.abs(w / vol - 0.5), band_score(f, grad, h, svdd.gamma, svdd.offset, lin, curv))
        score = jnp.where(fac[-1] > 0, score, jnp.inf)
        idx, chosen = select_cells(score, k, x, lo, hi)
        unrefined = unrefined + jnp.sum(partial_) - jnp.sum(partial_[idx] & chosen)
        before = fac[-1]
        fac[-1] = fac[-1].at[idx].multiply(1.0 - chosen.astype(x.dtype))  # replaced by their children
        cells = x[idx]
        children = (cells[:, None, :] + CHILD_OFFSETS.astype(x.dtype) * h).reshape(-1, 3)
        f, grad = evaluate_children(svdd, lo, h, cells, 2 * per_axis, max(1, block // 4), jnp.sum(chosen))
        f, grad = f.reshape(-1), grad.reshape(-1, 3)
        x, per_axis = children, 2 * per_axis
        h, vol, refine, k = h / 2, vol / 8, refine // 2, 2 * k
        xs.append(x)
        occ.append(occupancy(f, grad, h))
        fac.append(vol * jnp.repeat(chosen.astype(x.dtype), 8))
        hs.append(h)
    hc = jnp.concatenate([jnp.broadcast_to(hl, xl.shape) for hl, xl in zip(hs, xs)])
    factor = jnp.concatenate(fac)
    if extrapolate and len(fac) > 1:
        coarse = jnp.concatenate(fac[:-2] + [before, jnp.zeros_like(fac[-1])])
        factor = (4.0 * factor - coarse) / 3.0
    return jnp.concatenate(xs), jnp.concatenate(occ), factor, hc, hs[0], unrefined


def select_cells(score, k, x, lo, hi):
    """The k slots of a level: idx (k,) cells to refine, chosen (k,) bool (a prefix; the other
    slots are not refined). Every cell with score < 1 when they fit, in index order (Z-order,
    or the Z-order of the parents at later levels); otherwise the k best scores, in Z-order
    (top_k and a sort only then: they cost more than half of the coarse grid)."""
    want = score < 1.0
    n = jnp.sum(want)

    def by_index(_):
        return first_true(want, k), jnp.arange(k) < n

    def by_score(_):
        neg, idx = jax.lax.top_k(-score, k)
        chosen = -neg < 1.0  # a prefix of idx
        # the chosen cells in Z-order (nearby children share blocks), the rest after them
        code = morton_codes(x[idx], lo, hi)
        perm = jnp.argsort(jnp.where(chosen, code, jnp.iinfo(jnp.int32).max))
        return idx[perm].astype(jnp.int32), chosen[perm]

    return jax.lax.cond(n <= k, by_index, by_score, None)


@partial(jax.jit, static_argnames=("grid", "outside"))
def region_moments(svdd, grid: GridConfig, outside: bool = True) -> Moments:
    """:func:`volume_moments` without checks, compiled per ``grid`` (static).

    outside (static): whether alpha's tangent may be nonzero where alpha = 0 (the secant
    nu-derivative moves such points; the implicit KKT derivative does not, and False skips
    their pass in the boundary term).
    """
    x, occ, fac, hc, h, unrefined = discretize(svdd, grid)
    field = _Field(svdd.points, svdd.alpha, svdd.gamma, svdd.offset)
    w = _boundary_weights(occ * fac, field, x, hc, fac, int(grid.block), bool(outside))  # in coarse cells
    mom = moments_from_occupancy(x, w, h)
    return mom._replace(unrefined=unrefined)


# --------------------------------------------------------------------------- a voxel solid, in JAX
def robust_moments(inside, occupied, origin, pitch, power, bias, extent=None) -> Moments:
    """Moments of a depth^p-weighted voxel solid in JAX: :func:`jaxpose.depth.depth_weights` (the
    exact distance transform, then :func:`jaxpose.weighted.depth_power_weights`), then
    :func:`jaxpose.weighted.grid_moments` (the host path,
    :func:`jaxpose.pose.estimators.solid_center_volume`, runs the same functions on scipy's
    distance transform in NumPy). Pure JAX, jittable, vmappable.

    Args:
      inside: (nx, ny, nz) bool, the solid's voxels; occupied: (nx, ny, nz) bool, voxels that
        straddle the surface (they count half in the volume; all False for a mesh solid), or None
        for none (a mesh :class:`jaxpose.occupancy.solid.Solid`'s ``occupied``).
      origin: (3,) lower corner of voxel (0, 0, 0); pitch: () voxel edge (units).
      power: () depth exponent p >= 0; bias: () voxels subtracted from the distance transform. A
        traced power outside [0, inf) (negative, NaN, inf), which cannot be refused, weighs every
        voxel 0 (:func:`jaxpose.depth.depth_weights`): the moments of zero mass, center 0, mean
        distance 0 and second moment 0 (no NaN, derivatives 0), beside the solid's volume; a power
        in range gives a mean distance > 0 wherever the volume is > 0. :func:`jaxpose.normalize`
        reports such a power as ``Status.BAD_PARAMETERS``.
      extent: optional (3,) int, the grid within an array padded with False
        (:func:`jaxpose.depth.to_bucket`).

    Returns:
      :class:`Moments` in the grid's frame: center sum_v d_v^p x_v / sum_v d_v^p, volume pitch^3
      (#inside - #occupied / 2). Differentiable in ``power``, ``pitch`` and ``origin``; the
      occupancy itself carries no derivative.

    Raises:
      InvalidInputError: arguments of other shapes (known while tracing too), a concrete power or
        bias that is not a finite number >= 0 (:func:`jaxpose._validate.check_power`).
    """
    check_power(power)
    shape = tuple(jnp.shape(inside))
    if len(shape) != 3:
        raise InvalidInputError(f"inside must be a 3-D grid (nx, ny, nz), got shape {shape}")
    wanted = {"occupied": (occupied, shape), "origin": (origin, (3,)), "pitch": (pitch, ()), "bias": (bias, ()),
              "extent": (extent, (3,))}
    for name, (value, want) in wanted.items():
        if value is not None:  # (a (2,) origin was read as (o0, o1, o1))
            check_shape(name, value, want, ", the shape of inside" if name == "occupied" else "")
    check_power(bias, "bias")  # (NaN weighed every voxel 0: moments of zero mass, without a word)
    if occupied is None:  # a mesh solid's (sol.occupied): was JAX's TypeError "unsupported operand type(s) for &"
        occupied = np.zeros(shape, bool)
    return _robust_moments(inside, occupied, origin, pitch, power, bias, extent)


@jax.jit
def _robust_moments(inside, occupied, origin, pitch, power, bias, extent=None) -> Moments:
    """:func:`robust_moments` without its checks (compiled)."""
    w = depth_weights(inside, power, bias, extent)
    return grid_moments(solid_occupancy(inside, occupied, w.dtype), w, origin, pitch)


_HALF = 0.5  # the moments are taken from the grid's middle (smaller numbers, fewer float32 digits lost)


def solid_moments(sol, power) -> Moments:
    """:func:`robust_moments` of a host :class:`jaxpose.occupancy.solid.Solid`, in voxel units from
    the grid's corner (origin 0, pitch 1; computed on the grid's :func:`jaxpose.depth.to_bucket`;
    JAX's default float): the robust estimator's moments where a derivative in ``power`` is wanted
    (the host entry points take :func:`jaxpose.pose.estimators.solid_center_volume`, NumPy).

    The world moments are ``sol.origin + sol.pitch * center`` (then ``@ sol.frame``), ``pitch^3 *
    volume``. Differentiable in ``power`` (a traced power: only its shape and dtype are checked). Raises
    InvalidInputError for a power that is not a finite number >= 0, or a ``sol`` that is no Solid
    (its AttributeError '... has no attribute inside')."""
    check_solid(sol)
    check_power(power)
    inside, extent, axes = to_bucket(sol.inside)
    occupied = np.zeros_like(inside) if sol.occupied is None else to_bucket(sol.occupied)[0]
    dtype = jnp.result_type(float)
    mom = robust_moments(inside, occupied, (-_HALF * extent).astype(dtype), np.ones((), dtype),
                         jnp.asarray(power, dtype), np.asarray(sol.bias, dtype), extent)
    back = np.argsort(axes)  # the bucket's axes back to the grid's
    center = mom.center + jnp.asarray(_HALF * extent, mom.center.dtype)  # from the grid's corner
    return mom._replace(center=center[back], second_moment=mom.second_moment[back][:, back])
