"""Translation and scale normalization (the paper's section 3.2), pure JAX.

Pre-scaling, which makes gamma dimensionless: points are centered at their mean
and divided by their reference size

    s_ref = sqrt(mean ||x - mean||^2) / sqrt(5 / 12),

the RMS distance from the mean relative to that of a unit cube's surface
(sqrt(5/12) ~ 0.6455), so a unit cube's surface has s_ref = 1 and the paper's
gamma range (0, 50] keeps its meaning for objects of about that size. The
measure is invariant to rotation and translation and proportional to scale,
hence normalize(R s X + t) gives the same normalized shape rotated by R.

The pre-scaled points are also turned to their principal axes (``principal_axes``),
so the volume grid turns with the object: the result is equivariant under
rotations up to float rounding, not only up to grid error. The SVDD is fitted on
these points; its region's centroid c_m (eq. 4) and mean distance d_m (eq. 5) are
mapped back: center = mean + s_ref axes c_m, scale = s_ref d_m.

Derivatives in gamma and nu flow through the SVDD solution (implicit, KKT) and
the grid occupancy, whose derivative is the coarea boundary term
int g df/dtheta delta(f) dV with delta smeared over one cell.
"""
from __future__ import annotations

import math
import numbers
from functools import partial
from typing import NamedTuple, Sequence

import jax
import jax.numpy as jnp
import numpy as np

from . import _validate
from ._hyper import hyper_jvp
from .moments import _volume_moments
from .svdd import _fit

__all__ = ["Pose", "normalize", "normalize_batch", "reference_frame", "prescale", "principal_axes", "REFERENCE_RMS"]

REFERENCE_RMS = math.sqrt(5.0 / 12.0)


class Pose(NamedTuple):
    """A similarity x -> (x - center) / scale. A pytree.

    center : (3,) ; scale : () ; converged : () bool (solver reached tol) ;
    valid : () bool (finite, positive scale, non-empty region); iterations : ()
    Batched poses (from ``normalize_batch``) carry a leading batch axis.
    """

    center: jax.Array
    scale: jax.Array
    converged: jax.Array = True
    valid: jax.Array = True
    iterations: jax.Array = 0

    @classmethod
    def from_center_scale(cls, center, scale) -> "Pose":
        center = jnp.asarray(center)
        scale = jnp.asarray(scale, center.dtype)
        valid = jnp.all(jnp.isfinite(center)) & jnp.isfinite(scale) & (scale > 0)
        return cls(center, scale, jnp.asarray(True), valid, jnp.asarray(0))

    @property
    def matrix(self):
        """(..., 4, 4) homogeneous matrix of x -> (x - center) / scale."""
        c, s = jnp.asarray(self.center), jnp.asarray(self.scale)
        eye = jnp.broadcast_to(jnp.eye(3, dtype=c.dtype), c.shape[:-1] + (3, 3))
        top = jnp.concatenate([eye / s[..., None, None], (-c / s[..., None])[..., None]], axis=-1)
        bottom = jnp.broadcast_to(jnp.asarray([0, 0, 0, 1], c.dtype), c.shape[:-1] + (1, 4))
        return jnp.concatenate([top, bottom], axis=-2)

    def apply(self, x):
        """Normalize points x : (n, 3) -> (n, 3)."""
        return (jnp.asarray(x) - self.center) / self.scale

    def inverse(self) -> "Pose":
        """The inverse similarity y -> scale y + center, as a Pose."""
        return self._replace(center=-self.center / self.scale, scale=1.0 / self.scale)


def reference_frame(points, mask=None):
    """Mean (3,) and reference size () of points (m, 3) (see module docs)."""
    m = points.shape[0]
    w = jnp.ones((m,), points.dtype) if mask is None else jnp.asarray(mask, points.dtype)
    n = jnp.sum(w)
    mean = jnp.sum(w[:, None] * points, axis=0) / n
    mean = mean + jnp.sum(w[:, None] * (points - mean), axis=0) / n  # second pass: offsets far from 0
    d = points - mean
    rms = jnp.sqrt(jnp.sum(w * jnp.sum(d * d, axis=-1)) / n)
    return mean, rms / REFERENCE_RMS


