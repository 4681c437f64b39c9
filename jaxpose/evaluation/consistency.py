r"""Consistency of centers and scales within classes (paper, section 4.2): ``evaluate`` and ``sweep``.

Every object of a class shares the pose of its rigid core (no similarity transform was applied
to them), so a good translation/scale normalization gives the same center and scale to all of
them. For one class and one method with centers :math:`c_1..c_n` (3-vectors) and scales
:math:`s_1..s_n`, with :math:`\bar c = \frac1n\sum_k c_k` and :math:`\bar s = \frac1n\sum_k s_k`:

* ``sigma_tr``      = :math:`\sqrt{\frac1n\sum_k \lVert c_k-\bar c\rVert^2}`, the RMS distance
  of the centers from their mean (equivalently the square root of the summed per-axis
  population variances);
* ``sigma_tr_axis`` = :math:`\frac13\sum_{a\in\{x,y,z\}} \sqrt{\frac1n\sum_k (c_{k,a}-\bar c_a)^2}`,
  the mean over axes of the per-axis population standard deviation (ddof = 0);
* ``sigma_scale``   = :math:`\sqrt{\frac1n\sum_k (s_k-\bar s)^2}`, population std of the scales;
* ``cv_scale``      = ``sigma_scale`` / :math:`\bar s`, the same relative to the mean scale.

All are in the units of the meshes (the procedural dataset has largest extent ~1 per object).
A summary value is the plain average of the per-class values over classes.

Methods (:data:`METHODS`), each a center and a scale about it:

* ``ocsvm``: :func:`jaxpose.normalize` on ``count`` area-weighted surface samples
  (``Pose.center``, ``Pose.scale``);
* ``surface_centroid``: area-weighted surface centroid, area-weighted mean distance of the
  surface from it;
* ``vertex_mean``: mean of the vertices, area-weighted mean distance of the surface from it;
* ``bbox``: bounding-box center, largest extent (the unit-cube scale);
* ``min_ball``: center and radius of the minimum enclosing ball of the vertices.
"""
from __future__ import annotations

import time

import numpy as np

from .. import baselines
from .._validate import InvalidInputError
from . import alignment
from .measures import scale_spread, spread

__all__ = ["METHODS", "evaluate", "sweep", "format_table", "SWEEP_VALUES", "SWEEP_FIXED"]

METHODS = ("ocsvm", "surface_centroid", "vertex_mean", "bbox", "min_ball")
_BASELINES = {  # method -> (baselines center, baselines scale)
    "surface_centroid": ("surface_centroid", "mean_distance"),
    "vertex_mean": ("vertex_mean", "mean_distance"),
    "bbox": ("bbox_center", "unit_cube"),
    "min_ball": ("min_ball", "unit_sphere"),
}
SWEEP_VALUES = {"gamma": (1.0, 2.0, 5.0, 10.0, 20.0, 30.0, 40.0, 47.0, 50.0),
                "nu": (0.1, 0.2, 0.3, 0.4, 0.5, 0.6)}
SWEEP_FIXED = {"gamma": {"nu": 0.0}, "nu": {"gamma": 47.0}}  # the paper's Fig. 5 (a), (b)


def _sample(mesh, count, seed):
    from ..mesh import sample_surface

    return np.asarray(sample_surface(mesh, count, seed), dtype=np.float64)


def _ocsvm(points_list, gamma, nu, options):
    """Centers (n, 3), scales (n,) and solver convergence flags of jaxpose.normalize per point set.

    A loop over ``normalize`` (one compilation for equal point counts): on CPU it is faster
    than ``normalize_batch``, whose vmapped loops run every object as long as the slowest
    and cannot skip work per object.
    """
    from ..pose import normalize

    poses = [normalize(p, gamma=gamma, nu=nu, **options) for p in points_list]
    centers = np.stack([np.asarray(p.center, dtype=np.float64).reshape(3) for p in poses])
    scales = np.array([float(np.asarray(p.scale)) for p in poses])
    converged = [bool(np.asarray(p.converged)) for p in poses]
    return centers, scales, converged


def _baseline(meshes, method):
    center_name, scale_name = _BASELINES[method]
    centers = np.stack([baselines.center(m, center_name) for m in meshes])
    scales = np.array([baselines.scale(m, scale_name, c) for m, c in zip(meshes, centers)])
    return centers, scales


