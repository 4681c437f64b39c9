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

Methods: the named estimators of :mod:`jaxpose.pose.estimators` (the robust default, the paper's
``ocsvm``, the surface centroid, vertex mean, bounding box, minimum ball, the closed-form solid with
its gyration radius or sqrt(area), the depth-weighted voxel solid), each on every input variant of
:mod:`jaxpose.evaluation.variants` (plain, outliers, big_outliers, points, holes).
"""
from __future__ import annotations

import warnings
from collections.abc import Iterable, Mapping

import numpy as np

from .. import baselines
from .._validate import InvalidInputError, OpenMeshWarning, check_bool, check_callback, check_names, is_name
from ..config import OCSVM
from . import alignment
from .measures import scale_spread, spread
from .tables import check_result, class_tables, counted
from .variants import VARIANTS, make_class

__all__ = ["METHODS", "LEGEND", "evaluate", "sweep", "format_table", "format_per_class", "SWEEP_VALUES", "SWEEP_FIXED"]

METHODS = ("robust", "ocsvm", "surface_centroid", "vertex_mean", "bbox", "min_ball", "solid", "solid_sqrt_area",
           "depth_weighted_solid:2", "depth_weighted_solid:4")
SWEEP_VALUES = {"gamma": (1.0, 2.0, 5.0, 10.0, 20.0, 30.0, 40.0, 47.0, 50.0),
                "nu": (0.1, 0.2, 0.3, 0.4, 0.5, 0.6)}
SWEEP_FIXED = {"gamma": {"nu": 0.0}, "nu": {"gamma": OCSVM.gamma}}  # the paper's Fig. 5 (a), (b)
KEYS = ("sigma_tr", "sigma_tr_axis", "sigma_scale", "cv_scale")


def _sample(mesh, count, seed):
    from ..mesh import sample_surface

    return np.asarray(sample_surface(mesh, count, seed), dtype=np.float64)


def _ocsvm(points_list, gamma, nu, options):
    """Centers (n, 3), scales (n,) and solver convergence flags of jaxpose.normalize per point set
    (a loop: one compilation for equal point counts)."""
    from ..pose.pose import normalize

    poses = [normalize(p, method="ocsvm", gamma=gamma, nu=nu, **options) for p in points_list]
    centers = np.stack([np.asarray(p.center, dtype=np.float64).reshape(3) for p in poses])
    scales = np.array([float(np.asarray(p.scale)) for p in poses])
    converged = [bool(np.asarray(p.converged)) for p in poses]
    return centers, scales, converged


def _check_classes(classes):
    """``classes`` as {name: [mesh, ...]} with at least 2 meshes (trimesh.Trimesh, or PointCloud)
    per class; InvalidInputError naming the class otherwise (a mesh in place of the list, a
    generator, an array were TypeError or AttributeError deep in the run)."""
    if not isinstance(classes, dict) or not classes:
        raise InvalidInputError("classes must be a non-empty dict {class name: [meshes]}")
    for name, meshes in classes.items():
        if (isinstance(meshes, (str, bytes, Mapping)) or hasattr(meshes, "vertices") or not hasattr(meshes, "__len__")
                or not hasattr(meshes, "__getitem__")):  # a list, a tuple, a sequence (make_class's rule)
            raise InvalidInputError(f"class {name!r} must be a list of meshes, got {type(meshes).__name__}"
                                    + (f": pass {{{name!r}: [...]}}" if hasattr(meshes, "vertices") else ""))
        if len(meshes) < 2:
            raise InvalidInputError(f"class {name!r} needs at least 2 objects, got {len(meshes)}")
        for k, mesh in enumerate(meshes):
            if not hasattr(mesh, "vertices"):
                raise InvalidInputError(f"class {name!r}: object {k} must be a mesh (trimesh.Trimesh, or a "
                                        f"PointCloud), got {type(mesh).__name__}")


def _check_methods(methods):
    from ..pose.estimators import method_key  # (lazily, as the other uses here: JAX at run time)

    return METHODS if methods is None else check_names(methods, "methods", key=method_key, what="method")


def _check_ocsvm(gamma, nu, count, seed, options):
    """The OCSVM's parameters and options, checked before any work (given to normalize per object,
    a bad one became every ocsvm cell's error, and an unknown option went unnoticed without ocsvm);
    returns the seed as an int."""
    from .. import _validate
    from ..config import PoseConfig
    from ..sample import check_count

    _validate.check_gamma(gamma)
    _validate.check_nu(nu)
    check_count(count)
    seed = _validate.check_int(seed, "seed", 0)
    PoseConfig.create(**options)
    return seed


def _check_variants(variants):
    variants = check_names(variants, "variants", what="variant")
    unknown = [v for v in variants if not is_name(v, VARIANTS)]
    if unknown:
        raise InvalidInputError(f"unknown variants {unknown}; valid: {', '.join(VARIANTS)}")
    return variants


def _any_ocsvm(methods):
    """Whether one of ``methods`` has an ``ocsvm`` center or scale (``estimate_many`` refuses the
    OCSVM's options where none has)."""
    from ..pose.estimators import parse_method, resolve

    return any("ocsvm" in resolve(parse_method(spec)[0]) for spec in methods)


def _measure(centers, scales):
    return {**spread(centers), **scale_spread(scales),
            "centers": centers.tolist(), "scales": scales.tolist()}


def reference_method(variant):
    """The baseline a variant's spreads are compared with: the vertex mean for point clouds,
    the surface centroid otherwise."""
    return "vertex_mean" if variant == "points" else "surface_centroid"


def _evaluate_class(meshes, methods, options, seconds):
    """{method: cell} for one class (one variant): the spreads, or the error a method raised."""
    from ..pose.estimators import estimate_many

    poses = {m: [] for m in methods}
    opened = 0
    for mesh in meshes:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", OpenMeshWarning)
            for method, (pose, sec) in estimate_many(mesh, methods, timings=True, **options).items():
                poses[method].append(pose)
                seconds[method] += sec
        opened += any(issubclass(w.category, OpenMeshWarning) for w in caught)
    cells = {}
    for method, found in poses.items():
        errors = [p for p in found if isinstance(p, Exception)]
        if errors:
            cells[method] = {"error": str(errors[0]), "failed": len(errors)}
            continue
        centers = np.stack([np.asarray(p.center, np.float64).reshape(3) for p in found])
        scales = np.array([float(np.asarray(p.scale)) for p in found])
        cells[method] = _measure(centers, scales)
        if method == "ocsvm":
            cells[method]["converged"] = [bool(np.asarray(p.converged)) for p in found]
    cells["open_meshes"] = opened
    return cells


def _warm_up(mesh, methods, options, first):
    """Each method once on one object, timed into `first` {method: seconds}: the first call, which
    compiles what JAX compiles, kept apart from the run times."""
    from ..pose.estimators import estimate_many

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", OpenMeshWarning)
        for method, (_, sec) in estimate_many(mesh, methods, timings=True, **options).items():
            first[method] += sec


def _summary(per_class, methods, seconds, variant, first=None, objects=0):
    rows = []
    for method in methods:
        cells = [per_class[c][method] for c in per_class]
        row = {"method": method, "seconds": seconds[method],
               "seconds_per_object": seconds[method] / objects if objects else None,
               "first_call_seconds": None if first is None else first[method]}
        if any("error" in c for c in cells):
            row.update({k: None for k in KEYS}, error=next(c["error"] for c in cells if "error" in c))
        else:
            row.update({k: float(np.mean([c[k] for c in cells])) for k in KEYS})
        rows.append(row)
    ref = {r["method"]: r for r in rows}.get(reference_method(variant))
    for row in rows:
        ok = ref is not None and ref["sigma_tr"] and row["sigma_tr"] is not None
        row["sigma_tr_vs_reference"] = (row["sigma_tr"] / ref["sigma_tr"] - 1.0) if ok else None
        row["reference"] = reference_method(variant)
    return rows


def _core(params):
    """The header's note of a core aligned on its share of the surface (nothing for the default)."""
    weight = params.get("core_weight", "vertices")
    return f" (core by {weight})" if params.get("align_core") and weight != "vertices" else ""


def evaluate(classes, gamma=None, nu=None, methods=None, count=None, seed=OCSVM.seed, align_core=False,
             progress=None, sweep=False, variants=("plain",), core_weight="vertices", **normalize_options) -> dict:
    """Within-class spread of centers and scales for each method and input variant (paper, sec. 4.2).

    Args:
      classes: {class name: [Trimesh, ...]} (at least 2 per class), e.g.
        :func:`jaxpose.datasets.make_dataset` or :func:`jaxpose.datasets.load_folder`.
      gamma, nu, normalize_options: for ``ocsvm`` (:func:`jaxpose.normalize`); None: the defaults
        (:data:`jaxpose.config.OCSVM`). Given where no method is ``ocsvm``, they are refused
        (nothing would read them: the sweep sets gamma and nu itself, and reads ``count`` and the
        normalize options), as :func:`jaxpose.pose.estimators.estimate_many` and ``jaxpose
        evaluate`` refuse them.
      methods: names of :data:`jaxpose.pose.estimators.METHODS`, optionally ``"name:power"`` for the
        depth exponent (default :data:`METHODS`: every estimator, the depth-weighted solid at
        powers 2 and 4), each once (``"robust"`` and ``"robust:4"``, its default power spelled out,
        are one method named twice).
      count, seed: surface samples per mesh for ``ocsvm`` (None: the default; refused as gamma
        where nothing reads it); ``seed`` also seeds the variants.
      align_core: first rigidly align each class with :func:`jaxpose.evaluation.align_core` (the
        meshes of a class must share their vertex order, as registrations do).
      core_weight: what the stable core is a share of when ``align_core``: ``"vertices"`` or
        ``"area"`` (:func:`jaxpose.evaluation.align_core`'s ``weight``).
      progress: optional callable(done, total, message), told as each (variant, class) starts.
      sweep: also run :func:`sweep` over gamma and nu (paper, Fig. 5) into ``result["sweeps"]``.
      variants: names of :data:`jaxpose.evaluation.variants.VARIANTS` (each once), each made from
        the aligned meshes (:func:`jaxpose.evaluation.variants.make_class`).

    Returns:
      A JSON-able dict ``{"params", "variants": {variant: {"summary": [row, ...], "per_class":
      {class: {method: cell}}}}, "summary", "per_class"}`` (the last two: the first variant's). A row
      holds ``method``, the averages over classes of ``sigma_tr``, ``sigma_tr_axis``,
      ``sigma_scale``, ``cv_scale`` (None, with ``error``, where the method does not apply, e.g.
      surface estimators on points), ``sigma_tr_vs_reference`` (sigma_tr / the reference's - 1; the
      reference is the surface centroid, or the vertex mean for points), ``seconds`` (all objects,
      after a first call of each method on the variant's first object), ``seconds_per_object`` and
      ``first_call_seconds`` (that first call: JIT compilation included). A cell holds the spreads
      and the ``centers`` and ``scales`` per object, or ``error``.

    Raises:
      InvalidInputError: bad classes, methods, variants (unknown, or one named twice) or core_weight,
        or a bad gamma, nu, count, seed or normalize option, or one of the OCSVM's given where none
        runs (named, before any work).
    """
    _check_classes(classes)
    methods = _check_methods(methods)
    variants = _check_variants(variants)
    given = [name for name, value in (("gamma", gamma), ("nu", nu), ("count", count)) if value is not None]
    gamma, nu = OCSVM.gamma if gamma is None else gamma, OCSVM.nu if nu is None else nu
    count = OCSVM.count if count is None else count
    seed = _check_ocsvm(gamma, nu, count, seed, normalize_options)  # a NumPy or JAX integer scalar: its int
    alignment.check_core_weight(core_weight)
    align_core, sweep = check_bool(align_core, "align_core"), check_bool(sweep, "sweep")
    uses_ocsvm = _any_ocsvm(methods)
    if not uses_ocsvm:  # given, nothing would read them (as estimate_many); the sweep sets gamma and nu itself
        from ..pose.estimators import check_ocsvm_unread

        unread = [name for name in given if name != "count"] if sweep else given + list(normalize_options)
        swept = {"gamma", "nu"} & set(unread)  # the sweep sets them itself; it reads the others
        check_ocsvm_unread(unread, methods, "'ocsvm' among the methods" + (
            " (the sweep sets gamma and nu itself)" if swept else ", or sweep=True"))
    check_callback(progress, "progress")
    if align_core:
        classes = alignment.align_classes(classes, weight=core_weight)
    options = {"gamma": gamma, "nu": nu, "count": count, "seed": seed, "ocsvm": normalize_options} if uses_ocsvm else {}
    total, done, out = len(variants) * len(classes), 0, {}
    for variant in variants:
        per_class, seconds, first, objects = {}, dict.fromkeys(methods, 0.0), dict.fromkeys(methods, 0.0), 0
        for k, (name, meshes) in enumerate(classes.items()):
            shapes = make_class(meshes, variant, seed, k)
            if k == 0:  # compilation apart: every method once on the variant's first object, untimed below
                if progress is not None:
                    progress(done, total, f"{variant}: first call of each method (compiles)")
                _warm_up(shapes[0], methods, options, first)
            if progress is not None:
                progress(done, total, f"{variant}: {name} ({len(meshes)} objects)")
            done += 1
            per_class[name] = _evaluate_class(shapes, methods, options, seconds)
            objects += len(shapes)
        out[variant] = {"summary": _summary(per_class, methods, seconds, variant, first, objects),
                        "per_class": per_class}
    if progress is not None:
        progress(total, total, "done")
    params = {"gamma": float(gamma), "nu": float(nu), "count": int(count), "seed": int(seed),
              "align_core": bool(align_core), "core_weight": core_weight, "methods": list(methods), "variants": list(variants),
              "classes": list(classes), "objects": {c: len(m) for c, m in classes.items()},
              "normalize_options": {k: _jsonable(v) for k, v in normalize_options.items()}}
    first = out[variants[0]]
    result = {"params": params, "variants": out, "summary": first["summary"], "per_class": first["per_class"]}
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


def sweep(classes, param="gamma", values=None, fixed=None, count=OCSVM.count, seed=OCSVM.seed, progress=None,
          **normalize_options) -> dict:
    """sigma_tr and sigma_scale of ``ocsvm`` as one parameter varies (paper, Fig. 5 and 6).

    param : "gamma" or "nu"; values : default :data:`SWEEP_VALUES` [param]
    fixed : the other parameter, default :data:`SWEEP_FIXED` [param] (nu = 0 for the gamma
        sweep, the default gamma for the nu sweep, as in the paper); keys "gamma" and "nu" only,
        the other one required; a value given for the swept parameter is overridden by each of
        ``values`` (``{"gamma": 47.0, "nu": 0.3}`` sweeps gamma at nu = 0.3)
    Surface samples are drawn once per mesh and reused for every value.

    Returns ``{"param", "values", "fixed", "per_class": {class: {"sigma_tr": [...],
    "sigma_scale": [...]}}, "average": {"sigma_tr": [...], "sigma_scale": [...]},
    "surface_centroid": {"per_class": {class: {"sigma_tr", "sigma_scale"}}, "average":
    {"sigma_tr", "sigma_scale"}}}``.
    """
    from .._validate import check_gamma, check_nu

    if param not in SWEEP_VALUES:
        raise InvalidInputError(f"param must be 'gamma' or 'nu', got {param!r}")
    _check_classes(classes)
    check_callback(progress, "progress")
    if isinstance(values, (str, bytes)):  # its characters were the values: "47" swept 4 and 7
        raise InvalidInputError(f"values must be a list of numbers, got the string {values!r}")
    values = SWEEP_VALUES[param] if values is None else values
    if not isinstance(values, Iterable) or not (values := list(values)):
        raise InvalidInputError(f"values must be a non-empty list of numbers, got {values!r:.80}")
    other = "nu" if param == "gamma" else "gamma"
    fixed = SWEEP_FIXED[param] if fixed is None else fixed
    if not isinstance(fixed, Mapping) or other not in fixed or not set(fixed) <= {"gamma", "nu"}:  # (a typo: KeyError)
        raise InvalidInputError(f"fixed must give the other parameter, {{{other!r}: value}} (keys 'gamma' and 'nu' "
                                f"only; the swept one is overridden by each value), got {fixed!r:.80}")
    check = {"gamma": check_gamma, "nu": check_nu}
    for value in values:  # every value before any work (a bad one failed after the samples were drawn)
        check[param](value)
    for name in fixed:
        check[name](fixed[name])
    seed = _check_ocsvm(OCSVM.gamma, OCSVM.nu, count, seed, normalize_options)  # count, seed, the options
    values, fixed = [float(v) for v in values], {other: float(fixed[other])}
    points = {name: [_sample(m, count, seed) for m in meshes] for name, meshes in classes.items()}
    per_class = {name: {"sigma_tr": [], "sigma_scale": []} for name in classes}
    for value in values:
        args = {**fixed, param: value}
        for name in classes:
            if progress is not None:
                progress(None, None, f"sweep {param}={value:g}: {name}")
            centers, scales, _ = _ocsvm(points[name], args["gamma"], args["nu"], normalize_options)
            per_class[name]["sigma_tr"].append(spread(centers)["sigma_tr"])
            per_class[name]["sigma_scale"].append(scale_spread(scales)["sigma_scale"])
    reference = {}
    for name, meshes in classes.items():
        centers = np.stack([baselines.surface_centroid(m) for m in meshes])
        scales = np.array([baselines.mean_distance(m, c) for m, c in zip(meshes, centers)])
        reference[name] = {"sigma_tr": spread(centers)["sigma_tr"],
                           "sigma_scale": scale_spread(scales)["sigma_scale"]}
    average = {k: np.mean([per_class[c][k] for c in classes], axis=0).tolist() for k in ("sigma_tr", "sigma_scale")}
    return {"param": param, "values": values, "fixed": fixed, "per_class": per_class, "average": average,
            "surface_centroid": {"per_class": reference,
                                 "average": {k: float(np.mean([reference[c][k] for c in classes]))
                                             for k in ("sigma_tr", "sigma_scale")}}}


# ------------------------------------------------------------------ report
LEGEND = (
    "sigma_tr      spread of a class's centers: RMS distance of the centers from their mean, in the meshes' units\n"
    "              (the built-in objects are about 1 across), averaged over classes; lower is better",
    "vs REFERENCE  sigma_tr relative to the reference method's (surface centroid; vertex mean for point clouds):\n"
    "              -50 % halves the spread; lower is better",
    "sigma_scale   standard deviation of a class's scales, in each method's own scale units (a volume's cube root,\n"
    "              a mean distance, an extent): not comparable between methods",
    "cv_scale      sigma_scale / mean scale, dimensionless: the scale's consistency, comparable between methods;\n"
    "              lower is better",
    "ms/object     run time per object after the first call; first s: that first call on one object, JIT\n"
    "              compilation included",
    "n/a           the method does not apply to this input (e.g. a closed-surface estimator on a point cloud)\n"
    "              or refused an object of it (e.g. a point cloud too sparse to hold together; the --json\n"
    "              output names the error)",
)


def _uses_ocsvm(result):
    p = result.get("params", {})
    methods = p.get("methods") or [r["method"] for r in result.get("summary", [])]
    return "sweeps" in result or any(str(m).partition(":")[0] == "ocsvm" for m in methods)


def format_table(result) -> str:
    """The summaries of :func:`evaluate` as terminal tables, one per variant, with a legend.

    Columns: sigma_tr, its change against the variant's reference (the surface centroid; the
    vertex mean for point clouds), sigma_scale, cv_scale, milliseconds per object after the first
    call, and the first call's seconds (compilation included); n/a where a method does not apply.
    The header names gamma, nu and count only when the OCSVM runs (nothing else uses them). With
    ``result["sweeps"]`` (``sweep=True``), a table per swept parameter follows: the class averages
    of the OCSVM's sigma_tr and sigma_scale per value, against the surface centroid's.
    """
    check_result(result, "evaluate")
    p = result.get("params", {})
    per_variant = result.get("variants") or {"plain": {"summary": result["summary"], "per_class": result["per_class"]}}
    objects = p.get("objects") or {}
    sizes = sorted(set(objects.values()))
    size = (f" x {sizes[0]} objects" if len(sizes) == 1 else f", {sum(objects.values())} objects") if sizes else ""
    ocsvm = f", ocsvm: gamma={p.get('gamma')}, nu={p.get('nu')}, count={p.get('count')}" if _uses_ocsvm(result) else ""
    n = len(result.get("per_class", {}))
    lines = [f"{counted(n, 'class')}{size}, seed={p.get('seed')}, "
             f"align_core={p.get('align_core')}{_core(p)}{ocsvm}"]
    for variant, block in per_variant.items():
        ref = reference_method(variant)
        head = (f"{'method':<24}{'sigma_tr':>10}{'vs ' + ref:>21}{'sigma_scale':>13}{'cv_scale':>10}"
                f"{'ms/object':>11}{'first s':>9}")
        lines += ["", f"variant {variant}", head, "-" * len(head)]
        for row in block["summary"]:
            per = row.get("seconds_per_object")
            first = row.get("first_call_seconds")
            timing = (f"{'' if per is None else f'{1e3 * per:.1f}':>11}"
                      f"{'' if first is None else f'{first:.1f}':>9}")
            if row["sigma_tr"] is None:
                lines.append(f"{row['method']:<24}{'n/a':>10}{'':>21}{'n/a':>13}{'n/a':>10}{timing}")
                continue
            rel = row.get("sigma_tr_vs_reference")
            rel = "" if rel is None else f"{100.0 * rel:+.1f}%"
            lines.append(f"{row['method']:<24}{row['sigma_tr']:>10.5f}{rel:>21}{row['sigma_scale']:>13.5f}"
                         f"{row['cv_scale']:>10.5f}{timing}")
    lines += _sweep_lines(result.get("sweeps") or {})
    lines += ["", *LEGEND]
    return "\n".join(lines)


def _sweep_lines(sweeps) -> list:
    """The lines of :func:`sweep` results {param: sweep}: per value, the class averages of the
    OCSVM's sigma_tr and sigma_scale, against the surface centroid's (nothing without sweeps)."""
    lines = []
    for param, block in sweeps.items():
        fixed = ", ".join(f"{k}={v:g}" for k, v in block.get("fixed", {}).items())
        ref = block["surface_centroid"]["average"]
        lines += ["", f"sweep of the ocsvm method's {param} ({fixed}), averages over classes; surface centroid: "
                      f"sigma_tr {ref['sigma_tr']:.5f}, sigma_scale {ref['sigma_scale']:.5f}",
                  f"{param:>10}{'sigma_tr':>12}{'sigma_scale':>13}", "-" * 35]
        lines += [f"{value:>10g}{tr:>12.5f}{sc:>13.5f}" for value, tr, sc in
                  zip(block["values"], block["average"]["sigma_tr"], block["average"]["sigma_scale"])]
    return lines


def format_per_class(result) -> str:
    """The per-class cells of :func:`evaluate` as terminal tables, one per class, every method side by side.

    Rows: methods; columns: ``sigma_tr`` and ``cv_scale`` in each variant. ``*`` marks the lowest
    value of a column (ties included), ``~`` a value within 5 % of it; n/a where a method does not
    apply. An average over classes (:func:`format_table`) can hide a class that loses; this cannot.
    """
    check_result(result, "evaluate")
    per_variant = result.get("variants") or {"plain": {"summary": result["summary"], "per_class": result["per_class"]}}

    def rows(cells, methods):
        columns = {(v, key): {m: block[m][key] for m in methods if m in block and "error" not in block[m]}
                   for v, block in cells.items() for key in ("sigma_tr", "cv_scale")}
        texts = {}
        for m in methods:
            text = ""
            for v in cells:
                for key in ("sigma_tr", "cv_scale"):
                    col = columns[v, key]
                    if m not in col:
                        text += f"{'n/a':>12}"
                        continue
                    low = min(col.values())
                    mark = "*" if col[m] <= low else ("~" if col[m] <= 1.05 * low else " ")
                    text += f"{col[m]:>11.5f}{mark}"
            texts[m] = text
        return texts

    lines = class_tables(per_variant, result.get("params", {}).get("objects", {}),
                         f"{'sigma_tr':>12}{'cv_scale':>12}", 24, rows)
    lines += ["", "* lowest of the column, ~ within 5 % of it"]
    return "\n".join(lines)