def principal_axes(y, mask=None):
    """(3, 3) orthonormal eigenvectors (columns) of the covariance of centered y : (m, 3).

    The grid is laid out along these axes, so it turns with the object and the
    discretization error does not depend on the object's orientation. Treated as a
    constant for differentiation (the exact moments do not depend on the frame).
    """
    w = jnp.ones(y.shape[:1], y.dtype) if mask is None else jnp.asarray(mask, y.dtype)
    cov = jnp.einsum("m,mi,mj->ij", w, y, y) / jnp.sum(w)
    _, axes = jnp.linalg.eigh(jax.lax.stop_gradient(cov))
    return jax.lax.stop_gradient(axes)


def prescale(points, mask=None):
    """Points in the reference frame: y = ((x - mean) / s_ref) @ axes.

    -> y : (m, 3), and ``to_world(c)`` mapping a point of that frame back: mean + s_ref axes c;
    s_ref : () (0 for degenerate input; y is then computed with 1).
    """
    mean, size = reference_frame(points, mask)
    safe = jnp.where(size > 0, size, 1.0)
    axes = principal_axes(points - mean, mask)
    y = ((points - mean) / safe) @ axes
    return y, (lambda c: mean + safe * (axes @ c)), size


def _normalize(points, mask, gamma, nu, resolution, refine, band, tol, max_iter, check_every, kernel, block,
               solver=None):
    # issue 3: derivatives in (gamma, nu) alone come from forward-mode columns, also under jax.grad
    # (same values and derivatives; see jaxpose/_hyper.py); derivatives in points as before.
    impl = partial(_normalize_impl, resolution=resolution, refine=refine, band=band, tol=tol, max_iter=max_iter,
                   check_every=check_every, kernel=kernel, block=block, solver=solver)
    return hyper_jvp(impl, (2, 3))(points, mask, gamma, nu)


def _normalize_impl(points, mask, gamma, nu, resolution, refine, band, tol, max_iter, check_every, kernel, block,
                    solver=None):
    y, to_world, size = prescale(points, mask)
    svdd = _fit(y, gamma, nu, mask, None, tol=tol, max_iter=max_iter, check_every=check_every, kernel=kernel, block=block,
                solver=solver)
    # the implicit KKT derivative moves alpha only on the support: skip the alpha = 0 pass
    return _pose_of(svdd, to_world, size, resolution, refine, band, block, outside=False)


def _pose_of(svdd, to_world, size, resolution, refine, band, block, outside):
    """The pose (eqs. 4, 5) of an SVDD fitted to pre-scaled points, in world units.
    outside: see ``moments._boundary_weights`` (False when alpha's tangent vanishes where alpha = 0)."""
    mom = _volume_moments(svdd, resolution, block, refine, band, outside=outside)
    center = to_world(mom.center)
    scale = jnp.where(size > 0, size, 1.0) * mom.mean_distance
    valid = (size > 0) & jnp.all(jnp.isfinite(center)) & jnp.isfinite(scale) & (scale > 0) & (mom.volume > 0)
    return Pose(center, scale, svdd.converged, valid, svdd.iterations)


_STATIC = ("resolution", "refine", "band", "tol", "max_iter", "check_every", "kernel", "block", "solver")
DEFAULTS = dict(resolution=64, refine=2, band=16384, tol=1e-3, max_iter=20_000, check_every=10, kernel="auto", block=2048,
                solver=None)
_normalize_jit = jax.jit(_normalize, static_argnames=_STATIC)


def _options(resolution, refine, band, tol, max_iter, check_every, kernel, block, solver=None):
    if not all(isinstance(v, numbers.Integral) for v in (refine, band)) or refine < 1 or refine & (refine - 1) or band < 0:
        raise _validate.InvalidInputError(f"refine must be a power of 2 and band >= 0, got {refine!r}, {band!r}")
    _validate.check_options(tol, max_iter, check_every, block)  # issue 6: also rejects NaN tol, block < 1
    _validate.check_choices(kernel=kernel, solver=solver)
    return dict(
        resolution=_validate.check_resolution(resolution),
        refine=int(refine),
        band=int(band),
        tol=float(tol),
        max_iter=int(max_iter),
        check_every=int(check_every),
        kernel=kernel,
        block=int(block),
        solver=solver,
    )


