"""Canonical frames on the dev meshes: every rotation method in all five input variants (the acceptance table).

``python -m benchmarks.rotation [--json OUT] [--datasets faust-dev,kids-dev] [--variants ...] [--figures DIR]``
from a source checkout with ../shared beside it. Each class is rigid-core aligned, every variant made
from the aligned meshes, and every method of :data:`jaxpose.rotation.rotation.ROTATIONS` measured by
:func:`jaxpose.evaluation.evaluate_rotation` (angle of each instance's frame to the class's chordal
mean frame; raw and sign-free). Also: the ``core`` frame without its part cue and cross-check (the
moments alone), the equivariance error (random rotations of a few meshes), the acceptance verdict
(mean <= 10, max <= 30 degrees on plain meshes, other variants <= 2x plain) and, with ``--figures``,
the per-instance angles and one class overlaid in its canonical frames. Prints markdown; asserts nothing.
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks.consistency import DATASETS, SHARED, class_folder
from benchmarks.data import require

ABLATION = "core (moments only)"


def _ablation(classes, variants, seed=0):
    """Summary rows of the core frame without the feet cue and the cross-check, per variant."""
    from jaxpose import baselines
    from jaxpose.rotation import rotation
    from jaxpose.evaluation.rotation import class_angles, sign_free_angles
    from jaxpose.evaluation.variants import make_class

    out = {}
    for variant in variants:
        cells = []
        for k, meshes in enumerate(classes.values()):
            frames = [rotation.core_frame(rotation.frame_solid(*baselines.split_geometry(s)), feet=False,
                                          cross_check=False) for s in make_class(meshes, variant, seed, k)]
            rs = np.stack([f.rotation for f in frames])
            raw, free = class_angles(rs), sign_free_angles(rs)[0]
            flag = np.array([f.flag for f in frames])
            cells.append([raw.mean(), raw.max(), free.mean(), free.max(), flag.mean(),
                          raw[~flag].mean() if (~flag).any() else np.nan,
                          raw[~flag].max() if (~flag).any() else np.nan])
        c = np.nanmean(np.array(cells, float), axis=0)
        out[variant] = {"method": ABLATION, "raw_mean": c[0], "raw_max": c[1], "sign_free_mean": c[2],
                        "sign_free_max": c[3], "flagged": c[4], "unflagged_mean": c[5], "unflagged_max": c[6]}
    return out


def equivariance(classes, rotations=3, meshes=2):
    """Max angle (radians) between frame(Q x) and frame(x) Q^T for the core, head and ocsvm frames, over
    the first meshes of each class and random rotations Q: {method: {"unflagged": .., "all": ..}}."""
    import trimesh

    from jaxpose.evaluation.rotation import angle
    from jaxpose.rotation.rotation import frame_of

    rng = np.random.default_rng(0)
    worst = {k: {"unflagged": 0.0, "all": 0.0} for k in ("core", "head", "ocsvm")}
    for ms in classes.values():
        for m in ms[:meshes]:
            base = {k: frame_of(m, k) for k in worst}
            for _ in range(rotations):
                q, r = np.linalg.qr(rng.normal(size=(3, 3)))
                q = q * np.sign(np.diag(r))
                q = q if np.linalg.det(q) > 0 else -q
                moved = trimesh.Trimesh(np.asarray(m.vertices) @ q.T + 1.0, m.faces, process=False)
                for k in worst:
                    e = np.radians(angle(frame_of(moved, k).rotation, base[k].rotation @ q.T))
                    worst[k]["all"] = max(worst[k]["all"], e)
                    if not base[k].flag:
                        worst[k]["unflagged"] = max(worst[k]["unflagged"], e)
    return worst


def _fmt(v, pct=False):
    if v is None or (isinstance(v, float) and np.isnan(v)):
        return "-"
    return f"{100 * v:.0f}%" if pct else f"{v:.1f}"


def markdown(result, ablation=None):
    """One markdown table per variant of an evaluate_rotation result (degrees)."""
    lines = []
    for variant, block in result["variants"].items():
        rows = list(block["summary"]) + ([ablation[variant]] if ablation else [])
        lines += ["", f"**{variant}**", "",
                  "| method | raw mean | raw max | sign-free mean | sign-free max | flagged | unflagged raw mean / max | s / shape |",
                  "|---|---|---|---|---|---|---|---|"]
        for r in rows:
            if r.get("raw_mean") is None:
                lines.append(f"| {r['method']} | n/a | | | | | | |")
                continue
            unf = "-" if r.get("unflagged_mean") is None or np.isnan(r["unflagged_mean"]) else \
                f"{r['unflagged_mean']:.1f} / {r['unflagged_max']:.1f}"
            sec = f"{r['seconds']:.3f}" if "seconds" in r else "-"
            lines.append(f"| {r['method']} | {_fmt(r['raw_mean'])} | {_fmt(r['raw_max'])} | {_fmt(r['sign_free_mean'])} | "
                         f"{_fmt(r['sign_free_max'])} | {_fmt(r.get('flagged'), True)} | {unf} | {sec} |")
    return "\n".join(lines)


def verdict(result, method="core"):
    """The acceptance criteria for one method: plain mean <= 10 (class average), no instance above 30
    degrees; other variants' means <= 2x plain."""
    rows = {v: next(r for r in b["summary"] if r["method"] == method) for v, b in result["variants"].items()}
    plain = rows.get("plain")
    out = {}
    if plain is not None and plain["raw_mean"] is not None:
        out["plain_mean<=10"] = plain["raw_mean"] <= 10.0
        out["plain_every_instance<=30"] = plain["raw_worst"] <= 30.0
        for v, r in rows.items():
            if v != "plain" and r["raw_mean"] is not None:
                out[f"{v}<=2x_plain"] = r["raw_mean"] <= 2.0 * plain["raw_mean"]
    return out


