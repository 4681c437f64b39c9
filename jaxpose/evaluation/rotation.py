r"""Consistency of canonical frames within classes: ``evaluate_rotation`` and its measures.

Every object of a class shares the pose of its rigid core (after :func:`align_core`), so a frame
that holds under articulation gives every instance the same rotation. For one class with frames
R_1..R_n (proper rotations, rows = axes):

* the class frame :math:`\bar R` is the chordal L2 mean, the projection of
  :math:`\frac1n\sum_k R_k` onto SO(3) (:func:`chordal_mean`);
* ``raw``: the geodesic angle :math:`\theta_k = \lvert\log(R_k \bar R^T)\rvert` of each instance
  to it, in degrees (:func:`angle`); a class's figures are the mean and the max over instances;
* ``sign_free``: the same after each instance may take the proper sign flip of its axes
  (identity or two axes negated) that brings it closest to the mean of the flipped frames
  (:func:`sign_free_angles`): what is left when every sign is right, the error of the axes alone.

A dataset's figure is the plain average of its classes' figures. Instances flagged as ambiguous
(``Frame.flag``) are counted, and the raw figures of the unflagged ones reported beside.
"""
from __future__ import annotations

import time

import numpy as np

from .._validate import (InvalidInputError, JaxposeError, check_bool, check_callback, check_int, check_known, check_names,
                         is_name, is_real_dtype)
from . import alignment
from .consistency import _check_classes, _check_variants
from .tables import check_result, class_tables, counted
from .variants import make_class

__all__ = ["PROPER_FLIPS", "angle", "chordal_mean", "class_angles", "sign_free_angles", "evaluate_rotation",
           "format_rotation_table", "format_rotation_per_class", "ROTATION_KEYS", "FAR"]

PROPER_FLIPS = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], dtype=np.float64)
FAR = 30.0  # degrees: a frame farther than this from its class's frame is a wrong frame (``*_over_30``)
ROTATION_KEYS = ("raw_mean", "raw_max", "sign_free_mean", "sign_free_max", "flagged", "unflagged_mean",
                 "unflagged_max", "flagged_over_30", "unflagged_over_30")


def _real_array(value, name, shape, what):
    """``value`` as a float64 array of finite reals whose shape passes ``shape``; InvalidInputError
    ('{name} must be {what}, got ...') otherwise."""
    try:
        arr = np.asarray(value)
    except (TypeError, ValueError):  # ragged and the like
        arr = None
    if arr is None or not is_real_dtype(arr.dtype) or not shape(arr.shape) or not np.all(np.isfinite(arr)):
        got = f"shape {arr.shape}" if arr is not None and is_real_dtype(arr.dtype) and not shape(arr.shape) else f"{value!r:.80}"
        raise InvalidInputError(f"{name} must be {what}, got {got}")
    return arr.astype(np.float64)


def _rotations(rotations):
    """rotations as an (n, 3, 3) float64 array (n >= 1) of finite numbers, each a proper rotation
    (R R^T = I within :func:`jaxpose.pose.result.rotation_tol` of its dtype, the Pose's rule; det R > 0); InvalidInputError otherwise (a matrix that
    is not one gave an angle all the same: zeros read 180 degrees from their "mean")."""
    from ..pose.result import rotation_tol

    tol = rotation_tol(getattr(rotations, "dtype", None))
    rs = _real_array(rotations, "rotations", lambda s: len(s) == 3 and s[0] >= 1 and s[1:] == (3, 3),
                     "an (n, 3, 3) array of finite numbers, n >= 1")
    deviation = np.max(np.abs(rs @ np.swapaxes(rs, 1, 2) - np.eye(3)), axis=(1, 2))
    bad = np.flatnonzero((deviation > tol) | (np.linalg.det(rs) <= 0))
    if len(bad):
        k = int(bad[0])
        raise InvalidInputError(f"rotations must be proper rotations (R R^T = I within {tol:g}, det R = +1); "
                                f"{len(bad)} of {len(rs)} are not, e.g. rotations[{k}] (|R R^T - I| "
                                f"{deviation[k]:.3g}, det {np.linalg.det(rs[k]):.3g})")
    return rs


def angle(a, b):
    """Geodesic angle in degrees between rotations a, b (3, 3) of m = a b^T: atan2(sin, cos) with
    cos = (trace m - 1) / 2 and sin = |vee(m - m^T)| / 2 (accurate at small angles too)."""
    a, b = (_real_array(r, name, lambda s: s == (3, 3), "a (3, 3) array of finite numbers") for r, name in ((a, "a"), (b, "b")))
    return _angle(a, b)