def normalize(
    points,
    gamma=47.0,
    nu=0.5,
    *,
    resolution=64,
    refine=2,
    band=16384,
    tol=1e-3,
    max_iter=20_000,
    check_every=10,
    kernel="auto",
    block=2048,
    solver=None,
    throw=False,
) -> Pose:
    """The OCSVM pose (center c_m, scale d_m) of surface samples.

    points : (m, 3) float samples of a surface (any units, any offset)
    gamma : () > 0, dimensionless (for the pre-scaled points, see module docs)
    nu : () in [0, 1]
    resolution, refine, band : volume-integral grid (static, see ``volume_moments``);
        the defaults resolve the boundary like a 128^3 grid, extrapolated with the 64^3 level
        (center ~1e-5 of the object's size off a 512 reference on FAUST meshes); resolution=32
        takes about half the time (~2e-4); resolution=32, refine=8 for thin shells (3x slower)
    tol, max_iter, check_every, kernel, block, solver : solver options (see ``fit_svdd``; solver None:
        "pg" up to 2500 points, "auto" above, on CPU)
    throw : concrete calls only: raise ConvergenceError if the solver hit max_iter,
        JaxposeError if the pose is not valid (otherwise see ``Pose.converged`` / ``Pose.valid``)

    A pure JAX function of (points, gamma, nu): jittable (options static),
    vmappable, differentiable in gamma and nu (and points).
    Concrete points are centered and scaled in float64 NumPy first (float16 and integers
    are computed in float32), so float32 coordinates far from the origin keep their shape.
    """
    opts = _options(resolution, refine, band, tol, max_iter, check_every, kernel, block, solver)
    _validate.check_points(points)
    _validate.check_gamma(gamma)
    _validate.check_nu(nu)
    shift, size = None, None
    if _validate.is_traced(points):  # pure-JAX path (jit, vmap, grad in points): unchanged
        points = jnp.asarray(points)
        if not jnp.issubdtype(points.dtype, jnp.floating):
            points = points.astype(jnp.result_type(float))
    else:  # issue 6: pre-center/scale in float64 before the cast to the compute dtype
        dtype = _validate.compute_dtype(points)
        shift, size = _validate.frame64(points)
        points = jnp.asarray((np.asarray(points, np.float64) - shift) / size, dtype)
    pose = _normalize_jit(points, None, gamma, nu, **opts)
    return _finish(pose, shift, size, gamma, nu, throw, tol)


def _finish(pose, shift, size, gamma, nu, throw, tol):
    """Issue 6: map a pre-scaled pose back, flag out-of-range traced gamma / nu as not valid,
    and raise on request (concrete results only)."""
    if shift is not None:
        dtype = pose.center.dtype
        center = jnp.asarray(shift, dtype) + jnp.asarray(size, dtype)[..., None] * pose.center
        scale = jnp.asarray(size, dtype) * pose.scale
        finite = jnp.all(jnp.isfinite(center), axis=-1) & jnp.isfinite(scale) & (scale > 0)
        pose = pose._replace(center=center, scale=scale, valid=pose.valid & finite)
    g, n = jnp.asarray(gamma), jnp.asarray(nu)
    in_range = jnp.isfinite(g) & (g > 0) & jnp.isfinite(n) & (n >= 0) & (n <= 1)
    pose = pose._replace(valid=pose.valid & in_range)
    if throw and not _validate.is_traced(pose.valid):
        if not bool(jnp.all(pose.converged)):
            raise _validate.ConvergenceError(
                f"SVDD solver hit its iteration cap ({np.asarray(pose.iterations)} iterations) before tol={tol}"
            )
        if not bool(jnp.all(pose.valid)):
            raise _validate.JaxposeError(
                f"no valid pose (center {np.asarray(pose.center)}, scale {np.asarray(pose.scale)}): "
                "the region is empty or degenerate at this grid; try other gamma / nu / resolution"
            )
    return pose


