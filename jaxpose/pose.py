"""The OCSVM pose (the paper's section 3.2): ``normalize``, ``normalize_batch`` and the one pipeline.

Pipeline (:func:`pose_pipeline`, what every entry point runs): points are put in their reference
frame (:func:`jaxpose.frame.prescale`: centered, divided by their reference size, turned to their
principal axes, so gamma is dimensionless and the grid turns with the object); the SVDD is fitted
there (:func:`jaxpose.svdd.solve_svdd`); the region's centroid c_m (eq. 4) and mean distance d_m
(eq. 5) are integrated on a grid (:func:`jaxpose.moments.region_moments`) and mapped back:
center = mean + s_ref axes c_m, scale = s_ref d_m.

Concrete inputs are first centered and scaled on the host in float64 (:func:`jaxpose.frame.host_frame`)
and the offset is added back at the end, so coordinates far from the origin keep their digits.

Derivatives in gamma and nu flow through the SVDD solution (by default its trend: secant slopes
over gamma (1 +- 1 %) and nu (1 +- 1 %); or the implicit KKT derivative; ``PoseConfig.derivative``)
and the grid occupancy, whose derivative is the coarea boundary term. With only two hyperparameters, reverse mode in them is computed from forward-mode
columns (:func:`jaxpose._hyper.hyper_jvp`).
"""
from __future__ import annotations

from functools import partial
from typing import NamedTuple, Sequence

import jax
import jax.numpy as jnp
import numpy as np

from . import _validate
from ._hyper import hyper_jvp
from .config import PoseConfig
from .frame import host_frame, prescale
from .moments import region_moments
from .svdd import solve_svdd
from .svdd.secant import with_secants

__all__ = ["Pose", "normalize", "normalize_batch", "pose_pipeline", "pose_from_svdd"]


class Pose(NamedTuple):
    """A similarity x -> R (x - center) / scale, with the diagnostics of how it was found. A pytree.

    Attributes:
      center: (3,) in the units of the input.
      scale: () > 0, in the units of the input.
      converged: () bool, the SVDD solver reached its tolerance.
      valid: () bool, finite center, positive finite scale, non-empty region, parameters in range.
      iterations: () solver iterations.
      ambiguity: None, or () in [0, 1]: how poorly the rotation is determined (0: every cue of
        :mod:`jaxpose.rotation` clears its threshold); see ``flagged``.
      rotation: None (no rotation: R = I), or (3, 3) a proper rotation whose rows are the canonical
        axes in the input's coordinates (``rotation=True`` of :func:`normalize` and friends).

    Poses from :func:`normalize_batch` carry a leading batch axis on every field.
    """

    center: jax.Array
    scale: jax.Array
    converged: jax.Array = True
    valid: jax.Array = True
    iterations: jax.Array = 0
    ambiguity: jax.Array | None = None
    rotation: jax.Array | None = None

    @classmethod
    def from_center_scale(cls, center, scale, rotation=None, ambiguity=None) -> "Pose":
        """A Pose from a given center (3,) and scale () (and optionally rotation (3, 3), ambiguity ());
        valid when center and scale are finite and scale > 0.

        Concrete values stay NumPy float64 (every digit of a center far from the origin is kept);
        traced values stay JAX arrays.
        """
        xp = jnp if _validate.is_traced(center) or _validate.is_traced(scale) else np
        center = xp.asarray(center, dtype=None if xp is jnp else np.float64)
        scale = xp.asarray(scale, center.dtype)
        valid = xp.all(xp.isfinite(center)) & xp.isfinite(scale) & (scale > 0)
        if rotation is not None:
            rotation = xp.asarray(rotation, center.dtype)
            ambiguity = xp.asarray(0.0 if ambiguity is None else ambiguity, center.dtype)
        return cls(center, scale, xp.asarray(True), valid, xp.asarray(0), ambiguity, rotation)

    @property
    def flagged(self):
        """() bool (or None without a rotation): the rotation is not well determined (ambiguity > 0)."""
        return None if self.ambiguity is None else jnp.asarray(self.ambiguity) > 0

    def _rotation(self, dtype):
        if self.rotation is None:
            return jnp.broadcast_to(jnp.eye(3, dtype=dtype), jnp.shape(self.center)[:-1] + (3, 3))
        return jnp.asarray(self.rotation, dtype)

    @property
    def matrix(self):
        """(..., 4, 4) homogeneous matrix of x -> R (x - center) / scale."""
        c, s = jnp.asarray(self.center), jnp.asarray(self.scale)
        if self.rotation is None:
            eye = jnp.broadcast_to(jnp.eye(3, dtype=c.dtype), c.shape[:-1] + (3, 3))
            top = jnp.concatenate([eye / s[..., None, None], (-c / s[..., None])[..., None]], axis=-1)
        else:
            r = self._rotation(c.dtype) / s[..., None, None]
            top = jnp.concatenate([r, -jnp.einsum("...ij,...j->...i", r, c)[..., None]], axis=-1)
        bottom = jnp.broadcast_to(jnp.asarray([0, 0, 0, 1], c.dtype), c.shape[:-1] + (1, 4))
        return jnp.concatenate([top, bottom], axis=-2)

    def apply(self, x):
        """Normalize points x : (n, 3) -> (n, 3)."""
        y = (jnp.asarray(x) - self.center) / self.scale
        if self.rotation is None:
            return y
        return y @ jnp.asarray(self.rotation, y.dtype).T

    def inverse(self) -> "Pose":
        """The inverse similarity y -> scale R^T y + center, as a Pose (rotation R^T, center
        -R center / scale, scale 1 / scale)."""
        if self.rotation is None:
            return self._replace(center=-self.center / self.scale, scale=1.0 / self.scale)
        xp = np if isinstance(self.rotation, np.ndarray) and isinstance(self.center, np.ndarray) else jnp
        r = xp.asarray(self.rotation)
        center = -xp.einsum("...ij,...j->...i", r, self.center) / xp.asarray(self.scale)[..., None]
        return self._replace(center=center, scale=1.0 / self.scale, rotation=xp.swapaxes(r, -1, -2))


