"""A head-and-chest frame found from the depth field's merge tree (a prototype, not in the library).

``python -m benchmarks.head_frame [--datasets faust-dev,kids-dev]`` from a source checkout with
../shared beside it. For every rigid-core aligned mesh (:func:`jaxpose.evaluation.align_core`):

1. The robust solid of the ``core`` frame (:func:`jaxpose.rotation.frame_solid`) and its depth field
   D (distance to the outside).
2. The merge tree of the superlevel sets {D > t} (:func:`merge_tree`, 26-connected voxels): every
   local maximum of D is born at its depth and dies at the saddle where it joins a deeper one;
   persistence = birth - death.
3. Head and trunk: the neck is the most constricted saddle between thick parts, the largest
   birth / death among maxima born at least :data:`THICK` times as deep as the deepest (a neck is
   far thinner than the head it carries; a waist between chest and pelvis, or a knee, is not); the
   head and the trunk are the two components of {D > death} that meet there, the smaller one the
   head (a child's head is as thick as its trunk, so depth alone does not tell them apart).
4. Axes: ``up`` from the chest (the depth^2-weighted centroid of the solid below the neck saddle
   and within 2 head depths of it) to the head blob's centroid; the other two from the chest's
   second moments across ``up`` (left-right the wider, front-back the thinner).
5. Signs: ``up`` points to the head; front-back by one of the cues :func:`head_frame` returns, each
   measured for how often it agrees, within a class, with the majority of the instances' best sign flips.

Prints per class: the sign-free angle to the class frame (:func:`jaxpose.evaluation.rotation.sign_free_angles`),
the ``up`` axis's angle to the class mean (and how many ``up`` point against the ``core`` frame's
first axis, which points to the feet where that frame is right), the neck's constriction, and
per front-back cue its agreement and the raw angles it gives. Asserts nothing.
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time

import numpy as np
from scipy import ndimage

from benchmarks.consistency import DATASETS, SHARED, class_folder

THICK = 0.5  # the head is at least half as deep as the deepest part (the trunk); hands and feet are not
CHEST = 2.0  # the chest: solid below the neck saddle within this many head depths of it
CHEST_POWER = 2.0  # depth exponent of the chest's weights
_NEIGHBOURS = np.array([(a, b, c) for a in (-1, 0, 1) for b in (-1, 0, 1) for c in (-1, 0, 1) if (a, b, c) != (0, 0, 0)])


def merge_tree(inside, depth):
    """The merge tree of the superlevel sets of ``depth`` on the ``inside`` voxels (26-connected).

    Returns a list of (birth, death, peak, saddle, joins) per local maximum, most persistent first:
    birth its depth, death the depth at which it joins a deeper maximum (0 for the deepest), peak,
    saddle and the peak of the component it joins as flat voxel indices (-1 for the deepest).
    Union-find over voxels in decreasing depth.
    """
    shape = inside.shape
    d = np.where(inside, depth, -np.inf).ravel()
    flat = np.flatnonzero(inside.ravel())
    order = flat[np.argsort(-d[flat], kind="stable")]
    strides = np.array([shape[1] * shape[2], shape[2], 1])
    coords = np.stack(np.unravel_index(order, shape), axis=1)
    parent = np.full(d.size, -1, np.int64)
    peak = {}

    def find(x):
        root = x
        while parent[root] != root:
            root = parent[root]
        while parent[x] != root:
            parent[x], x = root, parent[x]
        return root

    out = []
    for v, xyz in zip(order.tolist(), coords):
        nb = xyz + _NEIGHBOURS
        ok = np.all((nb >= 0) & (nb < shape), axis=1)
        roots = {find(int(u)) for u in (nb[ok] @ strides) if parent[u] >= 0}
        parent[v] = v
        if not roots:
            peak[v] = v
            continue
        roots = sorted(roots, key=lambda r: -d[peak[r]])
        for r in roots[1:]:  # the shallower maxima die here
            out.append((d[peak[r]], d[v], peak[r], v, peak[roots[0]]))
            parent[r] = roots[0]
        parent[v] = roots[0]
    top = find(int(order[0]))
    out.append((d[peak[top]], 0.0, peak[top], -1, -1))
    return sorted(out, key=lambda r: -(r[0] - r[1]))


def _world(sol, voxels):
    """World coordinates of voxel centers: (n, 3) for a mask of the grid, (3,) for one flat index."""
    idx = np.stack(np.nonzero(voxels), 1) if np.ndim(voxels) == 3 else np.array(np.unravel_index(voxels, sol.inside.shape))
    return (sol.origin + sol.pitch * (idx + 0.5)) @ sol.frame


def neck(tree):
    """The entry of :func:`merge_tree` with the largest birth / death among maxima born at least
    ``THICK`` times as deep as the deepest: the most constricted saddle between thick parts."""
    top = max(r[0] for r in tree)
    joins = [r for r in tree if r[1] > 0 and r[0] >= THICK * top]
    if not joins:
        raise ValueError("the solid has no saddle between thick parts: no head to find")
    return max(joins, key=lambda r: r[0] / r[1])


def head_and_trunk(sol):
    """Boolean masks (trunk, head) of the two blobs that meet at the neck (:func:`neck`), the neck
    point (3,) in world coordinates, the head's depth and the neck's constriction birth / death."""
    birth, death, peak, saddle, joins = neck(merge_tree(sol.inside, sol.depth))
    lab, _ = ndimage.label(sol.depth > death, structure=np.ones((3, 3, 3), bool))
    a, b = lab == lab.ravel()[joins], lab == lab.ravel()[peak]
    trunk, head = (a, b) if a.sum() >= b.sum() else (b, a)
    head_depth = sol.depth.ravel()[joins] if head is a else birth
    return trunk, head, _world(sol, saddle), head_depth, birth / death


def head_frame(sol):
    """The frame of one solid: rows (up, left-right, front-back) (3, 3), det +1, front-back's sign
    not yet set; {cue name: signed offset along front-back}; the neck's constriction."""
    trunk, head, neck, head_depth, constriction = head_and_trunk(sol)
    x, dep = _world(sol, sol.inside), sol.depth[sol.inside]
    hc = _world(sol, head).mean(axis=0)
    rel = x - neck
    chest = (rel @ (hc - neck) < 0) & (np.linalg.norm(rel, axis=1) < CHEST * head_depth)
    w = dep[chest] ** CHEST_POWER
    cc = (w @ x[chest]) / w.sum()
    up = (hc - cc) / np.linalg.norm(hc - cc)
    d = (x[chest] - cc) @ (np.eye(3) - np.outer(up, up))
    _, e = np.linalg.eigh((d * w[:, None]).T @ d / w.sum())
    fb = e[:, 1]
    length = np.linalg.norm(hc - cc)
    beyond = (x - neck) @ up > 0  # the solid beyond the neck: the head
    below = (x - cc) @ up < -length  # the solid farther from the head than the chest: hips and legs
    height, side, ahead = ((x - neck) @ up, (x - neck) @ np.cross(fb, up), (x - neck) @ fb)
    jaw = (height > 0) & (height < 0.5 * head_depth) & (np.abs(side) < head_depth)  # just above the neck
    cues = {
        "head ahead of the chest": (x[beyond].mean(axis=0) - cc) @ fb,
        "head ahead of the neck": (x[beyond].mean(axis=0) - neck) @ fb,
        "body ahead of the chest": (x.mean(axis=0) - cc) @ fb,
        "legs ahead of the chest": (x[below].mean(axis=0) - cc) @ fb if below.any() else 0.0,
        "chest's deepest voxel": (x[chest][np.argmax(dep[chest])] - cc) @ fb,
        "jaw ahead of the neck": np.quantile(ahead[jaw], 0.98) + np.quantile(ahead[jaw], 0.02) if jaw.any() else 0.0,
    }
    return np.stack([up, np.cross(fb, up), fb]), cues, constriction


