"""``normalize`` and ``normalize_batch``: the pose of a point cloud by the robust estimator (the
default) or the paper's OCSVM (section 3.2), both pure JAX.

``method="robust"`` (:func:`robust_pipeline`): the robust voxel solid of the points
(:mod:`jaxpose.occupancy.points`), the depth^p-weighted centroid of its voxels and the cube root of
its volume. ``method="ocsvm"`` (:func:`pose_pipeline`, below). Options of the other method are
refused by name.

OCSVM pipeline (:func:`pose_pipeline`): points are put in their reference
frame (:func:`jaxpose.pose.frame.prescale`: centered, divided by their reference size, turned to their
principal axes, so gamma is dimensionless and the grid turns with the object); the SVDD is fitted
there (:func:`jaxpose.occupancy.svdd.solve_svdd`); the region's centroid c_m (eq. 4) and mean distance d_m
(eq. 5) are integrated on a grid (:func:`jaxpose.moments.region_moments`) and mapped back:
center = mean + s_ref axes c_m, scale = s_ref d_m.

Far from the origin. Concrete inputs (both methods) are first centered and scaled on the host in
float64 (:func:`jaxpose.pose.frame.host_frame`) and the pose is mapped back on the host in float64 (its
center and scale are float64 NumPy), so coordinates far from the origin keep every digit the
result can hold. A traced input cannot be moved first: when its coordinates are rounded by more
than ``MAX_ROUNDING`` of its spread, the pose is flagged (``Status.FAR_FROM_ORIGIN``, not valid).

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

import dataclasses
from functools import partial
import numbers
import os
import warnings
from typing import Iterable, Mapping

import jax
import jax.numpy as jnp
import numpy as np

from .. import _validate
from .._hyper import hyper_jvp
from ..config import OCSVM, ROBUST, PoseConfig, RobustConfig, SolverConfig
from ..moments import region_moments, robust_moments
from ..occupancy.points import POINT_BIAS, erode6, point_solid, spacing_subset
from ..occupancy.svdd import solve_svdd
from ..occupancy.svdd.problem import parameters_in_range
from ..occupancy.svdd.secant import with_secants
from ..orientation import region_frame
from .frame import host_frame, prescale
from .sizes import MAX_POINTS, bucket, pad, subsample_index
from .result import MIN_POINT_VOXELS, SECOND_BODY, Pose, Status, _register_pytree
from .validity import flag_offset, flag_range, no_extent, pose_status

__all__ = ["Pose", "METHODS", "DEFAULT_METHOD", "normalize", "normalize_batch", "chained_map", "pose_pipeline", "robust_pipeline",
           "pose_from_svdd", "frame_ocsvm", "FRAME"]

_register_pytree()  # (JAX is imported: Pose's rebuilds skip its constructor's casts)

METHODS = ("robust", "ocsvm")
FRAME = "frame"  # the pipeline's rotation argument of frame_ocsvm: the frame and its diagnostics
DEFAULT_METHOD = "robust"
_SHARED = ("resolution",)  # a grid resolution in both (voxels / OCSVM grid cells)
_ONLY = {  # keyword -> the method it belongs to (any other method refuses it)
    **{k: "ocsvm" for k in ("gamma", "nu", "max_points") + PoseConfig.FLAT if k not in _SHARED},
    **{k: "robust" for k in ("power",) + RobustConfig.FLAT if k not in _SHARED},
}
_UNSET = object()


def pose_from_svdd(svdd, to_world, size, grid, outside, rotation=False, y=None, mask=None):
    """The pose (eqs. 4, 5) of an SVDD fitted to pre-scaled points, in world units.

    Args:
      svdd: SVDD in the reference frame; to_world, size: from :func:`jaxpose.pose.frame.prescale`;
      grid: GridConfig; outside: see :func:`jaxpose.moments.region_moments`.
      rotation: also the region's frame (:func:`jaxpose.orientation.region_frame`), from the
        pre-scaled points ``y`` (m, 3) and their ``mask``; ``"frame"``: that, and return
        (pose, the frame's diagnostics) with the eigenvalues in the units of ``y``'s input
        squared (:data:`FRAME`).
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
    if rotation == FRAME:
        rot, amb, diagnostics = region_frame(mom.second_moment, mom.center, y, mask, axes, report=True)
        diagnostics["eigenvalues"] = diagnostics["eigenvalues"] * jnp.where(size > 0, size, 1.0) ** 2
        return Pose(center, scale, svdd.converged, valid, svdd.iterations, amb, rot, status, count), diagnostics
    rot, amb = region_frame(mom.second_moment, mom.center, y, mask, axes)
    return Pose(center, scale, svdd.converged, valid, svdd.iterations, amb, rot, status, count)


def _pipeline(points, mask, gamma, nu, stops, config, rotation=False):
    tol, max_iter, secant_tol = stops
    y, to_world, size = prescale(points, mask)
    extra = {"rotation": rotation, "y": y, "mask": mask} if rotation else {}
    if config.derivative == "exact":
        svdd = solve_svdd(y, gamma, nu, mask, None, config.svdd, tol, max_iter)
        # the implicit KKT derivative moves alpha only on the support: skip the alpha = 0 pass
        return pose_from_svdd(svdd, to_world, size, config.grid, outside=False, **extra)
    dtype = y.dtype
    gamma, nu = jnp.asarray(gamma, dtype), jnp.asarray(nu, dtype)
    sg = jax.lax.stop_gradient
    params = ("gamma", "nu") if config.derivative == "trend" else ("nu",)  # "secant": gamma implicit
    svdd = solve_svdd(y, sg(gamma) if "gamma" in params else gamma, sg(nu), mask, None, config.svdd, tol, max_iter)
    svdd = with_secants(svdd, gamma, nu, config.svdd, params, (config.gamma_delta, config.nu_delta),
                        secant_tol, config.secant_iterations, max_iter)
    return pose_from_svdd(svdd, to_world, size, config.grid, outside=True, **extra)  # the secant moves alpha = 0 points


def pose_pipeline(points, mask, gamma, nu, config: PoseConfig, rotation: bool = False) -> Pose:
    """The one pipeline from points to a Pose (module docs); pure JAX, no input checks.

    Args:
      points: (m, 3) float; mask: (m,) bool or None (False rows are padding);
      gamma, nu: () traced; config: :class:`jaxpose.config.PoseConfig` (static);
      rotation: (static) also the region's canonical frame (``Pose.rotation``, ``Pose.ambiguity``;
        not differentiated).

    Returns:
      Pose in the units of ``points``, its status that of :func:`jaxpose.pose.validity.pose_status`,
      OUT_OF_RANGE where the points' reference size is beyond their dtype
      (:func:`jaxpose.pose.validity.unresolved_size`) and FAR_FROM_ORIGIN where their offset is
      (:func:`jaxpose.pose.validity.unresolved_offset`). Derivatives in (gamma, nu) come from
      forward-mode columns, also under jax.grad / jacrev; derivatives in the points by plain autodiff.
    """
    return _stopped_pipeline(points, mask, gamma, nu, _stops(config), _without_stops(config), rotation)


def _stops(config: PoseConfig) -> tuple:
    """The stopping numbers of a config's solves: (tol, max_iter, the secant solves' tol)."""
    return config.svdd.tol, config.svdd.max_iter, config.secant_tol()


def _without_stops(config: PoseConfig) -> PoseConfig:
    """``config`` with the numbers :func:`_stops` reads set to their defaults: the static key of
    the compiled pipeline, so that configs that differ only in them share one program."""
    svdd = dataclasses.replace(config.svdd, tol=SolverConfig.tol, max_iter=SolverConfig.max_iter)
    return dataclasses.replace(config, svdd=svdd, nu_tol=None)


def _stopped_pipeline(points, mask, gamma, nu, stops, config, rotation=False):
    """:func:`pose_pipeline` with the stopping numbers ``stops`` (:func:`_stops`; traced in the
    compiled programs below) given apart from ``config`` (whose own are not read)."""
    rotation = FRAME if rotation == FRAME else bool(rotation)
    pose = hyper_jvp(partial(_pipeline, config=config, rotation=rotation), (2, 3))(points, mask, gamma, nu, stops)
    if rotation == FRAME:  # (pose, the frame's diagnostics): frame_ocsvm's program
        return flag_offset(flag_range(pose[0], points, mask), points, mask), pose[1]
    return flag_offset(flag_range(pose, points, mask), points, mask)


def robust_pipeline(points, mask, queries, query_mask, power, config: RobustConfig) -> Pose:
    """The robust pose of a point cloud; pure JAX, no input checks.

    Args:
      points: (n, 3) float; mask: (n,) bool or None (False rows are padding).
      queries, query_mask: (m,) int and (m,) bool or None, the points whose spacing is measured
        (:func:`jaxpose.occupancy.points.spacing_subset`).
      power: () depth exponent p >= 0 (traced, differentiable).
      config: :class:`jaxpose.config.RobustConfig` (static).

    Returns:
      Pose: center (3,) = sum_v d_v^p x_v / sum_v d_v^p over the kept voxels, scale () = V^(1/3),
      in the units of ``points``; ``converged`` True, ``iterations`` the closing radius in voxels,
      ``status`` EMPTY_SOLID when the points enclose no volume (no voxel of the solid lies deeper
      than its surface layer: an open sheet, a scan of one side), SPARSE_CLOUD when the solid spans
      fewer than ``MIN_POINT_VOXELS`` voxels (too sparse for a closing), SEPARATE_BODIES when a
      separate part of the points holds at least ``SECOND_BODY`` of the largest's occupied voxels
      (:func:`jaxpose.occupancy.points.linked_parts`), OUT_OF_RANGE when the points' size is beyond
      what their dtype computes a volume in (the solid has voxels, its volume in the points' units
      under- or overflows: in float32 extents outside about 1e-11 ... 1e12), DEGENERATE_INPUT,
      NOT_FINITE, FAR_FROM_ORIGIN (see :mod:`jaxpose.pose.validity`); ``count`` the points used.
    """
    n = points.shape[0]
    mask = jnp.ones((n,), bool) if mask is None else jnp.asarray(mask, bool)
    sol = point_solid(points, mask, queries, config, query_mask)
    power = jnp.asarray(power, points.dtype)
    inside = sol.inside
    corner, unit = jnp.zeros(3, power.dtype), jnp.ones((), power.dtype)  # voxel units from the corner
    mom = robust_moments(inside, sol.occupied, corner, unit, power, POINT_BIAS)
    center = sol.origin + sol.pitch * mom.center
    volume = mom.volume * sol.pitch**3
    # cbrt(max(volume, 0)) (NaN kept), without cbrt's infinite slope at 0 (a NaN derivative)
    scale = jnp.where(volume > 0, jnp.cbrt(jnp.where(volume > 0, volume, 1.0)), jnp.where(jnp.isnan(volume), volume, 0.0))
    sg = jax.lax.stop_gradient
    degenerate = no_extent(points, mask)
    finite = jnp.all(jnp.isfinite(center)) & jnp.isfinite(scale) & (scale > 0)
    bad_power = ~(jnp.isfinite(sg(power)) & (sg(power) >= 0))
    # no voxel deeper than the surface layer (distance <= POINT_BIAS: a face neighbour outside): a sheet
    shallow = ~jnp.any(erode6(inside))
    cells = [jnp.any(inside, axis=tuple(b for b in range(3) if b != a)) for a in range(3)]
    idx = [jnp.arange(c.shape[0]) for c in cells]
    across = jnp.max(jnp.stack([jnp.max(jnp.where(c, i, -1)) - jnp.min(jnp.where(c, i, c.shape[0])) + 1
                                for c, i in zip(cells, idx)]))
    several = sol.second_part >= SECOND_BODY
    # voxels, but no volume the dtype holds: the points' size cubed under- or overflows it (float32:
    # extents beyond about 1e-11 ... 1e12; a NaN pitch where their squares overflow)
    out_of_range = (mom.volume > 0) & ~(jnp.isfinite(volume) & (volume > 0))
    status = jnp.select([bad_power, degenerate, out_of_range, ~(volume > 0) | shallow, across < MIN_POINT_VOXELS,
                         several, ~finite],
                        [jnp.int32(int(c)) for c in (Status.BAD_PARAMETERS, Status.DEGENERATE_INPUT,
                                                      Status.OUT_OF_RANGE, Status.EMPTY_SOLID, Status.SPARSE_CLOUD,
                                                      Status.SEPARATE_BODIES, Status.NOT_FINITE)],
                        jnp.int32(0))
    pose = Pose(center, scale, jnp.asarray(True), status == 0, sol.radius, None, None, status,
                jnp.sum(mask).astype(jnp.int32))
    return flag_offset(pose, points, mask)


# XLA:CPU rewrites each reduction over more than 32 entries that it keeps for itself (here those of
# booleans and integers: any, all, counts, integer maxima; none of the robust program's float ones)
# into a chain of reduce-window stages, each a kernel of its own to compile, and the stages do not
# fuse with the reduced expression. Integer and boolean reductions give the same result in any
# order, so the robust programs switch that pass off (the GPU's tree reduction pass has another
# name). The OCSVM programs keep it: they hold a float sum it rewrites (a different order).
# Compiler options belong to a top-level program only: a call staged into an enclosing trace (a
# traced argument; jit or eval_shape around a concrete call) takes the plain program (_staged).
_EXACT_REDUCTIONS = {"xla_disable_hlo_passes": "tree_reduction_rewriter"}
_pipeline_jit = jax.jit(_stopped_pipeline, static_argnames=("config", "rotation"))
_robust_jit = jax.jit(robust_pipeline, static_argnames=("config",), compiler_options=_EXACT_REDUCTIONS)
_robust_staged = jax.jit(robust_pipeline, static_argnames=("config",))


def _top_level(program, staged, *args, **kwargs):
    """``program(*args, **kwargs)`` (compiled with ``_EXACT_REDUCTIONS``), or ``staged`` (the same
    function jitted without options) where the call is staged into an enclosing trace, whose
    compilation JAX leaves to the caller's options (it refuses a nested program's)."""
    # staged: a traced argument, or jit / eval_shape around the call, where (JAX stages every
    # operation inside a trace) even a new constant is a tracer
    if any(_validate.is_traced(a) for a in jax.tree.leaves((args, kwargs))) or _validate.is_traced(jnp.zeros(())):
        return staged(*args, **kwargs)
    return program(*args, **kwargs)


def _check_method(method):
    if method is None:  # the default, as normalize_mesh's and estimate's None (it was refused)
        return DEFAULT_METHOD
    if not _validate.is_name(method, METHODS):
        hint = (" (gamma and nu are keywords: normalize(points, method='ocsvm', gamma=..., nu=...))"
                if isinstance(method, numbers.Number) else "")
        raise _validate.InvalidInputError(f"method must be one of {', '.join(map(repr, METHODS))}, "
                                          f"got {method!r}{hint}")
    return method


def _options(method, config, given, rotation):
    """(the static config of ``method``, its traced parameters) from the keywords of normalize.

    ``given``: every keyword the caller passed (unset ones left out). Refuses, naming the method
    it belongs to, any keyword of the other method.
    """
    for key in given:
        owner = _ONLY.get(key)
        if owner is not None and owner != method:
            raise _validate.InvalidInputError(
                f"{key} is an option of method={owner!r}; method={method!r} does not use it (pass "
                f"method={owner!r} or leave {key} out)")
    if method == "robust":
        if config is not None and not isinstance(config, RobustConfig):
            raise _validate.InvalidInputError(f"config must be a RobustConfig for method='robust', got "
                                              f"{type(config).__name__}")
        if rotation:
            raise _validate.InvalidInputError(
                "rotation=True is not available with method='robust' in normalize; use "
                "jaxpose.normalize_mesh(points, rotation=True), or method='ocsvm'")
        flat = {k: v for k, v in given.items() if k != "power"}
        return RobustConfig.create(config, **flat), {"power": given.get("power", ROBUST.power)}
    if config is not None and not isinstance(config, PoseConfig):
        raise _validate.InvalidInputError(f"config must be a PoseConfig for method='ocsvm', got "
                                          f"{type(config).__name__}")
    flat = {k: v for k, v in given.items() if k not in ("gamma", "nu", "max_points")}
    return PoseConfig.create(config, **flat), {"gamma": given.get("gamma", OCSVM.gamma), "nu": given.get("nu", OCSVM.nu)}


def _check_params(method, params, given):
    """Check the method's concrete parameters (power; gamma, nu, max_points; traced ones pass) and
    return how many points a set may have before it is subsampled (None: no limit; robust)."""
    if method == "robust":
        _validate.check_power(params["power"])  # a () array of reals is checked as its number
        return None
    _validate.check_gamma(params["gamma"])
    _validate.check_nu(params["nu"])
    return _check_max_points(given.get("max_points", MAX_POINTS))


def _given(**kwargs):
    return {k: v for k, v in kwargs.items() if v is not _UNSET}


def _points_argument(points, options):
    """normalize's points, also when named by the keyword ``x`` (popped from ``options``): the
    argument's name until it followed the documented API, ``normalize(points, ...)``; warns."""
    if "x" in options:
        if points is not _UNSET:
            raise _validate.InvalidInputError("normalize: the points are given twice (points and x); name them points")
        warnings.warn("normalize(x=...) is deprecated: the argument is named points, normalize(points=...)",
                      DeprecationWarning, stacklevel=3)
        return options.pop("x")
    if points is _UNSET:
        raise TypeError("normalize() missing its points: normalize(points, method=...), points an (m, 3) array")
    return points


def normalize(points=_UNSET, method: str | None = DEFAULT_METHOD, *, power=_UNSET, gamma=_UNSET, nu=_UNSET, config=None,
              throw=False, rotation=False, max_points=_UNSET, seed=0, **options) -> Pose:
    """The pose (center, scale) of a point cloud: the robust estimator (default) or the OCSVM.

    Args:
      points: (m, 3) points (samples of a surface, or a scan's vertices), any units and offset
        (float32, float64; float16, bfloat16 and integers are promoted, concrete or traced alike:
        :func:`jaxpose._validate.compute_dtype`); concrete or traced. The keyword ``x=`` (its
        name before it followed the documented API) still works and warns (DeprecationWarning).
      method: ``"robust"`` (default, also for None: the depth^p-weighted centroid of the points'
        robust voxel solid and its volume's cube root, :func:`robust_pipeline`; the same default as
        :func:`jaxpose.normalize_mesh`) or ``"ocsvm"`` (the paper's centroid c_m and mean
        distance d_m of the OCSVM region, :func:`pose_pipeline`).
      power: robust only: () depth exponent p >= 0 (default 4; traced and differentiable).
      gamma, nu: ocsvm only: () gamma > 0 dimensionless (for the pre-scaled points,
        :mod:`jaxpose.pose.frame`; default 47), nu in [0, 1] (default 0.5); traced and differentiable.
      config: a :class:`jaxpose.config.RobustConfig` (robust) or :class:`jaxpose.config.PoseConfig`
        (ocsvm); or, as keywords, its flat options. Robust: ``resolution`` (96 voxels along the main
        body's largest extent), ``coarse``, ``keep_ratio``, ``max_closing``, ``spacing_samples``.
        OCSVM: grid ``resolution`` (64), ``refine``, ``band``, ``extrapolate``; solver ``tol``,
        ``max_iter``, ``check_every``, ``kernel``, ``solver``; ``block``; ``derivative``
        ("trend" | "exact" | "secant"), ``gamma_delta``, ``nu_delta``, ``secant_iterations``,
        ``nu_tol``. An option of the other method is refused (InvalidInputError naming it).
      throw: raise JaxposeError naming the reason if the pose is not valid (and, for ocsvm,
        ConvergenceError if the solver hit max_iter); otherwise an invalid concrete pose warns with
        :class:`jaxpose.InvalidPoseWarning`. Concrete calls only: where the pose is traced (traced
        points or parameters, or a call inside ``jit``) no exception can read it, and
        ``throw=True`` is refused while tracing (InvalidInputError; read ``Pose.valid`` /
        ``Pose.status`` there, :func:`jaxpose._validate.check_throw`).
      rotation: ocsvm only: also the canonical frame of the OCSVM region (``Pose.rotation``,
        ``Pose.ambiguity``); off changes nothing. Not differentiated.
      max_points: ocsvm only: int >= 4 or None: above this many points (default 4096) a seeded
        uniform subset is fitted (:func:`jaxpose.pose.sizes.subsample_index`; ``Pose.count``).
      seed: int >= 0 (a Python or NumPy integer, or a concrete () integer array, JAX's too): the
        seed of that subset (ocsvm) or of the subset whose spacing is measured
        (robust, above ``spacing_samples`` points).

    Returns:
      :class:`Pose` in the input's units. For a concrete input its center and scale are float64
      NumPy (mapped back on the host, every digit kept far from the origin); for a traced input,
      JAX arrays. ``Pose.valid`` / ``Pose.status`` say whether to trust it
      (:mod:`jaxpose.pose.validity`; a traced input too far from the origin for its dtype is
      ``FAR_FROM_ORIGIN``; one too small or too large for its dtype, ``OUT_OF_RANGE``: robust,
      where its volume under- or overflows, in float32 extents outside about 1e-11 ... 1e12;
      ocsvm, where the squares of its reference size (the RMS distance from the mean) under- or
      overflow, in float32 an RMS distance outside 4.2e-18 ... 1.8e19 / sqrt(m) for m points
      (:func:`jaxpose.pose.validity.unresolved_size`); a concrete input is rescaled on the host in
      float64 and is not flagged so: it is refused (InvalidInputError) only where its compute dtype
      cannot hold its coordinates or its spread at all (float32: coordinates above 3.4e38, an RMS
      spread below 1.2e-38; :func:`jaxpose.host.host_frame`)).

    Pure JAX in (points, power) or (points, gamma, nu): jittable (options static), vmappable. Derivatives:
    robust, in ``power`` (exact) and in the points through the grid's position and pitch (the
    voxel occupancy is piecewise constant); ocsvm, in gamma and nu (by default the trend over
    +-1 %, ``docs/design.md``) and in the points. Concrete points are centered and scaled in
    float64 NumPy first and padded to :func:`jaxpose.pose.sizes.bucket` rows (masked out), so sets of
    many sizes share a few compilations.

    Raises:
      InvalidInputError: bad points, method, parameter or option (unknown options and options of
        the other method are named).

    Example::

        pose = jaxpose.normalize(points)                        # robust, points: (m, 3)
        pose = jaxpose.normalize(points, method="ocsvm", gamma=20.0)
        normalized = pose.apply(points)
    """
    x = _points_argument(points, options)
    method = _check_method(method)
    given = {**_given(power=power, gamma=gamma, nu=nu, max_points=max_points), **options}
    config, params = _options(method, config, given, rotation)
    _validate.check_points(x)
    rotation = _validate.check_bool(rotation, "rotation")
    throw = _validate.check_throw(throw, points=x, **params)
    seed = _validate.check_int(seed, "seed", 0)
    index = subsample_index(np.shape(x)[0], _check_params(method, params, given), seed)
    shift, size, mask = None, None, None
    if _validate.is_traced(x):  # pure-JAX path (jit, vmap, grad in points)
        points = jnp.asarray(x)
        points = points.astype(_validate.compute_dtype(points))  # as a concrete input's (float16: float32)
        points = points if index is None else points[index]
    else:
        arr = np.asarray(x) if index is None else np.asarray(x)[index]
        dtype = _validate.compute_dtype(arr)
        shift, size = host_frame(arr)
        points, mask = pad([(np.asarray(arr, np.float64) - shift) / size], bucket(len(arr)), dtype)
        points, mask = points[0], mask[0]
    if method == "robust":
        queries, query_mask = _queries([np.shape(x)[0]], config.spacing_samples, seed)
        pose = _top_level(_robust_jit, _robust_staged, points, mask, queries[0], query_mask[0],
                          _as_argument(params["power"], points.dtype), config)
        return _finish(pose, shift, size, throw)
    gamma, nu = (_as_argument(params[k], points.dtype) for k in ("gamma", "nu"))
    pose = _pipeline_jit(points, mask, gamma, nu, _stops(config), _without_stops(config), rotation)
    return _finish(pose, shift, size, throw, gamma, nu, config.svdd.tol)


def frame_ocsvm(points, *, gamma=_UNSET, nu=_UNSET, config=None, throw=False, max_points=_UNSET, seed=0,
                **options):
    """``normalize(points, method="ocsvm", rotation=True, ...)`` of concrete points, and its frame's
    diagnostics: what :func:`jaxpose.rotation.rotation.frame_of` reports for ``ocsvm``.

    One program of its own (the pipeline with ``rotation=FRAME``; normalize's programs are not
    touched): the same solve, region and frame as normalize's, whose rotation and ambiguity it
    returns unchanged, with the values :func:`jaxpose.orientation.region_frame` computes on the way.

    Args:
      points: (m, 3) concrete points; gamma, nu, config, throw, max_points, seed, options: as
        :func:`normalize`'s for ``method="ocsvm"``.

    Returns:
      (pose, diagnostics): the :class:`Pose` normalize returns (rotation and ambiguity included);
      diagnostics a dict of NumPy values: ``eigenvalues`` (3,) float64, the region's second
      moments along its axes, largest first, in the input's units squared; ``stat`` (3,) the
      signed third moments E[z^3] / r^3 of the points along those axes before the sign flips;
      ``completed`` int, the axis whose sign det = +1 set; ``ok`` bool, False where the frame was
      not finite (rotation: the identity, ambiguity 1).

    Raises:
      InvalidInputError: as :func:`normalize`; traced points (the diagnostics are host values).
    """
    if _validate.is_traced(points):
        raise _validate.InvalidInputError("frame_ocsvm takes concrete points; use normalize(rotation=True) "
                                          "under jit")
    given = {**_given(gamma=gamma, nu=nu, max_points=max_points), **options}
    config, params = _options("ocsvm", config, given, True)
    _validate.check_points(points)
    throw = _validate.check_throw(throw, **params)
    seed = _validate.check_int(seed, "seed", 0)
    index = subsample_index(np.shape(points)[0], _check_params("ocsvm", params, given), seed)
    arr = np.asarray(points) if index is None else np.asarray(points)[index]
    shift, size = host_frame(arr)
    x, mask = pad([(np.asarray(arr, np.float64) - shift) / size], bucket(len(arr)), _validate.compute_dtype(arr))
    gamma, nu = (_as_argument(params[k], x[0].dtype) for k in ("gamma", "nu"))
    pose, found = _pipeline_jit(x[0], mask[0], gamma, nu, _stops(config), _without_stops(config), FRAME)
    pose = _finish(pose, shift, size, throw, gamma, nu, config.svdd.tol)
    diagnostics = {"eigenvalues": np.asarray(found["eigenvalues"], np.float64) * np.float64(size) ** 2,
                   "stat": np.asarray(found["stat"], np.float64), "completed": int(found["completed"]),
                   "ok": bool(found["ok"])}
    return pose, diagnostics


def _as_argument(value, dtype):
    """A concrete parameter (power; gamma, nu) as a () NumPy array of the ``dtype`` the pipeline
    computes it in (a traced one as it is): a Python float or int, a NumPy or a JAX scalar then
    reach the compiled pipeline as one argument type and share its compilation (a Python float is
    a weak-typed argument, an int an integer one, a NumPy float64 a strong-typed one: each was a
    compilation of its own), with the same values (the pipeline casts them to ``dtype``)."""
    return value if _validate.is_traced(value) else np.asarray(value, dtype)


def _queries(counts, samples, seed):
    """The spacing subsets of point sets of ``counts`` points (:func:`spacing_subset`), padded to
    one bucketed length: (n, q) int32 indices and (n, q) bool mask."""
    subsets = [spacing_subset(int(c), samples, seed) for c in counts]
    q = bucket(max(len(s) for s in subsets))
    queries = np.zeros((len(subsets), q), np.int32)
    query_mask = np.zeros((len(subsets), q), bool)
    for i, s in enumerate(subsets):
        queries[i, : len(s)], query_mask[i, : len(s)] = s, True
    return jnp.asarray(queries), jnp.asarray(query_mask)


def _check_max_points(max_points):
    if max_points is None:
        return None
    return _validate.check_int(max_points, "max_points", 4)


def _finish(pose, shift, size, throw, gamma=None, nu=None, tol=None):
    """Map a pose of host-prescaled points back to the input's units in float64 on the host (its
    center and scale become NumPy float64), flag out-of-range traced gamma / nu (ocsvm) as not
    valid, and raise (``throw``) or warn on an invalid concrete result. Its JAX float fields are in
    JAX's default float dtype (the Pose policy: float64 under x64 whatever the points' dtype, as
    for every method), a traced result's center and scale too, a concrete one's rotation and
    ambiguity too; ``status``, ``iterations`` and ``count`` are int32, traced or not."""
    status = jnp.asarray(pose.status)
    default = jnp.result_type(float)
    if shift is not None:
        size = np.asarray(size, np.float64)
        if _validate.is_traced(pose.center) or _validate.is_traced(pose.scale):  # traced parameters
            xp, shift, size = jnp, jnp.asarray(shift, default), jnp.asarray(size, default)
        else:
            xp = np
        center = shift + size[..., None] * xp.asarray(pose.center, np.float64 if xp is np else default)
        scale = size * xp.asarray(pose.scale, np.float64 if xp is np else default)
        finite = xp.all(xp.isfinite(center), axis=-1) & xp.isfinite(scale) & (scale > 0)
        status = jnp.where((status == 0) & ~jnp.asarray(finite), int(Status.NOT_FINITE), status)
        pose = pose._replace(center=center, scale=scale)
    if gamma is not None:
        status = jnp.where(parameters_in_range(gamma, nu), status, int(Status.BAD_PARAMETERS))
    status = status.astype(jnp.int32)
    counts = {k: jnp.asarray(getattr(pose, k)).astype(jnp.int32) for k in ("iterations", "count")
              if getattr(pose, k) is not None}  # int32, every method (the OCSVM's iterations were int64 under x64)
    traced = _validate.is_traced(status)  # traced points or parameters
    floats = {k: jnp.asarray(getattr(pose, k), default)  # concrete: center and scale stay NumPy float64
              for k in (("center", "scale") if traced else ()) + ("ambiguity", "rotation") if getattr(pose, k) is not None}
    pose = pose._replace(valid=status == 0, status=status, **counts, **floats)
    if traced:
        return pose
    if throw and tol is not None and not bool(jnp.all(pose.converged)):
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


def normalize_batch(list_of_points: Iterable, method: str | None = DEFAULT_METHOD, *, power=_UNSET, gamma=_UNSET,
                    nu=_UNSET, pad_to=None, throw=False, strategy="auto", config=None, rotation=False,
                    max_points=_UNSET, seed=0, **options) -> Pose:
    """Normalize many point clouds in one compiled call: padded to one row count, masked, and mapped.

    Args:
      list_of_points: an iterable (list, tuple, generator, ...) of (m_i, 3) concrete arrays; rows
        are padded (to ``pad_to``, or to :func:`jaxpose.pose.sizes.bucket` (max(m_i))) and masked out of every sum, so results equal :func:`normalize` per object (up to
        the OCSVM solver's tolerance). Each set is centered and scaled in float64 first.
      method, power, gamma, nu, config, options, throw, rotation, max_points, seed: as
        :func:`normalize` (shared by all objects; each set above ``max_points`` is subsampled).
      pad_to: optional row count (an int >= the largest set's size, after ``max_points``) to share
        one compilation across calls.
      strategy: "vmap" (all objects in lock-step: one program over the batch), "map"
        (``lax.map``, one object after another inside the compiled call; on CPU the batch is cut
        into as many independent ``lax.map`` chains as the process has cores, at most
        ``MAX_CHAINS`` (each chain is one more copy of the pipeline to compile), which XLA runs
        concurrently, :func:`chained_map`) or "auto" ("map" on CPU, "vmap" elsewhere: on CPU
        lock-step brings no parallelism, and every object runs as many solver iterations (ocsvm)
        or closing, labelling and distance rounds (robust) as the slowest; ``docs/performance.md``).

    Returns:
      :class:`Pose` whose fields have a leading axis of len(list_of_points).

    Raises:
      InvalidInputError: not an iterable of point sets (a mapping is refused: pass its values;
        one (m, 3) array too: pass ``[points]``), an empty one, a bad set (named by its index) or
        option.

    Under jit, use ``jax.vmap(normalize)`` instead (padding needs concrete arrays).

    Example::

        clouds = [jaxpose.sample_surface(mesh, m, seed=s) for s, m in ((0, 900), (1, 1000))]
        poses = jaxpose.normalize_batch(clouds)   # robust, one compiled call for both
        poses.center.shape, poses.scale.shape     # (2, 3), (2,); poses.center[1] is normalize(clouds[1]).center
    """
    method = _check_method(method)
    if not _validate.is_name(strategy, ("auto", "map", "vmap")):
        raise _validate.InvalidInputError(f"strategy must be 'auto', 'map' or 'vmap', got {strategy!r}")
    if strategy == "auto":
        strategy = "map" if jax.default_backend() == "cpu" else "vmap"
    given = {**_given(power=power, gamma=gamma, nu=nu, max_points=max_points), **options}
    config, params = _options(method, config, given, rotation)
    rotation = _validate.check_bool(rotation, "rotation")
    throw = _validate.check_throw(throw, **params)
    seed = _validate.check_int(seed, "seed", 0)
    limit = _check_params(method, params, given)
    pad_to = None if pad_to is None else _validate.check_int(pad_to, "pad_to", float("-inf"))  # its range below
    if isinstance(list_of_points, (str, bytes)) or not isinstance(list_of_points, Iterable):
        raise _validate.InvalidInputError(
            f"list_of_points must be an iterable of (m, 3) point sets, got {type(list_of_points).__name__}")
    if isinstance(list_of_points, Mapping):  # its keys would be the sets
        raise _validate.InvalidInputError(
            f"list_of_points must be an iterable of (m, 3) point sets, got a {type(list_of_points).__name__}: "
            "pass its values (list(d.values()); the poses follow their order)")
    if len(getattr(list_of_points, "shape", ())) == 2:  # its rows would be the sets
        raise _validate.InvalidInputError(
            f"list_of_points must be an iterable of (m, 3) point sets, got one {tuple(list_of_points.shape)} array: "
            "pass [points] (or normalize(points))")
    arrays = [_validate.check_points(p, name=f"points[{i}]") for i, p in enumerate(list_of_points)]
    if not arrays:
        raise _validate.InvalidInputError("normalize_batch needs at least one point set")
    if any(_validate.is_traced(a) for a in arrays):
        raise _validate.InvalidInputError("normalize_batch needs concrete point sets; under jit, use jax.vmap(normalize)")
    given_rows = [len(a) for a in arrays]
    arrays = [np.asarray(a) if (k := subsample_index(len(a), limit, seed)) is None else np.asarray(a)[k]
              for a in arrays]
    dtype = np.result_type(*[_validate.compute_dtype(a) for a in arrays])
    frames = [host_frame(a, name=f"points[{i}]") for i, a in enumerate(arrays)]
    arrays = [(np.asarray(a, np.float64) - c) / r for a, (c, r) in zip(arrays, frames)]
    shift, size = np.stack([c for c, _ in frames]), np.asarray([r for _, r in frames])
    largest = max(a.shape[0] for a in arrays)
    m = bucket(largest) if pad_to is None else int(pad_to)
    if m < largest:
        after = " after max_points" if largest < max(given_rows) else ""
        raise _validate.InvalidInputError(f"pad_to must be >= the largest point set's size ({largest} points{after}), "
                                          f"got {m}")
    pts, mask = pad(arrays, m, dtype)
    n = len(arrays)
    chains = min(n, _cores(), MAX_CHAINS) if strategy == "map" and jax.default_backend() == "cpu" else 1
    if method == "robust":
        queries, query_mask = _queries([len(a) for a in arrays], config.spacing_samples, seed)
        power = jnp.broadcast_to(jnp.asarray(params["power"], pts.dtype), (n,))
        pose = _top_level(_robust_batched, _robust_batched_staged, pts, mask, queries, query_mask, power, config=config,
                          strategy=strategy, chains=chains)
        return _finish(pose, shift, size, throw)
    gamma = jnp.broadcast_to(jnp.asarray(params["gamma"], pts.dtype), (n,))
    nu = jnp.broadcast_to(jnp.asarray(params["nu"], pts.dtype), (n,))
    pose = _batched(pts, mask, gamma, nu, _stops(config), config=_without_stops(config), strategy=strategy,
                    rotation=rotation, chains=chains)
    return _finish(pose, shift, size, throw, gamma, nu, config.svdd.tol)


MAX_CHAINS = 4  # chains of normalize_batch's "map" on CPU: compile time grows with each chain


def _cores() -> int:
    """CPU cores this process may run on."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


def chained_map(fn, xs, chains: int):
    """``jax.lax.map(fn, xs)`` as ``chains`` independent ``lax.map`` chains over consecutive
    slices of the leading axis, concatenated: the same results in the same order.

    The chains share no data, so XLA's CPU runtime runs them concurrently on its thread pool
    (one loop each); each holds one object's intermediates at a time. chains: static int >= 1
    (more than the batch: one object per chain).

    Example::

        >>> chained_map(lambda x: x * 2, jnp.arange(5.0), 2)
        Array([0., 2., 4., 6., 8.], dtype=float32)
    """
    n = jax.tree.leaves(xs)[0].shape[0]
    cuts = np.unique(np.linspace(0, n, max(1, min(int(chains), n)) + 1).round().astype(int))
    if len(cuts) <= 2:
        return jax.lax.map(fn, xs)
    parts = [jax.lax.map(fn, jax.tree.map(lambda x, a=a, b=b: x[a:b], xs)) for a, b in zip(cuts[:-1], cuts[1:])]
    return jax.tree.map(lambda *p: jnp.concatenate(p), *parts)


@partial(jax.jit, static_argnames=("config", "strategy", "rotation", "chains"))
def _batched(points, mask, gamma, nu, stops, config, strategy, rotation=False, chains=1):
    fn = lambda p, mk, g, n: _stopped_pipeline(p, mk, g, n, stops, config, rotation)
    if strategy == "map":
        return chained_map(lambda args: fn(*args), (points, mask, gamma, nu), chains)
    return jax.vmap(fn)(points, mask, gamma, nu)


def _robust_batch_pipeline(points, mask, queries, query_mask, power, config, strategy, chains=1):
    fn = lambda p, mk, q, qm, pw: robust_pipeline(p, mk, q, qm, pw, config)
    if strategy == "map":
        return chained_map(lambda args: fn(*args), (points, mask, queries, query_mask, power), chains)
    return jax.vmap(fn)(points, mask, queries, query_mask, power)


_robust_batched = jax.jit(_robust_batch_pipeline, static_argnames=("config", "strategy", "chains"),
                          compiler_options=_EXACT_REDUCTIONS)
_robust_batched_staged = jax.jit(_robust_batch_pipeline, static_argnames=("config", "strategy", "chains"))
