"""The ``head`` frame's cues, one by one, on the dev meshes (the study behind its sign rule).

``python -m benchmarks.head_frame [--datasets faust-dev,kids-dev]`` from a source checkout with
../shared beside it. For every rigid-core aligned plain mesh (:func:`jaxpose.evaluation.align_core`)
the ``head`` frame (:func:`jaxpose.rotation.head_frame`: head and trunk from
:func:`jaxpose.parts.find_parts`, up from the chest to the head, left-right and front-back from the
chest's second moments) and, along its front-back axis, every front-back cue measured: the three
the frame's vote uses and the others tried. Per class it prints the sign-free angle to the class
frame, the up axis's angle to the class's mean up, the share flagged and the raw angles of the
unflagged, the neck's constriction, and per cue how often its sign agrees with the class's
majority of best sign flips and the raw angles it would give alone. Asserts nothing. Every variant
of the ``head`` frame beside the other methods: ``python -m benchmarks.rotation``.
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time

import numpy as np

from benchmarks.consistency import DATASETS, SHARED, class_folder


def cues(sol, frame, found):
    """{cue name: signed offset along ``frame``'s front-back axis} for one solid (units): the vote's
    three (:func:`jaxpose.rotation.front_back_cues`) and the others tried."""
    from jaxpose import rotation

    geo = rotation.head_chest(sol, found)
    fb = frame.rotation[2] @ sol.frame.T  # the frame's front-back axis in grid coordinates
    x, dep, chest, cc = geo.centers, geo.depth, geo.chest, geo.chest_center
    beyond = (x - geo.parts.neck) @ geo.up > geo.eps
    below = (x - cc) @ geo.up < -np.linalg.norm(geo.head_center - cc)  # farther from the head than the chest
    head, body, jaw = rotation.front_back_cues(geo, fb)
    return {
        "the head beyond the neck ahead of the chest (vote)": head,
        "the body ahead of the chest (vote)": body,
        "the jaw ahead of the neck (vote)": jaw,
        "the legs ahead of the chest": (x[below].mean(axis=0) - cc) @ fb if below.any() else 0.0,
        "the chest's deepest voxel ahead of its centroid": (x[chest][np.argmax(dep[chest])] - cc) @ fb,
        "the head beyond the neck ahead of the neck": (x[beyond].mean(axis=0) - geo.parts.neck) @ fb,
    }


def measure(instances):
    """Per-class figures (module docs) of the ``head`` frame on one class's aligned instances."""
    from jaxpose import baselines, parts, rotation
    from jaxpose.evaluation.rotation import class_angles, sign_free_angles

    rows, values, flags, constriction = [], [], [], []
    for m in instances:
        sol = rotation.frame_solid(*baselines.split_geometry(m))
        frame, found = rotation.head_frame(sol), parts.find_parts(sol)
        c = cues(sol, frame, found)
        c["the core frame's feet"] = frame.rotation[2] @ rotation.core_frame(sol).rotation[2]
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


def main(argv=None):
    from jaxpose import datasets
    from jaxpose.evaluation import align_core

    p = argparse.ArgumentParser(prog="python -m benchmarks.head_frame")
    p.add_argument("--datasets", default=",".join(DATASETS))
    args = p.parse_args(argv)
    if not SHARED.is_dir():
        print(f"no {SHARED}: nothing to measure", file=sys.stderr)
        return 0
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.datasets.split(","):
            start = time.perf_counter()
            for cls, meshes in datasets.load_folder(class_folder(name, tmp)).items():
                r, n = measure(align_core(meshes)), len(meshes)
                ok = ~r["flagged"]
                print(f"\n### {name} {cls} ({n} meshes, plain)\n")
                print(f"raw {r['raw'].mean():.1f} / {r['raw'].max():.1f}, sign-free {r['sign_free'].mean():.1f} / "
                      f"{r['sign_free'].max():.1f}, up axis {r['up'].mean():.1f} / {r['up'].max():.1f} (mean / max "
                      f"degrees); flagged {int(r['flagged'].sum())}/{n}, unflagged raw "
                      + (f"{r['raw'][ok].mean():.1f} / {r['raw'][ok].max():.1f}" if ok.any() else "-")
                      + f"; the neck's birth / death {r['constriction'].min():.2f}-{r['constriction'].max():.2f}")
                print("\n| front-back cue | agrees | raw mean / max by it alone |\n|---|---|---|")
                for cue, (agree, raw) in r["cues"].items():
                    print(f"| {cue} | {100 * agree:.0f}% | {raw.mean():.1f} / {raw.max():.1f} |")
            print(f"\n({name}: {time.perf_counter() - start:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