def _angle(a, b):
    """:func:`angle` of checked (3, 3) float64 arrays (the loops below check once, outside)."""
    m = a @ b.T
    w = np.array([m[2, 1] - m[1, 2], m[0, 2] - m[2, 0], m[1, 0] - m[0, 1]])
    return float(np.degrees(np.arctan2(0.5 * np.linalg.norm(w), 0.5 * (np.trace(m) - 1.0))))


def chordal_mean(rotations):
    """The chordal L2 mean of rotations (n, 3, 3): the nearest rotation to their average (SVD)."""
    u, _, vt = np.linalg.svd(np.mean(_rotations(rotations), axis=0))
    return u @ np.diag([1.0, 1.0, np.sign(np.linalg.det(u @ vt)) or 1.0]) @ vt


def class_angles(rotations):
    """(n,) angles in degrees of each rotation (n, 3, 3) to their chordal mean."""
    rotations = _rotations(rotations)
    mean = chordal_mean(rotations)
    return np.array([_angle(r, mean) for r in rotations])


def sign_free_angles(rotations, iterations=10):
    """(n,) angles to the class frame when each instance may take its best proper sign flip.

    Alternates the chordal mean of the flipped frames and each instance's best flip (at most
    ``iterations`` times, an int >= 1), from every instance as a start; the start with the smallest
    mean angle wins. Returns (angles, flips (n, 3)).
    """
    rs = _rotations(rotations)
    iterations = check_int(iterations, "iterations", 1)  # (0 was UnboundLocalError, "2" a TypeError)
    best = None
    for start in range(len(rs)):
        mean = rs[start]
        for _ in range(iterations):
            flipped = np.array([min((f[:, None] * r for f in PROPER_FLIPS), key=lambda x: _angle(x, mean)) for r in rs])
            new = chordal_mean(flipped)
            done = np.allclose(new, mean)
            mean = new
            if done:
                break
        a = np.array([_angle(x, mean) for x in flipped])
        if best is None or a.mean() < best[0].mean():
            best = (a, np.sign(np.sum(flipped * rs, axis=2)))
    return best


def _summary_of_class(frames):
    rs = np.stack([f.rotation for f in frames])
    raw = class_angles(rs)
    free, _ = sign_free_angles(rs)
    amb = np.array([f.ambiguity for f in frames], np.float64)
    out = {"raw": raw.tolist(), "sign_free": free.tolist(), "ambiguity": amb.tolist(),
           "raw_mean": float(raw.mean()), "raw_max": float(raw.max()),
           "sign_free_mean": float(free.mean()), "sign_free_max": float(free.max()),
           "flagged": None, "unflagged_mean": None, "unflagged_max": None, "flagged_over_30": None,
           "unflagged_over_30": None}
    if np.all(np.isfinite(amb)):
        flag = amb > 0
        out["flagged"] = float(flag.mean())
        if (~flag).any():
            out["unflagged_mean"], out["unflagged_max"] = float(raw[~flag].mean()), float(raw[~flag].max())
        if (raw > FAR).any():
            out["flagged_over_30"] = float(flag[raw > FAR].mean())
        out["unflagged_over_30"] = int(np.sum((raw > FAR) & ~flag))
    return out


def _mean_or_none(values):
    values = [v for v in values if v is not None]
    return float(np.mean(values)) if values else None