def _check_classes(classes):
    if not isinstance(classes, dict) or not classes:
        raise InvalidInputError("classes must be a non-empty dict {class name: [meshes]}")
    for name, meshes in classes.items():
        if len(meshes) < 2:
            raise InvalidInputError(f"class {name!r} needs at least 2 objects, got {len(meshes)}")


def _check_methods(methods):
    methods = METHODS if methods is None else tuple(methods)
    unknown = [m for m in methods if m not in METHODS]
    if unknown or not methods:
        raise InvalidInputError(f"unknown methods {unknown}; valid: {', '.join(METHODS)}")
    return methods


def _measure(centers, scales):
    return {**spread(centers), **scale_spread(scales),
            "centers": centers.tolist(), "scales": scales.tolist()}


def _notify(progress, message):
    if progress is not None:
        progress(message)


def evaluate(classes, gamma=47.0, nu=0.5, methods=None, count=2000, seed=0, align_core=False,
             progress=None, sweep=False, **normalize_options) -> dict:
    """Within-class spread of centers and scales for each method (paper, sec. 4.2).

    classes : {class name: [Trimesh, ...]} (at least 2 per class), e.g.
        :func:`jaxpose.datasets.make_dataset` or :func:`jaxpose.datasets.load_folder`
    gamma, nu, **normalize_options : passed to :func:`jaxpose.normalize` (or ``normalize_batch``)
    methods : subset of :data:`METHODS` (default all)
    count, seed : surface samples per mesh for ``ocsvm`` (the same seed for every mesh)
    align_core : first rigidly align each class with :func:`jaxpose.evaluation.align_core` (meshes of a class must
        share their vertex order, as registrations do)
    progress : callable(str) or None, told when each class/method starts
    sweep : also run :func:`sweep` over gamma and nu (paper, Fig. 5) into ``result["sweeps"]``

    Returns a JSON-able dict: ``{"params": {...}, "summary": [{"method", "sigma_tr",
    "sigma_tr_axis", "sigma_scale", "cv_scale", "seconds"}, ...], "per_class": {class: {method:
    {"sigma_tr", "sigma_tr_axis", "sigma_scale", "cv_scale", "centers", "scales"}}}}`` (``ocsvm``
    cells also hold ``"converged"``, the solver's flag per object); summary
    values are averages over classes, ``seconds`` the total time of the method (for ``ocsvm``,
    sampling included; compilation is included in the first class).
    """
    _check_classes(classes)
    methods = _check_methods(methods)
    if align_core:
        classes = {name: alignment.align_core(meshes) for name, meshes in classes.items()}
    per_class, seconds = {}, dict.fromkeys(methods, 0.0)
    for name, meshes in classes.items():
        per_class[name] = {}
        for method in methods:
            _notify(progress, f"{name}: {method} ({len(meshes)} objects)")
            start = time.perf_counter()
            if method == "ocsvm":
                points = [_sample(m, count, seed) for m in meshes]
                centers, scales, converged = _ocsvm(points, gamma, nu, normalize_options)
            else:
                (centers, scales), converged = _baseline(meshes, method), None
            seconds[method] += time.perf_counter() - start
            per_class[name][method] = _measure(centers, scales)
            if converged is not None:
                per_class[name][method]["converged"] = converged
    keys = ("sigma_tr", "sigma_tr_axis", "sigma_scale", "cv_scale")
    summary = [{"method": method,
                **{k: float(np.mean([per_class[c][method][k] for c in per_class])) for k in keys},
                "seconds": seconds[method]} for method in methods]
    params = {"gamma": float(gamma), "nu": float(nu), "count": int(count), "seed": int(seed),
              "align_core": bool(align_core), "methods": list(methods), "classes": list(classes),
              "objects": {c: len(m) for c, m in classes.items()},
              "normalize_options": {k: _jsonable(v) for k, v in normalize_options.items()}}
    result = {"params": params, "summary": summary, "per_class": per_class}
    if sweep:
        result["sweeps"] = _both_sweeps(classes, count, seed, progress, normalize_options)
    return result


def _both_sweeps(classes, count, seed, progress, options):
    return {p: sweep(classes, p, count=count, seed=seed, progress=progress, **options) for p in ("gamma", "nu")}


