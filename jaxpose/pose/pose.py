"""The OCSVM pose (the paper's section 3.2): ``normalize``, ``normalize_batch`` and the one pipeline.

Pipeline (:func:`pose_pipeline`, what every entry point runs): points are put in their reference
frame (:func:`jaxpose.pose.frame.prescale`: centered, divided by their reference size, turned to their
principal axes, so gamma is dimensionless and the grid turns with the object); the SVDD is fitted
there (:func:`jaxpose.occupancy.svdd.solve_svdd`); the region's centroid c_m (eq. 4) and mean distance d_m
(eq. 5) are integrated on a grid (:func:`jaxpose.moments.region_moments`) and mapped back:
center = mean + s_ref axes c_m, scale = s_ref d_m.

Concrete inputs are first centered and scaled on the host in float64 (:func:`jaxpose.pose.frame.host_frame`)
and the offset is added back at the end, so coordinates far from the origin keep their digits.

Cost is bounded: above ``MAX_POINTS`` points a seeded uniform subset is used (``Pose.count`` says
how many); concrete point sets are padded (and masked) to one of four sizes per octave
(:mod:`jaxpose.pose.sizes`), so sets of many sizes share a few compilations. When a pose is valid is
:mod:`jaxpose.pose.validity`'s contract (``Pose.status``).

Derivatives in gamma and nu flow through the SVDD solution (by default its trend: secant slopes
over gamma (1 +- 1 %) and nu (1 +- 1 %); or the implicit KKT derivative; ``PoseConfig.derivative``)
and the grid occupancy, whose derivative is the coarea boundary term. With only two hyperparameters, reverse mode in them is computed from forward-mode
columns (:func:`jaxpose._hyper.hyper_jvp`).
"""
from __future__ import annotations

from functools import partial
import numbers
import warnings
from typing import Iterable

import jax
import jax.numpy as jnp
import numpy as np

from .. import _validate
from .._hyper import hyper_jvp
from ..config import OCSVM, PoseConfig
from .frame import host_frame, prescale
from ..moments import region_moments
from ..orientation import region_frame
from ..occupancy.svdd import solve_svdd
from ..occupancy.svdd.secant import with_secants
from .sizes import MAX_POINTS, bucket, pad, subsample_index
from .result import Pose, Status
from .validity import pose_status

__all__ = ["Pose", "normalize", "normalize_batch", "pose_pipeline", "pose_from_svdd"]


def pose_from_svdd(svdd, to_world, size, grid, outside, rotation=False, y=None, mask=None):
    """The pose (eqs. 4, 5) of an SVDD fitted to pre-scaled points, in world units.

    Args:
      svdd: SVDD in the reference frame; to_world, size: from :func:`jaxpose.pose.frame.prescale`;
      grid: GridConfig; outside: see :func:`jaxpose.moments.region_moments`.
      rotation: also the region's frame (:func:`jaxpose.orientation.region_frame`), from the
        pre-scaled points ``y`` (m, 3) and their ``mask``.
    """
    mom = region_moments(svdd, grid, outside)
    center = to_world(mom.center)
    scale = jnp.where(size > 0, size, 1.0) * mom.mean_distance
    status = pose_status(svdd.points, svdd.mask, svdd.gamma, size, mom, grid.refine, center, scale)
    valid, count = status == 0, jnp.sum(svdd.mask).astype(jnp.int32)
    if not rotation:
        return Pose(center, scale, svdd.converged, valid, svdd.iterations, status=status, count=count)
    origin = to_world(jnp.zeros(3, center.dtype))
    axes = jax.vmap(to_world)(jnp.eye(3, dtype=center.dtype)) - origin  # rows: size * axes[:, k]
    axes = (axes / jnp.linalg.norm(axes, axis=1, keepdims=True)).T
    rot, amb = region_frame(mom.second_moment, mom.center, y, mask, axes)
    return Pose(center, scale, svdd.converged, valid, svdd.iterations, amb, rot, status, count)


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


