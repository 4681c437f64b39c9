"""The ``head`` frame's cues, one by one, on the dev meshes (the study behind its sign rule).

``python -m benchmarks.head_frame [--datasets faust-dev,kids-dev] [--variants plain,...]`` from a
source checkout with ../shared beside it. For every rigid-core aligned mesh
(:func:`jaxpose.evaluation.align_core`) of each input variant
(:data:`jaxpose.evaluation.variants.VARIANTS`) the ``head`` frame
(:func:`jaxpose.rotation.rotation.head_frame`) and, along its front-back axis, every front-back cue measured:
the two the frame reads (the jaw below the skull's center, the surface's reach), the same jaw read
with every point counted once (from the lattice points, and from the vertices alone: what a
registered mesh's finer face adds), the whole head surface's centroid, the three solid cues of the
former vote (head beyond the neck ahead of the chest, the body ahead of the chest, the solid just
above the neck reaching forward) and the core frame's front. Per class it prints the sign-free
angle to the class frame, the up axis's angle to the class's mean up, the share flagged and the raw
angles of the unflagged, the neck's constriction, and per cue how often its sign agrees with the
class's majority of best sign flips and the raw angles it would give alone. Asserts nothing.
Every variant of the ``head`` frame beside the other methods: ``python -m benchmarks.rotation``.
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time

import numpy as np

from benchmarks.consistency import DATASETS, SHARED, class_folder
from benchmarks.data import require

SLAB = 0.5  # the former vote's jaw: the solid up to this many head depths above the neck


def cues(sol, frame, found, vertices, faces):
    """{cue name: signed offset along ``frame``'s front-back axis} for one solid (units)."""
    from jaxpose.rotation import rotation
    from jaxpose import sample

    lattice = sample.lattice_points(vertices, faces, rotation.CELL * sol.pitch)
    geo = rotation.head_chest(sol, found, lattice)
    fb = frame.rotation[2] @ sol.frame.T  # the frame's front-back axis in grid coordinates
    jaw, reach, _ = rotation.front_back_cues(geo, fb)

    def each_once(points):  # the jaw with every point counted once (no cells)
        every = rotation.head_surface(points @ sol.frame.T, sol, found, geo.up, geo.eps, cell=None)
        return rotation.front_back_cues(geo._replace(surface=every), fb)[0]

    x, cc, up = geo.centers, geo.chest_center, geo.up
    rel = x - found.neck
    height = rel @ up
    beyond = height > geo.eps  # the whole head, beyond the neck
    slab = beyond & (height < SLAB * found.head_depth + geo.eps) & (np.abs(rel @ np.cross(fb, up)) < found.head_depth)
    return {
        "the jaw ahead of the skull's center (the sign)": jaw,
        "the surface's reach, ahead + behind (the check)": reach,
        "the jaw, each lattice point once (no cells)": each_once(lattice),
        "the jaw, each vertex once (no cells, no face points)": each_once(vertices),
        "the whole head surface ahead of the skull's center": ((geo.surface - geo.skull) @ fb).mean(),
        "the head beyond the neck ahead of the chest (former vote)": (x[beyond].mean(axis=0) - cc) @ fb,
        "the body ahead of the chest (former vote)": (x.mean(axis=0) - cc) @ fb,
        "the solid just above the neck reaching forward (former vote)":
            np.quantile(rel[slab] @ fb, 0.98) + np.quantile(rel[slab] @ fb, 0.02) if slab.any() else 0.0,
        "the core frame's front": frame.rotation[2] @ rotation.core_frame(sol).rotation[2],
    }


def measure(instances):
    """Per-class figures (module docs) of the ``head`` frame on one class's aligned instances."""
    from jaxpose import baselines
    from jaxpose.rotation import parts, rotation
    from jaxpose.evaluation.rotation import class_angles, sign_free_angles

    rows, values, flags, constriction = [], [], [], []
    for m in instances:
        vertices, faces = baselines.split_geometry(m)
        sol = rotation.frame_solid(vertices, faces)
        frame, found = rotation.head_frame(sol, vertices, faces), parts.find_parts(sol)
        c = cues(sol, frame, found, vertices, faces)
        rows.append(frame.rotation)
        values.append(c)
        flags.append(frame.flag)
        constriction.append(found.constriction)
    rows, flags = np.stack(rows), np.array(flags)
    free, best = sign_free_angles(rows)
    raw = class_angles(rows)
    mean_down = rows[:, 0].mean(axis=0) / np.linalg.norm(rows[:, 0].mean(axis=0))
    out = {"raw": raw, "sign_free": free, "flagged": flags, "constriction": np.array(constriction),
           "up": np.degrees(np.arccos(np.clip(rows[:, 0] @ mean_down, -1.0, 1.0))), "cues": {}}
    for name in values[0]:
        v = np.array([c[name] for c in values])
        agree = np.sign(v) * best[:, 2]
        f = np.where(v >= 0, 1.0, -1.0)  # front-back (and left-right, det +1) by this cue alone
        out["cues"][name] = (max((agree > 0).mean(), (agree < 0).mean()),
                             class_angles(rows * np.stack([np.ones_like(f), f, f], axis=1)[:, :, None]))
    return out


def report(title, r, n):
    """Print one class's figures of :func:`measure` as markdown."""
    ok = ~r["flagged"]
    print(f"\n### {title}\n")
    print(f"raw {r['raw'].mean():.1f} / {r['raw'].max():.1f}, sign-free {r['sign_free'].mean():.1f} / "
          f"{r['sign_free'].max():.1f}, up axis {r['up'].mean():.1f} / {r['up'].max():.1f} (mean / max "
          f"degrees); flagged {int(r['flagged'].sum())}/{n}, unflagged raw "
          + (f"{r['raw'][ok].mean():.1f} / {r['raw'][ok].max():.1f}" if ok.any() else "-")
          + f"; the neck's birth / death {r['constriction'].min():.2f}-{r['constriction'].max():.2f}")
    print("\n| front-back cue | agrees | raw mean / max by it alone |\n|---|---|---|")
    for cue, (agree, raw) in r["cues"].items():
        print(f"| {cue} | {100 * agree:.0f}% | {raw.mean():.1f} / {raw.max():.1f} |")


def main(argv=None):
    from jaxpose import datasets
    from jaxpose.evaluation import align_core, make_class

    p = argparse.ArgumentParser(prog="python -m benchmarks.head_frame")
    p.add_argument("--datasets", default=",".join(DATASETS))
    p.add_argument("--variants", default="plain", help="comma-separated names of jaxpose.evaluation.VARIANTS")
    args = p.parse_args(argv)
    require(args.datasets.split(","), SHARED)  # nothing to measure: exit 1, saying where the data comes from
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.datasets.split(","):
            start = time.perf_counter()
            for k, (cls, meshes) in enumerate(datasets.load_folder(class_folder(name, tmp)).items()):
                aligned = align_core(meshes)
                for variant in args.variants.split(","):
                    report(f"{name} {cls} ({len(meshes)} meshes, {variant})",
                           measure(make_class(aligned, variant, 0, k)), len(meshes))
            print(f"\n({name}: {time.perf_counter() - start:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