def normalize_batch(list_of_points: Sequence, gamma=47.0, nu=0.5, *, pad_to=None, throw=False, strategy="auto",
                    **options) -> Pose:
    """Normalize many objects with one compilation (padding + masks).

    list_of_points : sequence of (m_i, 3) arrays; rows are padded to
    max(m_i) (or ``pad_to``) and masked out of every sum.
    Returns a Pose whose fields have a leading axis of len(list_of_points).
    Point counts differ only in padding: results equal ``normalize`` per object
    up to solver tolerance. Point sets must be concrete (under jit, vmap ``normalize``);
    each is centered and scaled in float64 first, as in ``normalize``. ``throw`` as there.
    strategy : "vmap" (all objects in lock-step: fills wide accelerators, but every object
        runs as many solver iterations as the slowest and skipped grid chunks become
        selects), "map" (``lax.map``, one object after another inside the compiled call:
        2.2x faster than "vmap" on 2 CPU cores, 12 objects at m = 1000), or "auto"
        ("map" on CPU, "vmap" elsewhere).
    """
    if strategy not in ("auto", "map", "vmap"):
        raise _validate.InvalidInputError(f"strategy must be 'auto', 'map' or 'vmap', got {strategy!r}")
    if strategy == "auto":
        strategy = "map" if jax.default_backend() == "cpu" else "vmap"
    unknown = set(options) - set(DEFAULTS)
    if unknown:
        raise _validate.InvalidInputError(f"unknown options {sorted(unknown)}; valid: {sorted(DEFAULTS)}")
    opts = _options(**{**DEFAULTS, **options})
    if len(list_of_points) == 0:
        raise _validate.InvalidInputError("normalize_batch needs at least one point set")
    arrays = [_validate.check_points(p, name=f"points[{i}]") for i, p in enumerate(list_of_points)]
    if any(_validate.is_traced(a) for a in arrays):  # issue 6: padding needs concrete arrays
        raise _validate.InvalidInputError("normalize_batch needs concrete point sets; under jit, use jax.vmap(normalize)")
    # issue 6: pre-center/scale each set in float64 (see normalize), mapped back in _finish
    dtype = np.result_type(*[_validate.compute_dtype(a) for a in arrays])
    frames = [_validate.frame64(a, name=f"points[{i}]") for i, a in enumerate(arrays)]
    arrays = [(np.asarray(a, np.float64) - c) / r for a, (c, r) in zip(arrays, frames)]
    shift, size = np.stack([c for c, _ in frames]), np.asarray([r for _, r in frames])
    _validate.check_gamma(gamma)
    _validate.check_nu(nu)
    m = max(a.shape[0] for a in arrays) if pad_to is None else int(pad_to)
    if m < max(a.shape[0] for a in arrays):
        raise _validate.InvalidInputError(f"pad_to={m} is smaller than the largest point set")
    pts = np.empty((len(arrays), m, 3), dtype)
    mask = np.zeros((len(arrays), m), bool)
    for i, a in enumerate(arrays):
        pts[i, : len(a)] = a
        pts[i, len(a):] = a[0]  # padding sits on a real point, masked out
        mask[i, : len(a)] = True
    pts = jnp.asarray(pts)  # float64 becomes float32 unless x64 is on
    gamma = jnp.broadcast_to(jnp.asarray(gamma, pts.dtype), (len(arrays),))
    nu = jnp.broadcast_to(jnp.asarray(nu, pts.dtype), (len(arrays),))
    pose = _batched(pts, jnp.asarray(mask), gamma, nu, strategy=strategy, **opts)
    return _finish(pose, shift, size, gamma, nu, throw, opts["tol"])


def _batched_impl(points, mask, gamma, nu, strategy="vmap", **opts):
    fn = lambda p, mk, g, n: _normalize(p, mk, g, n, **opts)
    if strategy == "map":
        return jax.lax.map(lambda args: fn(*args), (points, mask, gamma, nu))
    return jax.vmap(fn)(points, mask, gamma, nu)


_batched = jax.jit(_batched_impl, static_argnames=_STATIC + ("strategy",))