VOTE = ("head ahead of the chest", "body ahead of the chest", "jaw ahead of the neck")  # the vote's cues


def measure(instances):
    """Per-class figures of :func:`head_frame` on one class's rigid-core aligned instances (module docs)."""
    from jaxpose import baselines, rotation
    from jaxpose.evaluation.rotation import class_angles, sign_free_angles

    rows, cues, constriction, found = [], [], [], []
    for m in instances:
        sol = rotation.frame_solid(*baselines.split_geometry(m))
        r, c, p = head_frame(sol)
        core = rotation.core_frame(sol).rotation
        c["core frame's feet"] = r[2] @ core[2]
        c["vote of three"] = float(np.sign(sum(np.sign(c[k]) for k in VOTE)))
        rows.append(r)
        cues.append(c)
        constriction.append(p)
        found.append(r[0] @ core[0] < 0)  # the core frame's first axis points to the feet (right on FAUST)
    rows = np.stack(rows)
    free, flips = sign_free_angles(rows)
    ups = rows[:, 0]
    mean_up = ups.mean(axis=0) / np.linalg.norm(ups.mean(axis=0))
    up_angle = np.degrees(np.arccos(np.clip(ups @ mean_up, -1.0, 1.0)))
    out = {"sign_free": free, "up": up_angle, "against_core": np.array(found), "constriction": np.array(constriction),
           "cues": {}}
    for name in cues[0]:
        v = np.array([c[name] for c in cues])
        agree = np.sign(v) * flips[:, 2]
        f = np.where(v >= 0, 1.0, -1.0)
        signed = rows * np.stack([np.ones_like(f), f, f], axis=1)[:, :, None]  # front-back by the cue, det +1
        out["cues"][name] = (max((agree > 0).mean(), (agree < 0).mean()), class_angles(signed))
    return out