def normalize(points, gamma=OCSVM.gamma, nu=OCSVM.nu, *, config: PoseConfig | None = None, throw=False, rotation=False,
              max_points=MAX_POINTS, seed=0, **options) -> Pose:
    """The OCSVM pose (center c_m, scale d_m) of surface samples.

    Args:
      points: (m, 3) samples of a surface, any units and offset (float32, float64 or integers).
      gamma: () > 0, dimensionless (for the pre-scaled points, see :mod:`jaxpose.pose.frame`).
      nu: () in [0, 1].
      config: a :class:`jaxpose.config.PoseConfig`; or, as keywords, any of its flat options:
        grid ``resolution`` (64), ``refine`` (2), ``band`` (16384), ``extrapolate``; solver ``tol``
        (1e-3), ``max_iter``, ``check_every``, ``kernel``, ``solver`` (None: "pg" up to 2500
        points, "auto" above, on CPU); ``block`` (both); ``derivative`` ("trend" | "exact" |
        "secant"), ``gamma_delta``, ``nu_delta``, ``secant_iterations``, ``nu_tol``.
      throw: concrete calls only: raise ConvergenceError if the solver hit max_iter,
        JaxposeError naming the reason if the pose is not valid (otherwise an invalid concrete
        pose warns with :class:`jaxpose.InvalidPoseWarning`; see ``Pose.valid``, ``Pose.status``).
      rotation: also the canonical frame of the OCSVM region (``Pose.rotation``, rows = axes,
        det +1; ``Pose.ambiguity``, ``Pose.flagged``; :func:`jaxpose.orientation.region_frame`); off
        by default, and off changes nothing. Not differentiated.
      max_points: int >= 4 or None: above this many points, a uniform random subset of this size
        (``seed``) is fitted (:func:`jaxpose.pose.sizes.subsample_index`; ``Pose.count``); None fits every point.
      seed: int >= 0, the seed of that subset.

    Returns:
      :class:`Pose`. The default grid resolves the boundary like a 128^3 grid, extrapolated with
      the 64^3 level; ``resolution=32`` is about twice as fast and less accurate;
      ``resolution=32, refine=8`` for thin shells.

    A pure JAX function of (points, gamma, nu): jittable (options static), vmappable,
    differentiable in gamma, nu and the points. By default the derivatives in gamma and nu follow
    the trend of the pose over gamma (1 +- 1 %) and nu (1 +- 1 %) (two extra solves per parameter,
    only when differentiated); ``derivative="exact"`` gives the local implicit derivative
    (``docs/design.md``, "How gradients flow"). Concrete points are centered and scaled in
    float64 NumPy first (float16 and integers are computed in float32), then padded to
    :func:`jaxpose.pose.sizes.bucket` rows (masked out), so that sets of many sizes share a few compilations.

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
    rotation, max_points, seed = _check_rotation(rotation), _check_max_points(max_points), _check_seed(seed)
    index = subsample_index(np.shape(points)[0], max_points, seed)
    shift, size, mask = None, None, None
    if _validate.is_traced(points):  # pure-JAX path (jit, vmap, grad in points)
        points = jnp.asarray(points)
        if not jnp.issubdtype(points.dtype, jnp.floating):
            points = points.astype(jnp.result_type(float))
        points = points if index is None else points[index]
    else:
        arr = np.asarray(points) if index is None else np.asarray(points)[index]
        dtype = _validate.compute_dtype(arr)
        shift, size = host_frame(arr)
        points, mask = pad([(np.asarray(arr, np.float64) - shift) / size], bucket(len(arr)), dtype)
        points, mask = points[0], mask[0]
    pose = _pipeline_jit(points, mask, gamma, nu, config, rotation)
    return _finish(pose, shift, size, gamma, nu, throw, config.svdd.tol)


def _check_rotation(rotation):
    if not isinstance(rotation, (bool, np.bool_)):
        raise _validate.InvalidInputError(f"rotation must be True or False, got {rotation!r}")
    return bool(rotation)


def _check_max_points(max_points):
    if max_points is None:
        return None
    if isinstance(max_points, bool) or not isinstance(max_points, numbers.Integral) or max_points < 4:
        raise _validate.InvalidInputError(f"max_points must be an int >= 4 or None, got {max_points!r}")
    return int(max_points)


def _check_seed(seed):
    if isinstance(seed, bool) or not isinstance(seed, numbers.Integral) or seed < 0:
        raise _validate.InvalidInputError(f"seed must be an int >= 0, got {seed!r}")
    return int(seed)


def _finish(pose, shift, size, gamma, nu, throw, tol):
    """Map a pose of host-prescaled points back, flag out-of-range traced gamma / nu as not
    valid, and raise (``throw``) or warn on an invalid concrete result."""
    status = jnp.asarray(pose.status)
    if shift is not None:
        dtype = pose.center.dtype
        center = jnp.asarray(shift, dtype) + jnp.asarray(size, dtype)[..., None] * pose.center
        scale = jnp.asarray(size, dtype) * pose.scale
        finite = jnp.all(jnp.isfinite(center), axis=-1) & jnp.isfinite(scale) & (scale > 0)
        status = jnp.where((status == 0) & ~finite, int(Status.NOT_FINITE), status)
        pose = pose._replace(center=center, scale=scale)
    g, n = jnp.asarray(gamma), jnp.asarray(nu)
    in_range = jnp.isfinite(g) & (g > 0) & jnp.isfinite(n) & (n >= 0) & (n <= 1)
    status = jnp.where(in_range, status, int(Status.BAD_PARAMETERS)).astype(jnp.int32)
    pose = pose._replace(valid=status == 0, status=status)
    if _validate.is_traced(pose.valid):
        return pose
    if throw and not bool(jnp.all(pose.converged)):
        raise _validate.ConvergenceError(
            f"SVDD solver hit its iteration cap ({np.asarray(pose.iterations)} iterations) before tol={tol}"
        )
    if not bool(jnp.all(pose.valid)):
        codes = np.asarray(status).reshape(-1)
        bad = int(np.flatnonzero(codes)[0])
        which = f"point set {bad}: " if np.ndim(status) else ""
        message = f"no valid pose ({which}{Status(int(codes[bad])).message})"
        if throw:
            raise _validate.JaxposeError(message)
        warnings.warn(message + "; see Pose.status", _validate.InvalidPoseWarning, stacklevel=3)
    return pose


def normalize_batch(list_of_points: Iterable, gamma=OCSVM.gamma, nu=OCSVM.nu, *, pad_to=None, throw=False, strategy="auto",
                    config: PoseConfig | None = None, rotation=False, max_points=MAX_POINTS, seed=0,
                    **options) -> Pose:
    """Normalize many objects with one compilation (padding and masks).

    Args:
      list_of_points: an iterable (list, tuple, generator, ...) of (m_i, 3) concrete arrays; rows
        are padded to :func:`jaxpose.pose.sizes.bucket` (max(m_i)) (or ``pad_to``) and masked out of every sum, so
        results equal :func:`normalize` per object up to solver tolerance. Each set is centered
        and scaled in float64 first.
      gamma, nu: scalars, shared by all objects.
      pad_to: optional row count (>= the largest set) to share one compilation across calls.
      strategy: "vmap" (all objects in lock-step: fills wide accelerators, but every object runs
        as many solver iterations as the slowest), "map" (``lax.map``, one object after another
        inside the compiled call: faster on CPU) or "auto" ("map" on CPU, "vmap" elsewhere).
      config, options, throw, rotation, max_points, seed: as :func:`normalize` (each set above
        ``max_points`` is subsampled).

    Returns:
      :class:`Pose` whose fields have a leading axis of len(list_of_points).

    Raises:
      InvalidInputError: not an iterable of point sets, an empty one, a bad set (named by its
        index) or option.

    Under jit, use ``jax.vmap(normalize)`` instead (padding needs concrete arrays).
    """
    if strategy not in ("auto", "map", "vmap"):
        raise _validate.InvalidInputError(f"strategy must be 'auto', 'map' or 'vmap', got {strategy!r}")
    if strategy == "auto":
        strategy = "map" if jax.default_backend() == "cpu" else "vmap"
    config = PoseConfig.create(config, **options)
    _validate.check_gamma(gamma)
    _validate.check_nu(nu)
    rotation, max_points, seed = _check_rotation(rotation), _check_max_points(max_points), _check_seed(seed)
    if pad_to is not None and (isinstance(pad_to, bool) or not isinstance(pad_to, numbers.Integral)):
        raise _validate.InvalidInputError(f"pad_to must be an int or None, got {pad_to!r}")
    if isinstance(list_of_points, (str, bytes)) or not isinstance(list_of_points, Iterable):
        raise _validate.InvalidInputError(
            f"list_of_points must be an iterable of (m, 3) point sets, got {type(list_of_points).__name__}")
    arrays = [_validate.check_points(p, name=f"points[{i}]") for i, p in enumerate(list_of_points)]
    if not arrays:
        raise _validate.InvalidInputError("normalize_batch needs at least one point set")
    if any(_validate.is_traced(a) for a in arrays):
        raise _validate.InvalidInputError("normalize_batch needs concrete point sets; under jit, use jax.vmap(normalize)")
    arrays = [np.asarray(a) if (k := subsample_index(len(a), max_points, seed)) is None else np.asarray(a)[k]
              for a in arrays]
    dtype = np.result_type(*[_validate.compute_dtype(a) for a in arrays])
    frames = [host_frame(a, name=f"points[{i}]") for i, a in enumerate(arrays)]
    arrays = [(np.asarray(a, np.float64) - c) / r for a, (c, r) in zip(arrays, frames)]
    shift, size = np.stack([c for c, _ in frames]), np.asarray([r for _, r in frames])
    largest = max(a.shape[0] for a in arrays)
    m = bucket(largest) if pad_to is None else int(pad_to)
    if m < largest:
        raise _validate.InvalidInputError(f"pad_to={m} is smaller than the largest point set ({largest} points)")
    pts, mask = pad(arrays, m, dtype)
    gamma = jnp.broadcast_to(jnp.asarray(gamma, pts.dtype), (len(arrays),))
    nu = jnp.broadcast_to(jnp.asarray(nu, pts.dtype), (len(arrays),))
    pose = _batched(pts, mask, gamma, nu, config=config, strategy=strategy, rotation=rotation)
    return _finish(pose, shift, size, gamma, nu, throw, config.svdd.tol)


@partial(jax.jit, static_argnames=("config", "strategy", "rotation"))
def _batched(points, mask, gamma, nu, config, strategy, rotation=False):
    fn = lambda p, mk, g, n: pose_pipeline(p, mk, g, n, config, rotation)
    if strategy == "map":
        return jax.lax.map(lambda args: fn(*args), (points, mask, gamma, nu))
    return jax.vmap(fn)(points, mask, gamma, nu)