def figures(name, classes, result, out_dir):
    """rotation_angles_<name>.png (plain) and rotation_overlay_<name>.png (first class, core frames)."""
    from jaxpose import mesh, plot
    from jaxpose.evaluation import align_core

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    plot.rotation_angles(result, "plain", path=out / f"rotation_angles_{name}.png")
    first, meshes = next(iter(classes.items()))
    aligned = align_core(meshes)
    poses = [mesh.normalize_mesh(m, rotation=True)[1] for m in aligned]
    plot.rotation_overlay(aligned, poses, path=out / f"rotation_overlay_{name}.png",
                          title=f"{name} {first}: normalized with rotation=True")


def main(argv=None):
    from jaxpose import datasets
    from jaxpose.evaluation import VARIANTS, evaluate_rotation

    p = argparse.ArgumentParser(prog="python -m benchmarks.rotation")
    p.add_argument("--datasets", default=",".join(DATASETS))
    p.add_argument("--variants", default=",".join(VARIANTS))
    p.add_argument("--methods", default=None)
    p.add_argument("--json", default=None)
    p.add_argument("--figures", default=None)
    p.add_argument("--no-ablation", action="store_true")
    args = p.parse_args(argv)
    require(args.datasets.split(","), SHARED)  # nothing to measure: exit 1, saying where the data comes from
    variants = args.variants.split(",")
    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.datasets.split(","):
            start = time.perf_counter()
            classes = datasets.load_folder(class_folder(name, tmp))
            result = evaluate_rotation(classes, methods=args.methods.split(",") if args.methods else None,
                                       variants=variants, align_core=True)
            seconds = time.perf_counter() - start
            from jaxpose.evaluation import align_core

            aligned = {c: align_core(m) for c, m in classes.items()}
            ablation = None if args.no_ablation else _ablation(aligned, variants)
            eq = equivariance(aligned)
            print(f"\n### {name} ({seconds:.0f} s, loading included; angles in degrees, class averages)")
            print(markdown(result, ablation))
            print("\nequivariance, max angle(frame(Q x), frame(x) Q^T) in radians over 2 meshes per class x 3 "
                  "random rotations (unflagged frames / all): "
                  + ", ".join(f"{k} {v['unflagged']:.1e} / {v['all']:.1e}" for k, v in eq.items()))
            for method in ("core", "head"):
                print(f"acceptance ({method}):", json.dumps(verdict(result, method)))
            if args.figures:
                figures(name, classes, result, args.figures)
            result.update(seconds=seconds, equivariance=eq, ablation=ablation)
            out[name] = result
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=1, default=float))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