def pose_from_svdd(svdd, to_world, size, grid, outside, rotation=False, y=None, mask=None):
    """The pose (eqs. 4, 5) of an SVDD fitted to pre-scaled points, in world units.

    Args:
      svdd: SVDD in the reference frame; to_world, size: from :func:`jaxpose.frame.prescale`;
      grid: GridConfig; outside: see :func:`jaxpose.moments.region_moments`.
      rotation: also the region's frame (:func:`jaxpose.rotation.region_frame`), from the
        pre-scaled points ``y`` (m, 3) and their ``mask``.
    """
    mom = region_moments(svdd, grid, outside)
    center = to_world(mom.center)
    scale = jnp.where(size > 0, size, 1.0) * mom.mean_distance
    valid = (size > 0) & jnp.all(jnp.isfinite(center)) & jnp.isfinite(scale) & (scale > 0) & (mom.volume > 0)
    if not rotation:
        return Pose(center, scale, svdd.converged, valid, svdd.iterations)
    from .rotation import region_frame

    origin = to_world(jnp.zeros(3, center.dtype))
    axes = jax.vmap(to_world)(jnp.eye(3, dtype=center.dtype)) - origin  # rows: size * axes[:, k]
    axes = (axes / jnp.linalg.norm(axes, axis=1, keepdims=True)).T
    rot, amb = region_frame(mom.second_moment, mom.center, y, mask, axes)
    return Pose(center, scale, svdd.converged, valid, svdd.iterations, amb, rot)