def evaluate_rotation(classes, methods=None, variants=("plain",), align_core=False, seed=0, progress=None,
                      frames=False, core_weight="vertices", **options) -> dict:
    """Within-class agreement of canonical frames for each rotation method and input variant.

    Args:
      classes: {class name: [Trimesh, ...]} (at least 2 per class).
      methods: names of :data:`jaxpose.rotation.rotation.ROTATIONS`, each once (default: all of them).
      variants: names of :data:`jaxpose.evaluation.variants.VARIANTS`, each once, made from the aligned meshes.
      align_core: first rigidly align each class (:func:`jaxpose.evaluation.align_core`).
      core_weight: ``"vertices"`` or ``"area"``, ``align_core``'s ``weight``.
      seed: seeds the variants (and the OCSVM samples).
      progress: optional callable(done, total, message).
      frames: also return each instance's rotation (``per_class[...][method]["rotations"]``).
      options: for :func:`jaxpose.rotation.rotation.frame_of` (``resolution``; ``ocsvm`` dict).

    Returns:
      ``{"params", "variants": {variant: {"summary": [row, ...], "per_class": {class: {method:
      cell}}}}}``. A row holds ``method``, the class averages of ``raw_mean``, ``raw_max``,
      ``sign_free_mean``, ``sign_free_max`` (degrees), ``flagged`` (share of instances),
      ``unflagged_mean`` / ``unflagged_max`` (raw, unflagged instances), ``flagged_over_30`` (share
      of the instances above 30 degrees that are flagged), ``unflagged_over_30`` (the number of
      instances above 30 degrees left unflagged, summed over the classes: frames that are wrong and
      do not say so), ``raw_worst`` (the largest raw angle of any instance) and ``seconds`` (per
      instance); None
      where a method does not apply (with ``error``). A cell holds the same keys for one class
      and the per-instance ``raw``, ``sign_free`` angles and ``ambiguity``.
    """
    from ..rotation.core import frame_solid
    from ..rotation.rotation import ROTATIONS, SOLID_FRAMES, check_frame_options, frame_of
    from .. import baselines

    _check_classes(classes)
    methods = ROTATIONS if methods is None else check_names(methods, "methods", what="rotation method")
    unknown = [m for m in methods if not is_name(m, ROTATIONS)]
    if unknown:
        raise InvalidInputError(f"unknown rotation methods {unknown}; valid: {', '.join(ROTATIONS)}")
    variants = _check_variants(variants)
    alignment.check_core_weight(core_weight)
    seed = check_int(seed, "seed", 0)  # a NumPy or JAX integer scalar as its int (a bool, a float refused)
    align_core, frames = check_bool(align_core, "align_core"), check_bool(frames, "frames")
    check_callback(progress, "progress")
    check_known(options, ("resolution", "ocsvm"))  # (frame_of's TypeError at the first shape)
    check_frame_options(options.get("resolution"), options.get("ocsvm"))  # not each method's error cell
    unread = [(key, readers) for key, readers in (("resolution", SOLID_FRAMES), ("ocsvm", ("ocsvm",)))
              if options.get(key) not in (None, {}) and not set(readers) & set(methods)]
    for key, readers in unread:  # given, nothing would read it (frame_of refuses it where a frame does not)
        raise InvalidInputError(f"{key} is an option of the {' and '.join(readers)} frame{'s' if len(readers) > 1 else ''}, "
                                f"which the methods {', '.join(methods)} do not include; leave it out")
    if align_core:
        classes = alignment.align_classes(classes, weight=core_weight)
    ocsvm = {"seed": seed, **options.pop("ocsvm", {})}
    total, done, out = len(variants) * len(classes), 0, {}
    for variant in variants:
        per_class, seconds, count = {}, dict.fromkeys(methods, 0.0), 0
        for k, (name, meshes) in enumerate(classes.items()):
            if progress is not None:
                progress(done, total, f"rotation {variant}: {name} ({len(meshes)} objects)")
            done += 1
            found = {m: [] for m in methods}
            for shape in make_class(meshes, variant, seed, k):
                count += 1
                sol = None
                for method in methods:
                    start = time.perf_counter()
                    try:
                        if method in SOLID_FRAMES and sol is None:  # one solid for both frames
                            sol = frame_solid(*baselines.split_geometry(shape), options.get("resolution"))
                        # each frame gets what it reads (frame_of refuses the others): the solid holds the resolution
                        given = {"sol": sol} if method in SOLID_FRAMES else {"ocsvm": ocsvm} if method == "ocsvm" else {}
                        found[method].append(frame_of(shape, method, **given))
                    except (JaxposeError, ValueError) as exc:
                        found[method].append(exc)
                    seconds[method] += time.perf_counter() - start
            cells = {}
            for method, fs in found.items():
                errors = [f for f in fs if isinstance(f, Exception)]
                if errors:
                    cells[method] = {"error": str(errors[0]), "failed": len(errors)}
                    continue
                cells[method] = _summary_of_class(fs)
                if frames:
                    cells[method]["rotations"] = [f.rotation.tolist() for f in fs]
            per_class[name] = cells
        rows = []
        for method in methods:
            cells = [per_class[c][method] for c in per_class]
            row = {"method": method, "seconds": seconds[method] / max(count, 1)}
            if any("error" in c for c in cells):
                row.update(dict.fromkeys(ROTATION_KEYS), raw_worst=None,
                           error=next(c["error"] for c in cells if "error" in c))
            else:
                row.update({key: _mean_or_none([c[key] for c in cells]) for key in ROTATION_KEYS
                            if key != "unflagged_over_30"})
                row["raw_worst"] = float(max(c["raw_max"] for c in cells))
                misses = [c["unflagged_over_30"] for c in cells if c["unflagged_over_30"] is not None]
                row["unflagged_over_30"] = int(sum(misses)) if misses else None
            rows.append(row)
        out[variant] = {"summary": rows, "per_class": per_class}
    if progress is not None:
        progress(total, total, "done")
    params = {"align_core": bool(align_core), "core_weight": core_weight, "seed": int(seed), "methods": list(methods),
              "variants": list(variants), "classes": list(classes),
              "objects": {c: len(m) for c, m in classes.items()}}
    return {"params": params, "variants": out}