def _jsonable(value):
    if isinstance(value, (bool, int, float, str)) or value is None:
        return value
    if isinstance(value, (np.floating, np.integer)):
        return value.item()
    return repr(value)


def sweep(classes, param="gamma", values=None, fixed=None, count=2000, seed=0, progress=None,
          **normalize_options) -> dict:
    """sigma_tr and sigma_scale of ``ocsvm`` as one parameter varies (paper, Fig. 5 and 6).

    param : "gamma" or "nu"; values : default :data:`SWEEP_VALUES` [param]
    fixed : the other parameter, default :data:`SWEEP_FIXED` [param] (nu = 0 for the gamma
        sweep, gamma = 47 for the nu sweep, as in the paper)
    Surface samples are drawn once per mesh and reused for every value.

    Returns ``{"param", "values", "fixed", "per_class": {class: {"sigma_tr": [...],
    "sigma_scale": [...]}}, "average": {"sigma_tr": [...], "sigma_scale": [...]},
    "surface_centroid": {"per_class": {class: {"sigma_tr", "sigma_scale"}}, "average":
    {"sigma_tr", "sigma_scale"}}}``.
    """
    if param not in SWEEP_VALUES:
        raise InvalidInputError(f"param must be 'gamma' or 'nu', got {param!r}")
    _check_classes(classes)
    values = [float(v) for v in (SWEEP_VALUES[param] if values is None else values)]
    if not values:
        raise InvalidInputError("values must not be empty")
    fixed = dict(SWEEP_FIXED[param] if fixed is None else fixed)
    points = {name: [_sample(m, count, seed) for m in meshes] for name, meshes in classes.items()}
    per_class = {name: {"sigma_tr": [], "sigma_scale": []} for name in classes}
    for value in values:
        args = {**fixed, param: value}
        for name in classes:
            _notify(progress, f"sweep {param}={value:g}: {name}")
            centers, scales, _ = _ocsvm(points[name], args["gamma"], args["nu"], normalize_options)
            per_class[name]["sigma_tr"].append(spread(centers)["sigma_tr"])
            per_class[name]["sigma_scale"].append(scale_spread(scales)["sigma_scale"])
    reference = {}
    for name, meshes in classes.items():
        centers, scales = _baseline(meshes, "surface_centroid")
        reference[name] = {"sigma_tr": spread(centers)["sigma_tr"],
                           "sigma_scale": scale_spread(scales)["sigma_scale"]}
    average = {k: np.mean([per_class[c][k] for c in classes], axis=0).tolist() for k in ("sigma_tr", "sigma_scale")}
    return {"param": param, "values": values, "fixed": fixed, "per_class": per_class, "average": average,
            "surface_centroid": {"per_class": reference,
                                 "average": {k: float(np.mean([reference[c][k] for c in classes]))
                                             for k in ("sigma_tr", "sigma_scale")}}}


# ------------------------------------------------------------------ report
def format_table(result) -> str:
    """The summary of :func:`evaluate` as a terminal table, with OCSVM's relative reduction."""
    p = result.get("params", {})
    head = (f"{len(result.get('per_class', {}))} classes, gamma={p.get('gamma')}, nu={p.get('nu')}, "
            f"count={p.get('count')}, align_core={p.get('align_core')}")
    columns = ("sigma_tr", "sigma_tr_axis", "sigma_scale", "cv_scale", "seconds")
    rows = [f"{'method':<18}" + "".join(f"{c:>15}" for c in columns)]
    rows.append("-" * len(rows[0]))
    for row in result["summary"]:
        rows.append(f"{row['method']:<18}" + "".join(
            f"{row[c]:>15.2f}" if c == "seconds" else f"{row[c]:>15.5f}" for c in columns))
    by = {row["method"]: row for row in result["summary"]}
    lines = [head, *rows]
    if "ocsvm" in by and "surface_centroid" in by:
        o, s = by["ocsvm"], by["surface_centroid"]
        change = [f"{k} {100.0 * (s[k] - o[k]) / s[k]:+.1f}%" for k in columns[:4] if s[k] > 0]
        lines.append("reduction of ocsvm vs surface_centroid (positive = ocsvm more consistent): "
                     + ", ".join(change))
    return "\n".join(lines)