def _pipeline(points, mask, gamma, nu, config, rotation=False):
    y, to_world, size = prescale(points, mask)
    extra = {"rotation": True, "y": y, "mask": mask} if rotation else {}
    if config.derivative == "exact":
        svdd = solve_svdd(y, gamma, nu, mask, None, config.svdd)
        # the implicit KKT derivative moves alpha only on the support: skip the alpha = 0 pass
        return pose_from_svdd(svdd, to_world, size, config.grid, outside=False, **extra)
    dtype = y.dtype
    gamma, nu = jnp.asarray(gamma, dtype), jnp.asarray(nu, dtype)
    sg = jax.lax.stop_gradient
    params = ("gamma", "nu") if config.derivative == "trend" else ("nu",)  # "secant": gamma implicit
    svdd = solve_svdd(y, sg(gamma) if "gamma" in params else gamma, sg(nu), mask, None, config.svdd)
    svdd = with_secants(svdd, gamma, nu, config.svdd, params, (config.gamma_delta, config.nu_delta),
                        config.secant_tol(), config.secant_iterations)
    return pose_from_svdd(svdd, to_world, size, config.grid, outside=True, **extra)  # the secant moves alpha = 0 points


def pose_pipeline(points, mask, gamma, nu, config: PoseConfig, rotation: bool = False) -> Pose:
    """The one pipeline from points to a Pose (module docs); pure JAX, no input checks.

    Args:
      points: (m, 3) float; mask: (m,) bool or None (False rows are padding);
      gamma, nu: () traced; config: :class:`jaxpose.config.PoseConfig` (static);
      rotation: (static) also the region's canonical frame (``Pose.rotation``, ``Pose.ambiguity``;
        not differentiated).

    Returns:
      Pose in the units of ``points``. Derivatives in (gamma, nu) come from forward-mode
      columns, also under jax.grad / jacrev; derivatives in the points by plain autodiff.
    """
    return hyper_jvp(partial(_pipeline, config=config, rotation=bool(rotation)), (2, 3))(points, mask, gamma, nu)


_pipeline_jit = jax.jit(pose_pipeline, static_argnames=("config", "rotation"))


def normalize(points, gamma=47.0, nu=0.5, *, config: PoseConfig | None = None, throw=False, rotation=False,
              **options) -> Pose:
    """The OCSVM pose (center c_m, scale d_m) of surface samples.

    Args:
      points: (m, 3) samples of a surface, any units and offset (float32, float64 or integers).
      gamma: () > 0, dimensionless (for the pre-scaled points, see :mod:`jaxpose.frame`).
      nu: () in [0, 1].
      config: a :class:`jaxpose.config.PoseConfig`; or, as keywords, any of its flat options:
        grid ``resolution`` (64), ``refine`` (2), ``band`` (16384), ``extrapolate``; solver ``tol``
        (1e-3), ``max_iter``, ``check_every``, ``kernel``, ``solver`` (None: "pg" up to 2500
        points, "auto" above, on CPU); ``block`` (both); ``derivative`` ("trend" | "exact" |
        "secant"), ``gamma_delta``, ``nu_delta``, ``secant_iterations``, ``nu_tol``.
      throw: concrete calls only: raise ConvergenceError if the solver hit max_iter,
        JaxposeError if the pose is not valid (otherwise see ``Pose.converged`` / ``Pose.valid``).
      rotation: also the canonical frame of the OCSVM region (``Pose.rotation``, rows = axes,
        det +1; ``Pose.ambiguity``, ``Pose.flagged``; :func:`jaxpose.rotation.region_frame`); off
        by default, and off changes nothing. Not differentiated.

    Returns:
      :class:`Pose`. The default grid resolves the boundary like a 128^3 grid, extrapolated with
      the 64^3 level; ``resolution=32`` is about twice as fast and less accurate;
      ``resolution=32, refine=8`` for thin shells.

    A pure JAX function of (points, gamma, nu): jittable (options static), vmappable,
    differentiable in gamma, nu and the points. By default the derivatives in gamma and nu follow
    the trend of the pose over gamma (1 +- 1 %) and nu (1 +- 1 %) (two extra solves per parameter,
    only when differentiated); ``derivative="exact"`` gives the local implicit derivative
    (``docs/design.md``, "How gradients flow"). Concrete points are centered and scaled in
    float64 NumPy first (float16 and integers are computed in float32).

    Raises:
      InvalidInputError: bad points, gamma, nu or option (unknown options are named).

    Example::

        >>> pose = jaxpose.normalize(points)           # points: (m, 3)
        >>> normalized = pose.apply(points)            # center 0, mean distance 1
    """
    config = PoseConfig.create(config, **options)
    _validate.check_points(points)
    _validate.check_gamma(gamma)
    _validate.check_nu(nu)
    shift, size = None, None
    if _validate.is_traced(points):  # pure-JAX path (jit, vmap, grad in points)
        points = jnp.asarray(points)
        if not jnp.issubdtype(points.dtype, jnp.floating):
            points = points.astype(jnp.result_type(float))
    else:
        dtype = _validate.compute_dtype(points)
        shift, size = host_frame(points)
        points = jnp.asarray((np.asarray(points, np.float64) - shift) / size, dtype)
    pose = _pipeline_jit(points, None, gamma, nu, config, _check_rotation(rotation))
    return _finish(pose, shift, size, gamma, nu, throw, config.svdd.tol)