def format_rotation_table(result) -> str:
    """The summaries of :func:`evaluate_rotation` as terminal tables, one per variant (degrees)."""
    check_result(result, "evaluate_rotation")
    core = result["params"].get("core_weight", "vertices")
    core = f" (core by {core})" if result["params"]["align_core"] and core != "vertices" else ""
    n = len(result["params"]["classes"])
    lines = [f"{counted(n, 'class')}, align_core={result['params']['align_core']}{core}, "
             "angles to the class frame (chordal mean), degrees, mean / max over instances"]

    def num(v, fmt="{:.1f}"):
        return "n/a" if v is None else fmt.format(v)

    for variant, block in result["variants"].items():
        head = (f"{'method':<14}{'raw mean':>10}{'raw max':>10}{'free mean':>11}{'free max':>10}"
                f"{'flagged':>9}{'unflagged':>15}{'>30':>5}{'s/shape':>9}")
        lines += ["", f"variant {variant}", head, "-" * len(head)]
        for row in block["summary"]:
            unflagged = "" if row["unflagged_mean"] is None else \
                f"{row['unflagged_mean']:.1f} / {row['unflagged_max']:.1f}"
            flagged = "" if row["flagged"] is None else f"{100 * row['flagged']:.0f}%"
            miss = "" if row["unflagged_over_30"] is None else str(row["unflagged_over_30"])
            lines.append(f"{row['method']:<14}{num(row['raw_mean']):>10}{num(row['raw_max']):>10}"
                         f"{num(row['sign_free_mean']):>11}{num(row['sign_free_max']):>10}{flagged:>9}"
                         f"{unflagged:>15}{miss:>5}{row['seconds']:>9.3f}")
    lines += ["", "unflagged: raw mean / max of the unflagged instances; >30: instances over 30 degrees off left unflagged"]
    return "\n".join(lines)


def format_rotation_per_class(result) -> str:
    """The per-class cells of :func:`evaluate_rotation` as terminal tables, one per class.

    Rows: methods; columns per variant: the raw mean / max angle to the class frame (degrees), the
    share of instances flagged and the number of instances more than 30 degrees off left
    unflagged (``>30``; blank for a method without a flag). ``*`` marks the lowest raw mean of a
    column; n/a where a method does not apply.
    """
    check_result(result, "evaluate_rotation")

    def rows(cells, methods):
        lows = {}
        for v, block in cells.items():
            means = [block[m]["raw_mean"] for m in methods if "error" not in block[m]]
            lows[v] = min(means) if means else None
        texts = {}
        for m in methods:
            text = ""
            for v, block in cells.items():
                cell = block[m]
                if "error" in cell:
                    text += f"{'n/a':>16}{'':>7}{'':>5}"
                    continue
                mark = "*" if cell["raw_mean"] <= lows[v] else " "
                flag = "" if cell["flagged"] is None else f"{100 * cell['flagged']:.0f}%"
                miss = "" if cell["unflagged_over_30"] is None else str(cell["unflagged_over_30"])
                text += f"{cell['raw_mean']:>7.1f} / {cell['raw_max']:>5.1f}{mark}{flag:>7}{miss:>5}"
            texts[m] = text
        return texts

    lines = class_tables(result["variants"], result.get("params", {}).get("objects", {}),
                         f"{'mean / max':>16}{'flag':>7}{'>30':>5}", 28, rows)
    lines += ["", "angles in degrees to the class frame (chordal mean), raw; * lowest mean of the column; "
              "flag: share flagged; >30: instances over 30 degrees off left unflagged"]
    return "\n".join(lines)
