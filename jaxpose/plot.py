"""Figures of the paper, headless (matplotlib's Agg canvas; no pyplot state, no OpenGL).

Every function draws into ``ax`` when given (an Axes, or a sequence of them where a function
draws several panels) or into a new :class:`matplotlib.figure.Figure`, saves it as PNG when
``path`` is given, and returns the Figure. matplotlib is imported inside the functions so that
``import jaxpose`` stays light. Bad arguments raise :class:`jaxpose.errors.InvalidInputError` (a
``ValueError``).

* :func:`region_slices`   slices of the decision function f through the region's center, the
  f = 0 contour and the samples (paper, Fig. 3);
* :func:`mesh_3d`         a mesh (Poly3DCollection) or a point cloud (scatter);
* :func:`centers_plot`    a shape with the baseline centers and the OCSVM center marked;
* :func:`sweep_curves`    sigma_tr (or sigma_scale) against gamma / nu, averaged (Fig. 5) or per
  class (Fig. 6), with the surface centroid's value as a red line;
* :func:`scale_bars`      per-class sigma_scale, OCSVM against the surface's mean distance (Fig. 7);
* :func:`class_bars`      which method is most consistent per class (sigma_tr and cv_scale);
* :func:`variant_bars`, :func:`variants_figure`  each method across the input variants;
* :func:`overlay_pairs`   pairs of normalized objects of one class overlaid (Fig. 8);
* :func:`evaluation_figures`  all figures of an :func:`jaxpose.evaluation.evaluate` result;
* :func:`rotation_angles` per-instance angles to the class frame, per rotation method;
* :func:`rotation_overlay` the instances of one class in their canonical frames, overlaid;
* :func:`rotation_figures`    all figures of an :func:`jaxpose.evaluation.evaluate_rotation` result.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .config import OCSVM
from .errors import InvalidInputError

__all__ = ["region_slices", "mesh_3d", "centers_plot", "sweep_curves", "scale_bars", "variant_bars", "class_bars",
           "variants_figure", "method_colors", "METHOD_COLORS",
           "overlay_pairs", "evaluation_figures", "rotation_angles", "rotation_overlay", "rotation_figures"]

OCSVM_COLOR = "tab:blue"  # the paper's blue curve
SURFACE_COLOR = "tab:red"  # and red line
REGION_COLOR = "tab:orange"  # the paper's orange distribution
CENTER_STYLES = {  # name -> (label, color, marker)
    "ocsvm": ("OCSVM", OCSVM_COLOR, "*"),
    "surface_centroid": ("surface centroid", SURFACE_COLOR, "o"),
    "vertex_mean": ("vertex mean", "tab:green", "s"),
    "bbox_center": ("bounding-box center", "tab:purple", "^"),
    "min_ball": ("min. ball center", "tab:brown", "D"),
    "solid_centroid": ("solid centroid", "tab:olive", "v"),
    "robust_depth": ("robust (default)", "k", "P"),
}
_PLANES = {"xy": (0, 1), "xz": (0, 2), "yz": (1, 2)}


# --------------------------------------------------------------------------- helpers
def _figure(ax, nrows=1, ncols=1, size=(4.0, 3.5), projection=None, **kw):
    """(figure, axes as a flat list) drawing into ``ax`` or a new Figure."""
    if ax is not None:
        axes = list(np.ravel(ax)) if isinstance(ax, (list, tuple, np.ndarray)) else [ax]
        return axes[0].figure, axes
    from matplotlib.figure import Figure

    fig = Figure(figsize=(size[0] * ncols, size[1] * nrows), layout="constrained")
    if projection == "3d":
        import mpl_toolkits.mplot3d  # noqa: F401  (registers the projection)
    axes = fig.subplots(nrows, ncols, squeeze=False, subplot_kw={"projection": projection} if projection else None, **kw)
    return fig, list(axes.ravel())


def _finish(fig, path, dpi=90):
    if path is not None:
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(path, dpi=dpi)
    return fig


def _check_result(result, kind):
    """:func:`jaxpose.evaluation.tables.check_result` (imported when a figure is drawn)."""
    from .evaluation.tables import check_result

    return check_result(result, kind)


def _blocks(result):
    """{variant: {"summary", "per_class"}} of an evaluation result (one without ``variants``: its
    summary as "plain")."""
    return result.get("variants") or {"plain": {"summary": result["summary"], "per_class": result["per_class"]}}


def _variant(blocks, variant):
    """(name, block) of ``variant`` in ``blocks`` (None: the first); InvalidInputError naming the
    variants the result holds otherwise (was a KeyError)."""
    if variant is None:
        variant = next(iter(blocks))
    if not isinstance(variant, str) or variant not in blocks:
        raise InvalidInputError(f"variant {variant!r} is not in the result; it holds {', '.join(map(repr, blocks))}")
    return variant, blocks[variant]


def _check_metric(metric):
    """One of :data:`METRIC_LABELS` (InvalidInputError naming them otherwise)."""
    if not isinstance(metric, str) or metric not in METRIC_LABELS:
        raise InvalidInputError(f"metric must be one of {', '.join(map(repr, METRIC_LABELS))}, got {metric!r}")
    return metric


def _check_plane(plane, name="plane"):
    """One of the planes "xy", "xz", "yz" (InvalidInputError naming ``name`` otherwise)."""
    if not isinstance(plane, str) or plane not in _PLANES:
        raise InvalidInputError(f"{name} must be one of {', '.join(map(repr, _PLANES))}, got {plane!r}")
    return plane


def _vertices_faces(mesh_or_points):
    try:
        v = np.asarray(getattr(mesh_or_points, "vertices", mesh_or_points), dtype=np.float64)
    except (TypeError, ValueError):  # a string, a ragged list: float()'s error
        raise InvalidInputError(f"expected a mesh or an (n, 3) array of points, got {mesh_or_points!r:.80}") from None
    f = getattr(mesh_or_points, "faces", None)
    f = np.asarray(f, dtype=np.int64) if f is not None and len(f) > 0 else None
    if v.ndim != 2 or v.shape[1] != 3 or len(v) == 0:
        raise InvalidInputError(f"expected a mesh or an (n, 3) array of points, got shape {v.shape}")
    bad = int(np.count_nonzero(~np.all(np.isfinite(v), axis=1)))
    if bad:  # (matplotlib's "Axis limits cannot be NaN or Inf")
        raise InvalidInputError(f"expected finite coordinates, got {bad} of {len(v)} points with NaN or inf")
    return v, f


def _center_scale(pose):
    """(center (3,), scale) of a Pose-like object or a (center, scale) pair."""
    c, s = (pose.center, pose.scale) if hasattr(pose, "center") else pose
    c, s = np.asarray(c, float), np.asarray(s, float)
    if c.shape != (3,) or s.shape != ():
        raise InvalidInputError(f"a pose must be one center (3,) and a scale () > 0, finite (one pose of a batch: "
                                f"index it), got shapes {c.shape} and {s.shape}")
    if not (np.all(np.isfinite(c)) and np.isfinite(s)):
        status = getattr(pose, "status", None)
        why = ""
        if status is not None and np.ndim(status) == 0 and int(status) != 0:
            from .pose.result import status_message

            why = f", status {int(status)} ({status_message(int(status))})"
        raise InvalidInputError(f"an invalid pose{why}: its center {c.tolist()} and scale {float(s)} must be finite "
                                "(check pose.valid before plotting)")
    if not s > 0:
        raise InvalidInputError(f"a pose's scale must be > 0, got {float(s)}")
    return c, float(s)


def _equal_3d(ax, points):
    lo, hi = points.min(axis=0), points.max(axis=0)
    mid, half = (lo + hi) / 2, max(float((hi - lo).max()) / 2, 1e-9)
    ax.set_xlim(mid[0] - half, mid[0] + half)
    ax.set_ylim(mid[1] - half, mid[1] + half)
    ax.set_zlim(mid[2] - half, mid[2] + half)
    ax.set_box_aspect((1, 1, 1))


# --------------------------------------------------------------------------- Fig. 3
def region_slices(svdd_or_points, gamma=OCSVM.gamma, nu=OCSVM.nu, *, center=None, planes=("xy", "xz", "yz"),
                  pixels=100, thickness=0.04, ax=None, path=None, title=None, **normalize_options):
    """Slices of the OCSVM decision function through the region's center (paper, Fig. 3).

    svdd_or_points : an :class:`jaxpose.SVDD` (drawn in its own units) or (m, 3) surface
        samples, fitted here like :func:`jaxpose.normalize` does: pre-scaled by
        :func:`jaxpose.pose.frame.reference_frame`, ``gamma`` dimensionless; drawn in the units of
        the points
    center : (3,) where the slices cut; default the region's centroid c_m (eq. 4): for points,
        ``jaxpose.normalize(points, method="ocsvm", gamma=gamma, nu=nu, **normalize_options).center`` (its compilation is
        shared with other calls of ``normalize``), for an SVDD ``volume_moments(svdd).center``
    planes : which slices, from "xy", "xz", "yz"; one panel each
    pixels : pixels per side of a slice; thickness : samples within this fraction of the
        largest extent from a slice are drawn black, the others light grey
    The region f >= 0 is filled orange, its boundary f = 0 drawn black, the center a blue star.
    """
    import jax.numpy as jnp

    from jaxpose.moments import volume_moments
    from jaxpose.pose.frame import reference_frame
    from jaxpose.pose.pose import normalize
    from jaxpose._validate import check_int, check_names, check_points, check_real
    from jaxpose.occupancy.svdd import SVDD, decision_function, fit_svdd

    planes = [_check_plane(p, "planes") for p in check_names(planes, "planes")]  # before any fit
    pixels, thickness = check_int(pixels, "pixels", 2), check_real(thickness, "thickness", 0)
    if center is not None:
        try:
            given = np.asarray(center, np.float64)
        except (TypeError, ValueError):
            given = None
        if given is None or given.shape != (3,) or not np.all(np.isfinite(given)):
            raise InvalidInputError(f"center must be 3 finite numbers (where the slices cut), got {center!r:.80}")
        center = given
    if isinstance(svdd_or_points, SVDD):
        svdd = svdd_or_points
        mask = np.asarray(svdd.mask, bool)
        points = np.asarray(svdd.points, np.float64)[mask]
        mean, size = np.zeros(3), 1.0
        label = f"gamma={float(svdd.gamma):g}"
    else:
        points = np.asarray(check_points(svdd_or_points), np.float64)  # NaN named per row, not after the rescaling
        m, s = reference_frame(jnp.asarray(points))
        mean, size = np.asarray(m, np.float64), float(s)
        svdd = fit_svdd(jnp.asarray((points - mean) / size), gamma, nu)
        label = f"gamma={gamma:g}, nu={nu:g}"
    if center is None and isinstance(svdd_or_points, SVDD):
        center = np.asarray(volume_moments(svdd, resolution=24).center, np.float64)
    elif center is None:
        center = np.asarray(normalize(jnp.asarray(points), method="ocsvm", gamma=gamma, nu=nu, **normalize_options).center, np.float64)
    center = np.asarray(center, np.float64).reshape(3)
    lo, hi = points.min(axis=0), points.max(axis=0)
    pad = 0.15 * float((hi - lo).max())
    lo, hi = lo - pad, hi + pad
    fig, axes = _figure(ax, 1, len(planes))
    if len(axes) != len(planes):
        raise InvalidInputError(f"got {len(axes)} axes for {len(planes)} planes")
    for a, plane in zip(axes, planes):
        i, j = _PLANES[plane]
        k = 3 - i - j
        u = np.linspace(lo[i], hi[i], pixels)
        v = np.linspace(lo[j], hi[j], pixels)
        uu, vv = np.meshgrid(u, v)
        x = np.empty(uu.shape + (3,))
        x[..., i], x[..., j], x[..., k] = uu, vv, center[k]
        f = np.asarray(decision_function(svdd, jnp.asarray(((x - mean) / size).reshape(-1, 3), svdd.points.dtype)))
        f = f.reshape(uu.shape)
        bound = float(np.abs(f).max()) or 1.0
        a.imshow(f, origin="lower", extent=(lo[i], hi[i], lo[j], hi[j]), cmap="Greys_r", vmin=-bound, vmax=bound,
                 alpha=0.35, interpolation="bilinear")
        if f.max() > 0:
            a.contourf(uu, vv, f, levels=[0.0, np.inf], colors=[REGION_COLOR], alpha=0.55)
            if f.min() < 0:
                a.contour(uu, vv, f, levels=[0.0], colors="k", linewidths=0.8)
        near = np.abs(points[:, k] - center[k]) <= thickness * float((hi - lo).max())
        a.scatter(points[~near, i], points[~near, j], s=1, c="0.75", linewidths=0)
        a.scatter(points[near, i], points[near, j], s=2, c="k", linewidths=0)
        a.plot(center[i], center[j], "*", color=OCSVM_COLOR, ms=10, mec="w", mew=0.6)
        a.set_aspect("equal")
        a.set_xlabel("xyz"[i])
        a.set_ylabel("xyz"[j])
        a.set_title(f"{plane} slice, {label}" if title is None else title, fontsize=8)
    return _finish(fig, path)


# --------------------------------------------------------------------------- 3D shapes
def mesh_3d(mesh_or_points, ax=None, *, color="0.7", alpha=0.5, edgecolor=None, max_faces=6000, point_size=2,
            elev=15, azim=-60, path=None, title=None, label=None, limits=None):
    """A mesh as a Poly3DCollection (at most ``max_faces`` faces, an evenly spaced subset
    beyond), or points (n, 3) as a scatter. ``limits`` : (k, 3) points the equal-aspect view
    must contain (default the shape's vertices)."""
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    v, f = _vertices_faces(mesh_or_points)
    fig, (a,) = _figure(ax, projection="3d", size=(4.0, 4.0))
    if f is not None:
        if len(f) > max_faces:
            f = f[np.linspace(0, len(f) - 1, max_faces).astype(int)]
        poly = Poly3DCollection(v[f], facecolor=color, edgecolor=edgecolor or "none", alpha=alpha,
                                linewidths=0.1, label=label)
        a.add_collection3d(poly)
    else:
        a.scatter(v[:, 0], v[:, 1], v[:, 2], s=point_size, c=color, alpha=alpha, linewidths=0, label=label)
    _equal_3d(a, v if limits is None else np.asarray(limits, float).reshape(-1, 3))
    a.view_init(elev=elev, azim=azim)
    a.set_xlabel("x")
    a.set_ylabel("y")
    a.set_zlabel("z")
    if title:
        a.set_title(title, fontsize=9)
    return _finish(fig, path)


def centers_plot(mesh_or_points, pose=None, gamma=OCSVM.gamma, nu=OCSVM.nu, *, methods=("robust_depth", "surface_centroid",
                 "vertex_mean", "bbox_center", "min_ball"), count=1000, seed=0, plane="xz", ax=None, path=None, title=None,
                 **normalize_options):
    """A shape with the OCSVM center and other centers (names of ``jaxpose.pose.estimators.CENTERS``) marked.

    pose : the OCSVM :class:`jaxpose.Pose` (or (center, scale)); default ``jaxpose.normalize``
        of ``count`` surface samples with (gamma, nu, normalize_options)
    plane : None for a 3D view, or "xy" / "xz" / "yz" for a projection of surface samples
        (markers are never hidden behind the surface there)
    The OCSVM scale is drawn as a circle (sphere outline) of radius ``pose.scale`` about its center.
    """
    import jaxpose
    from jaxpose.pose import estimators

    if plane is not None:
        _check_plane(plane)
    v, f = _vertices_faces(mesh_or_points)
    samples = np.asarray(jaxpose.sample_surface(mesh_or_points, count, seed)) if f is not None else v
    if pose is None:
        pose = jaxpose.normalize(samples, method="ocsvm", gamma=gamma, nu=nu, **normalize_options)
    c, s = _center_scale(pose)
    centers = {"ocsvm": c, **{m: np.asarray(estimators.estimate(mesh_or_points, center=m, scale="unit_cube").center,
                                            float) for m in methods}}
    if plane is None:
        fig = mesh_3d(mesh_or_points, ax, alpha=0.25, title=title)
        a = fig.axes[0] if ax is None else ax
        for name, p in centers.items():
            lab, col, mk = CENTER_STYLES[name]
            a.scatter(*p, marker=mk, c=col, s=80 if name == "ocsvm" else 40, label=lab, depthshade=False)
    else:
        fig, (a,) = _figure(ax, size=(5.0, 4.0))
        i, j = _PLANES[plane]
        a.scatter(samples[:, i], samples[:, j], s=2, c="0.6", linewidths=0)
        t = np.linspace(0, 2 * np.pi, 200)
        a.plot(c[i] + s * np.cos(t), c[j] + s * np.sin(t), "--", color=OCSVM_COLOR, lw=0.8, label="OCSVM scale")
        for name, p in centers.items():
            lab, col, mk = CENTER_STYLES[name]
            a.plot(p[i], p[j], mk, color=col, ms=12 if name == "ocsvm" else 7, mec="k", mew=0.5, label=lab, ls="none")
        a.set_aspect("equal")
        a.set_xlabel("xyz"[i])
        a.set_ylabel("xyz"[j])
        a.set_title(title or f"centers (OCSVM gamma={gamma:g}, nu={nu:g})", fontsize=9)
    a.legend(fontsize=7, loc="best")
    return _finish(fig, path)


# --------------------------------------------------------------------------- Fig. 5, 6, 7
_GREEK = {"gamma": "γ", "nu": "ν"}


def _sweeps(result_sweeps):
    if isinstance(result_sweeps, dict) and "summary" in result_sweeps and "sweeps" not in result_sweeps:
        raise InvalidInputError("the result holds no sweeps (evaluate(..., sweep=True), jaxpose evaluate --sweep, "
                                "records them)")  # (was KeyError 'average')
    if not isinstance(result_sweeps, dict) or not ("param" in result_sweeps or "sweeps" in result_sweeps or all(
            isinstance(v, dict) and "param" in v for v in result_sweeps.values())):  # (a TypeError, AttributeError)
        raise InvalidInputError("result_sweeps must be evaluate()'s result or its 'sweeps', or one sweep() dict, "
                                f"got {result_sweeps!r:.80}")
    if "param" in result_sweeps:  # one sweep
        return {result_sweeps["param"]: result_sweeps}
    if "sweeps" in result_sweeps:  # a whole evaluate() result
        return dict(result_sweeps["sweeps"])
    return dict(result_sweeps)


def _sweep_panel(a, sweep, curve, reference, metric, title):
    p = sweep["param"]
    a.plot(sweep["values"], curve, "o-", color=OCSVM_COLOR, ms=3, label="OCSVM")
    if reference is not None:
        a.axhline(reference, color=SURFACE_COLOR, label="surface centroid")
    fixed = ", ".join(f"{_GREEK.get(k, k)}={v:g}" for k, v in sweep.get("fixed", {}).items())
    a.set_xlabel(_GREEK.get(p, p))
    a.set_ylabel("σ_tr" if metric == "sigma_tr" else "σ_scale")
    a.set_title(f"{title} ({fixed})" if fixed else title, fontsize=8)
    a.grid(alpha=0.3)


def sweep_curves(result_sweeps, *, param=None, per_class=False, metric="sigma_tr", ax=None, path=None, ncols=4):
    """sigma_tr (or ``metric="sigma_scale"``) of OCSVM against gamma and nu, with the surface
    centroid's value as a red line.

    result_sweeps : ``result["sweeps"]`` of :func:`jaxpose.evaluation.evaluate` ({"gamma": sweep,
        "nu": sweep}), a whole result, or one :func:`jaxpose.evaluation.sweep` dict
    per_class : False -> one panel per swept parameter, averaged over classes (Fig. 5 a, b);
        True -> one panel per class for ``param`` (default "nu", else the first; Fig. 6)
    """
    sweeps = _sweeps(result_sweeps)
    if not sweeps:
        raise InvalidInputError("no sweeps to draw")
    if metric not in ("sigma_tr", "sigma_scale"):
        raise InvalidInputError(f"metric must be 'sigma_tr' or 'sigma_scale', got {metric!r}")
    if param is not None and param not in sweeps:
        raise InvalidInputError(f"param {param!r} was not swept; swept: {', '.join(map(repr, sweeps))}")
    ref_key = metric if metric in ("sigma_tr", "sigma_scale") else None
    if not per_class:
        names = [param] if param is not None else [p for p in ("gamma", "nu") if p in sweeps] or list(sweeps)
        fig, axes = _figure(ax, 1, len(names))
        for a, p, letter in zip(axes, names, "abcdefgh"):
            sw = sweeps[p]
            ref = sw.get("surface_centroid", {}).get("average", {}).get(ref_key)
            _sweep_panel(a, sw, sw["average"][metric], ref, metric, f"({letter}) average over classes")
        axes[0].legend(fontsize=7)
        return _finish(fig, path)
    p = param or ("nu" if "nu" in sweeps else next(iter(sweeps)))
    sw = sweeps[p]
    classes = list(sw["per_class"])
    cols = min(ncols, len(classes))
    fig, axes = _figure(ax, math.ceil(len(classes) / cols), cols, size=(2.8, 2.3))
    for a, name in zip(axes, classes):
        ref = sw.get("surface_centroid", {}).get("per_class", {}).get(name, {}).get(ref_key)
        _sweep_panel(a, sw, sw["per_class"][name][metric], ref, metric, name)
    for a in axes[len(classes):]:
        a.set_axis_off()
    axes[0].legend(fontsize=6)
    return _finish(fig, path)


METHOD_COLORS = {  # one colour per method of jaxpose.evaluation.METHODS, the paper's blue and red kept
    "robust": "black",
    "ocsvm": OCSVM_COLOR,
    "surface_centroid": SURFACE_COLOR,
    "vertex_mean": "tab:green",
    "bbox": "tab:purple",
    "min_ball": "tab:brown",
    "solid": "tab:olive",
    "solid_sqrt_area": "tab:cyan",
    "depth_weighted_solid:2": "tab:orange",
    "depth_weighted_solid:4": "tab:pink",
    "depth_weighted_solid": "tab:gray",
}
METRIC_LABELS = {  # axis labels with units
    "sigma_tr": "σ_tr: spread of the centers (mesh units)",
    "sigma_tr_axis": "σ_tr per axis (mesh units)",
    "sigma_scale": "σ_scale (the method's scale units)",
    "cv_scale": "cv = σ_scale / mean scale (dimensionless)",
}


def method_colors(methods) -> dict:
    """{method: colour}, distinct for every method given: :data:`METHOD_COLORS`, then unused
    colours of matplotlib's tab20 for names it does not list."""
    import matplotlib

    out = {m: METHOD_COLORS[m] for m in methods if m in METHOD_COLORS}
    spare = [c for c in matplotlib.colormaps["tab20"].colors
             if all(not np.allclose(c, matplotlib.colors.to_rgb(v)) for v in out.values())]
    for k, m in enumerate(m for m in methods if m not in out):
        out[m] = spare[k % len(spare)]
    return out


def _grouped_bars(a, groups, values, methods, colors):
    """Bars of values[method] (one per group; NaN: left out) side by side per group."""
    width = 0.8 / len(methods)
    x = np.arange(len(groups))
    for n, m in enumerate(methods):
        a.bar(x + (n - (len(methods) - 1) / 2) * width, values[m], width, label=m.replace("_", " "), color=colors[m])
    a.set_xticks(x, [g.replace("_", "\n") for g in groups], fontsize=7)
    a.grid(axis="y", alpha=0.3)


def _legend_outside(fig, axes):
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside right upper", fontsize=7, title="method", title_fontsize=7)


def scale_bars(result, *, metric="sigma_scale", methods=("ocsvm", "surface_centroid"), ax=None, path=None):
    """Per-class bars of ``metric`` (default sigma_scale; the paper's Fig. 7: OCSVM against the
    surface's mean distance, two scales of the same kind) for ``methods`` of an
    :func:`jaxpose.evaluation.evaluate` result, the average over classes last; the legend beside
    the axes, the units on the y axis."""
    _check_result(result, "evaluate")
    from ._validate import check_names

    _check_metric(metric)
    methods = check_names(methods, "methods")  # (a string: its letters, none of them a method)
    per_class = result["per_class"]
    classes = list(per_class)
    methods = [m for m in methods if all(metric in per_class[c].get(m, {}) for c in classes)]
    if not methods:
        raise InvalidInputError("none of the methods is in the result")
    labels = classes + ["average"]
    fig, axes = _figure(ax, size=(min(14.0, max(5.0, 0.2 * len(labels) * len(methods) + 3.0)), 3.4))
    values = {}
    for m in methods:
        vals = [per_class[c][m][metric] for c in classes]
        values[m] = vals + [float(np.mean(vals))]
    _grouped_bars(axes[0], labels, values, methods, method_colors(methods))
    axes[0].set_ylabel(METRIC_LABELS.get(metric, metric), fontsize=8)
    axes[0].set_title(f"{metric} per class (lower is more consistent)", fontsize=9)
    if ax is None:
        _legend_outside(fig, axes)
    else:
        axes[0].legend(fontsize=6)
    return _finish(fig, path)


def class_bars(result, variant=None, *, path=None):
    """Which method is most consistent, per class: σ_tr (top) and cv_scale (bottom) per class and
    their average, one colour per method, for one input variant (default the first) of an
    :func:`jaxpose.evaluation.evaluate` result. Methods that do not apply to the variant are left
    out (named in the title)."""
    _check_result(result, "evaluate")
    variant, block = _variant(_blocks(result), variant)
    per_class = block["per_class"]
    classes = list(per_class)
    every = [row["method"] for row in block["summary"]]
    methods = [m for m in every if all("sigma_tr" in per_class[c].get(m, {}) for c in classes)]
    if not methods:
        raise InvalidInputError(f"no method applies to variant {variant!r}")
    colors = method_colors(every)
    labels = classes + ["average"]
    fig, axes = _figure(None, 2, 1, size=(min(16.0, max(8.0, 0.12 * len(labels) * len(methods) + 3.0)), 2.8))
    for a, metric in zip(axes, ("sigma_tr", "cv_scale")):
        values = {}
        for m in methods:
            vals = [per_class[c][m][metric] for c in classes]
            values[m] = vals + [float(np.mean(vals))]
        _grouped_bars(a, labels, values, methods, colors)
        a.set_ylabel(METRIC_LABELS[metric], fontsize=8)
    skipped = [m for m in every if m not in methods]
    note = f"; n/a here: {', '.join(skipped)}" if skipped else ""
    fig.suptitle(f"Which method is most consistent per class?\nInput variant {variant!r}; lower is better{note}",
                 fontsize=9)
    _legend_outside(fig, axes)
    return _finish(fig, path)


def variant_bars(result, *, metric="sigma_tr", ax=None, path=None):
    """Bars of ``metric`` per input variant and method of an :func:`jaxpose.evaluation.evaluate`
    result (averages over classes; methods that do not apply to a variant are left out); one
    colour per method, the legend beside the axes, the units on the y axis."""
    _check_result(result, "evaluate")
    _check_metric(metric)
    variants = _blocks(result)
    methods = [row["method"] for row in next(iter(variants.values()))["summary"]]
    fig, axes = _figure(ax, size=(min(14.0, 1.6 * len(variants) + 4.0), 3.4))
    values = {}
    for m in methods:
        rows = [{r["method"]: r for r in block["summary"]}[m] for block in variants.values()]
        values[m] = [np.nan if r[metric] is None else r[metric] for r in rows]
    _grouped_bars(axes[0], list(variants), values, methods, method_colors(methods))
    axes[0].set_ylabel(METRIC_LABELS.get(metric, metric), fontsize=8)
    axes[0].set_title(f"{metric} per input variant, averaged over classes (lower is more consistent)", fontsize=9)
    if ax is None:
        _legend_outside(fig, axes)
    else:
        axes[0].legend(fontsize=6, ncol=2)
    return _finish(fig, path)


def variants_figure(result, *, path=None):
    """How each method holds up across input variants: σ_tr (top) and cv_scale (bottom),
    averaged over classes, one colour per method; a method that does not apply to a variant has
    no bar there."""
    _check_result(result, "evaluate")
    variants = _blocks(result)
    methods = [row["method"] for row in next(iter(variants.values()))["summary"]]
    fig, axes = _figure(None, 2, 1, size=(min(14.0, 1.6 * len(variants) + 6.0), 2.8))
    for a, metric in zip(axes, ("sigma_tr", "cv_scale")):
        values = {}
        for m in methods:
            rows = [{r["method"]: r for r in block["summary"]}[m] for block in variants.values()]
            values[m] = [np.nan if r[metric] is None else r[metric] for r in rows]
        _grouped_bars(a, list(variants), values, methods, method_colors(methods))
        a.set_ylabel(METRIC_LABELS[metric], fontsize=8)
    fig.suptitle("How does each method hold up across input variants?\nAverages over classes; lower is better",
                 fontsize=9)
    _legend_outside(fig, axes)
    return _finish(fig, path)


# --------------------------------------------------------------------------- Fig. 8
def overlay_pairs(meshes, poses, *, labels=None, colors=("tab:blue", "tab:orange"), ax=None, path=None,
                  elev=15, azim=-60):
    """Pairs of objects, each normalized by its pose, overlaid (paper, Fig. 8).

    meshes : sequence of pairs (mesh_a, mesh_b) (or (n, 3) points)
    poses : sequence of pairs (pose_a, pose_b) (Pose or (center, scale)) -> one row; or a dict
        {row label: sequence of pairs}, e.g. {"OCSVM": ..., "surface centroid": ...} -> one row each;
        a Pose with a rotation turns its shape too (R (x - center) / scale, as ``Pose.apply``)
    Consistent normalization makes the two shapes of a pair coincide on their common parts.
    """
    rows = dict(poses) if isinstance(poses, dict) else {None: poses}
    meshes = list(meshes)
    for label, ps in rows.items():
        if len(ps) != len(meshes):
            raise InvalidInputError(f"{len(ps)} pose pairs for {len(meshes)} mesh pairs ({label})")
    fig, axes = _figure(ax, len(rows), len(meshes), projection="3d", size=(3.0, 3.0))
    k = 0
    for r, (label, ps) in enumerate(rows.items()):
        for pair, pose_pair, title in zip(meshes, ps, labels or [None] * len(meshes)):
            a = axes[k]
            k += 1
            normalized = []
            for m, pose in zip(pair, pose_pair):
                c, s = _center_scale(pose)
                v, f = _vertices_faces(m)
                r = getattr(pose, "rotation", None)  # (a Pose's rotation was left out: the shapes drawn unturned)
                normalized.append(((v - c) / s if r is None else (v - c) / s @ np.asarray(r, np.float64).T, f))
            limits = np.concatenate([v for v, _ in normalized])
            for (v, f), col in zip(normalized, colors):
                mesh_3d(_Shape(v, f), a, color=col, alpha=0.35, elev=elev, azim=azim, limits=limits)
            a.scatter([0], [0], [0], marker="+", c="k", s=40, depthshade=False)
            a.set_axis_off()
            a.set_box_aspect((1, 1, 1), zoom=1.25)
            head = " - ".join(x for x in (label, title) if x)
            if head:
                a.set_title(head, fontsize=8)
    return _finish(fig, path)


class _Shape:
    def __init__(self, vertices, faces):
        self.vertices, self.faces = vertices, faces


# --------------------------------------------------------------------------- all of an evaluation
def evaluation_figures(result, out_dir) -> list:
    """Write the figures of an :func:`jaxpose.evaluation.evaluate` result into ``out_dir``, one
    per question:

    * ``consistency_<variant>.png`` for every variant: which method is most consistent per class
      (:func:`class_bars`: σ_tr and cv_scale per class and on average);
    * ``variants.png`` with more than one variant: how each method holds up across the input
      variants (:func:`variants_figure`);
    * with ``result["sweeps"]``: ``sweep_average.png`` (the paper's Fig. 5) and
      ``sweep_per_class_<param>.png`` (Fig. 6): how γ and ν change the OCSVM's spread.

    Returns the list of written paths.
    """
    _check_result(result, "evaluate")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    blocks = _blocks(result)
    written = []
    for variant in blocks:
        p = out / f"consistency_{variant}.png"
        class_bars(result, variant, path=p)
        written.append(p)
    if len(blocks) > 1:
        p = out / "variants.png"
        variants_figure(result, path=p)
        written.append(p)
    sweeps = result.get("sweeps") or {}
    if sweeps:
        p = out / "sweep_average.png"
        sweep_curves(sweeps, path=p)
        written.append(p)
        for param in sweeps:
            p = out / f"sweep_per_class_{param}.png"
            sweep_curves(sweeps, param=param, per_class=True, path=p)
            written.append(p)
    return written


# --------------------------------------------------------------------------- rotation
_CLASS_MARKERS = "osD^vP*Xph<>"


def rotation_angles(result, variant=None, *, ax=None, path=None):
    """How far is each frame from its class frame: per-instance angles to the class's mean frame
    (degrees), one column per rotation method, from an :func:`jaxpose.evaluation.evaluate_rotation`
    result; each class its own colour and marker, raw angles filled (left), sign-free hollow
    (right), flagged frames ringed in red; 30 degrees dashed."""
    _check_result(result, "evaluate_rotation")
    variant, block = _variant(result["variants"], variant)
    methods = [row["method"] for row in block["summary"]]
    classes = list(block["per_class"])
    fig, axes = _figure(ax, size=(1.2 * len(methods) + 3.0, 3.8))
    a = axes[0]
    rng = np.random.default_rng(0)
    for k, name in enumerate(classes):
        color, marker = f"C{k % 10}", _CLASS_MARKERS[k % len(_CLASS_MARKERS)]
        for i, method in enumerate(methods):
            cell = block["per_class"][name].get(method, {})
            if "raw" not in cell:
                continue
            raw, free = np.asarray(cell["raw"], float), np.asarray(cell["sign_free"], float)
            flagged = np.nan_to_num(np.asarray(cell["ambiguity"], float), nan=0.0) > 0
            x = i + rng.uniform(-0.12, 0.12, len(raw))
            a.scatter(x - 0.2, raw, s=14, c=color, marker=marker, label=name if i == 0 else None)
            a.scatter(x + 0.2, free, s=14, facecolors="none", edgecolors=color, marker=marker)
            if flagged.any():
                a.scatter(x[flagged] - 0.2, raw[flagged], s=60, facecolors="none", edgecolors="red", linewidths=1.0,
                          label="flagged" if k == 0 and i == 0 else None)
    a.axhline(30, color="0.5", ls="--", lw=0.8)
    a.set_xticks(range(len(methods)), [f"{m}\nraw | sign-free" for m in methods], fontsize=7)
    a.set_ylabel("angle to the class's mean frame (degrees)", fontsize=8)
    a.set_ylim(0, 180)
    (fig.suptitle if ax is None else a.set_title)(
        f"How far is each frame from its class frame?\nVariant {variant!r}; lower is better", fontsize=9)
    if ax is None:
        handles, labels = a.get_legend_handles_labels()
        fig.legend(handles, labels, loc="outside right upper", fontsize=7, title="class", title_fontsize=7)
    else:
        a.legend(fontsize=6)
    return _finish(fig, path)


def rotation_overlay(meshes, poses, *, max_points=3000, ax=None, path=None, title=None):
    """The instances of one class, each normalized by its Pose (center, scale and rotation), overlaid
    as points in the canonical planes (axes 1-0 and 2-0): a frame that holds makes them coincide.
    A pose is a :class:`jaxpose.Pose` or any object with its ``apply`` and ``rotation``; one with a
    ``center`` and ``scale`` must also be one finite pose.

    Raises:
      InvalidInputError: a pose that is no :class:`jaxpose.Pose` (nor has its ``apply``: a
        (center, scale) pair has no frame to overlay), a Pose without a rotation (its frame would
        be the input's axes, drawn as if canonical: give ``rotation=np.eye(3)`` to draw those), one
        that is not one finite pose (as :func:`overlay_pairs`), or not one pose per mesh.
    """
    meshes, poses = list(meshes), list(poses)
    for k, pose in enumerate(poses):
        if not hasattr(pose, "apply"):  # (a (center, scale) pair: AttributeError, no attribute 'apply')
            raise InvalidInputError(f"poses[{k}] must be a Pose with its rotation (normalize(..., rotation=True), "
                                    f"normalize_mesh(..., rotation=...)), got {type(pose).__name__}: a (center, "
                                    "scale) pair has no frame to overlay (plot.overlay_pairs draws those)")
    if len(poses) != len(meshes):
        raise InvalidInputError(f"{len(poses)} poses for {len(meshes)} meshes: one pose per mesh")
    for k, pose in enumerate(poses):
        try:  # one finite pose (a NaN one was drawn as nothing, a batch's a shape error); an object with
            if hasattr(pose, "center") and hasattr(pose, "scale"):  # apply but no center, scale: its apply alone
                _center_scale(pose)
        except InvalidInputError as exc:
            raise InvalidInputError(f"poses[{k}]: {exc}") from None
        if getattr(pose, "rotation", None) is None:  # (was drawn in the input's axes, labelled as canonical)
            raise InvalidInputError(f"poses[{k}] has no rotation: rotation_overlay compares canonical frames; "
                                    "normalize with rotation=True (normalize_mesh(..., rotation=...)), or give "
                                    "Pose.from_center_scale(center, scale, rotation=np.eye(3)) to overlay the "
                                    "input's axes")
    fig, axes = _figure(ax, 1, 2, size=(3.2, 3.6))
    rng = np.random.default_rng(0)
    colors = [f"C{k % 10}" for k in range(len(meshes))]
    for m, pose, col in zip(meshes, poses, colors):
        v, _ = _vertices_faces(m)
        if len(v) > max_points:
            v = v[rng.choice(len(v), max_points, replace=False)]
        y = np.asarray(pose.apply(v), np.float64)
        for a, (h, k) in zip(axes, ((1, 0), (2, 0))):
            a.scatter(y[:, h], y[:, k], s=0.3, c=col, alpha=0.4, linewidths=0)
    for a, (h, k) in zip(axes, ((1, 0), (2, 0))):
        a.set_aspect("equal")
        a.set_xlabel(f"axis {h}")
        a.set_ylabel(f"axis {k}")
        a.invert_yaxis()
    if title:
        fig.suptitle(title, fontsize=9)
    return _finish(fig, path)


def rotation_figures(result, out_dir) -> list:
    """Write ``rotation_angles_<variant>.png`` for every variant of an
    :func:`jaxpose.evaluation.evaluate_rotation` result into ``out_dir``; returns the paths."""
    _check_result(result, "evaluate_rotation")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    for variant in result["variants"]:
        p = out / f"rotation_angles_{variant}.png"
        rotation_angles(result, variant, path=p)
        written.append(p)
    return written