def _check_rotation(rotation):
    if not isinstance(rotation, (bool, np.bool_)):
        raise _validate.InvalidInputError(f"rotation must be True or False, got {rotation!r}")
    return bool(rotation)


def _finish(pose, shift, size, gamma, nu, throw, tol):
    """Map a pose of host-prescaled points back, flag out-of-range traced gamma / nu as not
    valid, and raise on request (concrete results only)."""
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
                    config: PoseConfig | None = None, rotation=False, **options) -> Pose:
    """Normalize many objects with one compilation (padding and masks).

    Args:
      list_of_points: sequence of (m_i, 3) concrete arrays; rows are padded to max(m_i) (or
        ``pad_to``) and masked out of every sum, so results equal :func:`normalize` per object
        up to solver tolerance. Each set is centered and scaled in float64 first.
      gamma, nu: scalars, shared by all objects.
      pad_to: optional row count (>= the largest set) to share one compilation across calls.
      strategy: "vmap" (all objects in lock-step: fills wide accelerators, but every object runs
        as many solver iterations as the slowest), "map" (``lax.map``, one object after another
        inside the compiled call: faster on CPU) or "auto" ("map" on CPU, "vmap" elsewhere).
      config, options, throw, rotation: as :func:`normalize`.

    Returns:
      :class:`Pose` whose fields have a leading axis of len(list_of_points).

    Under jit, use ``jax.vmap(normalize)`` instead (padding needs concrete arrays).
    """
    if strategy not in ("auto", "map", "vmap"):
        raise _validate.InvalidInputError(f"strategy must be 'auto', 'map' or 'vmap', got {strategy!r}")
    if strategy == "auto":
        strategy = "map" if jax.default_backend() == "cpu" else "vmap"
    config = PoseConfig.create(config, **options)
    if len(list_of_points) == 0:
        raise _validate.InvalidInputError("normalize_batch needs at least one point set")
    arrays = [_validate.check_points(p, name=f"points[{i}]") for i, p in enumerate(list_of_points)]
    if any(_validate.is_traced(a) for a in arrays):
        raise _validate.InvalidInputError("normalize_batch needs concrete point sets; under jit, use jax.vmap(normalize)")
    dtype = np.result_type(*[_validate.compute_dtype(a) for a in arrays])
    frames = [host_frame(a, name=f"points[{i}]") for i, a in enumerate(arrays)]
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
    pose = _batched(pts, jnp.asarray(mask), gamma, nu, config=config, strategy=strategy,
                    rotation=_check_rotation(rotation))
    return _finish(pose, shift, size, gamma, nu, throw, config.svdd.tol)


@partial(jax.jit, static_argnames=("config", "strategy", "rotation"))
def _batched(points, mask, gamma, nu, config, strategy, rotation=False):
    fn = lambda p, mk, g, n: pose_pipeline(p, mk, g, n, config, rotation)
    if strategy == "map":
        return jax.lax.map(lambda args: fn(*args), (points, mask, gamma, nu))
    return jax.vmap(fn)(points, mask, gamma, nu)