def main(argv=None):
    from jaxpose import datasets
    from jaxpose.evaluation import VARIANTS, align_core
    from jaxpose.evaluation.variants import make_class

    p = argparse.ArgumentParser(prog="python -m benchmarks.head_frame")
    p.add_argument("--datasets", default=",".join(DATASETS))
    p.add_argument("--variants", default=",".join(VARIANTS))
    args = p.parse_args(argv)
    if not SHARED.is_dir():
        print(f"no {SHARED}: nothing to measure", file=sys.stderr)
        return 0
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.datasets.split(","):
            start = time.perf_counter()
            classes = {c: align_core(m) for c, m in datasets.load_folder(class_folder(name, tmp)).items()}
            summary = []
            for variant in args.variants.split(","):
                results = [measure(make_class(meshes, variant, 0, k)) for k, meshes in enumerate(classes.values())]
                cell = lambda f: np.mean([f(r) for r in results])  # noqa: E731 (class average)
                vote = [r["cues"]["vote of three"][1] for r in results]
                summary.append(f"| {variant} | {cell(lambda r: r['sign_free'].mean()):.1f} / "
                               f"{cell(lambda r: r['sign_free'].max()):.1f} | {cell(lambda r: r['up'].mean()):.1f} / "
                               f"{cell(lambda r: r['up'].max()):.1f} | {np.mean([v.mean() for v in vote]):.1f} / "
                               f"{np.mean([v.max() for v in vote]):.1f} | {max(v.max() for v in vote):.1f} |")
                if variant != "plain":
                    continue
                for cls, r in zip(classes, results):
                    n = len(r["up"])
                    print(f"\n### {name} {cls} ({n} meshes, plain)\n")
                    print(f"sign-free {r['sign_free'].mean():.1f} / {r['sign_free'].max():.1f}, up axis "
                          f"{r['up'].mean():.1f} / {r['up'].max():.1f} (mean / max degrees); up within 90 degrees of "
                          f"the class's mean up: {int((r['up'] < 90).sum())}/{n}, opposite the core frame's "
                          f"feet axis: {int(r['against_core'].sum())}/{n}; the neck's birth / death "
                          f"{r['constriction'].min():.2f}-{r['constriction'].max():.2f}")
                    print("\n| front-back cue | agrees | raw mean / max |\n|---|---|---|")
                    for cue, (agree, raw) in r["cues"].items():
                        print(f"| {cue} | {100 * agree:.0f}% | {raw.mean():.1f} / {raw.max():.1f} |")
            print(f"\n### {name}: every variant (class averages; raw with the vote of {', '.join(VOTE)})\n")
            print("| variant | sign-free mean / max | up mean / max | raw mean / max | largest raw |\n|---|---|---|---|---|")
            print("\n".join(summary))
            print(f"\n({name}: {time.perf_counter() - start:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
