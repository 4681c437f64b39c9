"""A head-and-chest frame found from the depth field's merge tree (a prototype, not in the library).

``python -m benchmarks.head_frame [--datasets faust-dev,kids-dev]`` from a source checkout with
../shared beside it. For every rigid-core aligned mesh (:func:`jaxpose.evaluation.align_core`):

1. The robust solid of the ``core`` frame (:func:`jaxpose.rotation.frame_solid`) and its depth field
   D (distance to the outside).
2. The merge tree of the superlevel sets {D > t} (:func:`merge_tree`, 26-connected voxels): every
   local maximum of D is born at its depth and dies at the saddle where it joins a deeper one;
   persistence = birth - death.
3. Head and trunk: the two blobs that the most persistent saddle separates (the components of
   {D > death} holding the deepest voxel and the most persistent other maximum); the smaller one is
   the head (a child's head is as thick as its trunk, so depth alone does not tell them apart).
4. Axes: ``up`` from the chest (the depth^2-weighted centroid of the solid below the neck saddle
   and within 2 head depths of it) to the head blob's centroid; the other two from the chest's
   second moments across ``up`` (left-right the wider, front-back the thinner).
5. Signs: ``up`` points to the head; front-back by one of the cues of :data:`CUES`, each measured
   for how often it agrees, within a class, with the majority of the instances' best sign flips.

Prints per class: the sign-free angle to the class frame (:func:`jaxpose.evaluation.rotation.sign_free_angles`),
the ``up`` axis's angle to the class mean (and how many ``up`` point against the ``core`` frame's
first axis, which points to the feet where that frame is right), the persistence of the head's saddle, and
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

CHEST = 2.0  # the chest: solid below the neck saddle within this many head depths of it
CHEST_POWER = 2.0  # depth exponent of the chest's weights
_NEIGHBOURS = np.array([(a, b, c) for a in (-1, 0, 1) for b in (-1, 0, 1) for c in (-1, 0, 1) if (a, b, c) != (0, 0, 0)])


def merge_tree(inside, depth):
    """The merge tree of the superlevel sets of ``depth`` on the ``inside`` voxels (26-connected).

    Returns a list of (birth, death, peak, saddle) per local maximum, most persistent first: birth
    its depth, death the depth at which it joins a deeper maximum (0 for the deepest), peak and
    saddle flat voxel indices (saddle -1 for the deepest). Union-find over voxels in decreasing depth.
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
            out.append((d[peak[r]], d[v], peak[r], v))
            parent[r] = roots[0]
        parent[v] = roots[0]
    top = find(int(order[0]))
    out.append((d[peak[top]], 0.0, peak[top], -1))
    return sorted(out, key=lambda r: -(r[0] - r[1]))


def _world(sol, voxels):
    """World coordinates of voxel centers: (n, 3) for a mask of the grid, (3,) for one flat index."""
    idx = np.stack(np.nonzero(voxels), 1) if np.ndim(voxels) == 3 else np.array(np.unravel_index(voxels, sol.inside.shape))
    return (sol.origin + sol.pitch * (idx + 0.5)) @ sol.frame


def head_and_trunk(sol):
    """Boolean masks (trunk, head) of the two blobs the most persistent saddle separates, the neck
    point (3,) in world coordinates, the head's depth and the saddle's persistence."""
    tree = merge_tree(sol.inside, sol.depth)
    deepest, second = tree[0], tree[1]
    lab, _ = ndimage.label(sol.depth > second[1], structure=np.ones((3, 3, 3), bool))
    a, b = lab == lab.ravel()[deepest[2]], lab == lab.ravel()[second[2]]
    trunk, head = (a, b) if a.sum() >= b.sum() else (b, a)
    head_depth = deepest[0] if head is a else second[0]
    return trunk, head, _world(sol, second[3]), head_depth, second[0] - second[1]


def head_frame(sol):
    """The frame of one solid: rows (up, left-right, front-back) (3, 3), det +1, front-back's sign
    not yet set; {cue name: signed offset along front-back}; the saddle's persistence / head depth."""
    trunk, head, neck, head_depth, persistence = head_and_trunk(sol)
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
    cues = {
        "head ahead of the chest": (x[beyond].mean(axis=0) - cc) @ fb,
        "head ahead of the neck": (x[beyond].mean(axis=0) - neck) @ fb,
        "body ahead of the chest": (x.mean(axis=0) - cc) @ fb,
        "legs ahead of the chest": (x[below].mean(axis=0) - cc) @ fb if below.any() else 0.0,
        "chest's deepest voxel": (x[chest][np.argmax(dep[chest])] - cc) @ fb,
    }
    return np.stack([up, np.cross(fb, up), fb]), cues, persistence / head_depth


def measure(meshes):
    """Per-class figures of :func:`head_frame` on rigid-core aligned meshes (module docs)."""
    from jaxpose import baselines, rotation
    from jaxpose.evaluation import align_core
    from jaxpose.evaluation.rotation import class_angles, sign_free_angles

    rows, cues, rel, found, core_fb = [], [], [], [], []
    for m in align_core(meshes):
        sol = rotation.frame_solid(*baselines.split_geometry(m))
        r, c, p = head_frame(sol)
        core = rotation.core_frame(sol).rotation
        rows.append(r)
        cues.append(c)
        rel.append(p)
        found.append(r[0] @ core[0] < 0)  # the core frame's first axis points to the feet (right on FAUST)
        core_fb.append(r[2] @ core[2])
    rows = np.stack(rows)
    free, flips = sign_free_angles(rows)
    ups = rows[:, 0]
    mean_up = ups.mean(axis=0) / np.linalg.norm(ups.mean(axis=0))
    up_angle = np.degrees(np.arccos(np.clip(ups @ mean_up, -1.0, 1.0)))
    out = {"sign_free": free, "up": up_angle, "against_core": np.array(found), "relative_persistence": np.array(rel),
           "cues": {}}
    for name in list(cues[0]) + ["core frame's front-back"]:
        v = np.array(core_fb if name == "core frame's front-back" else [c[name] for c in cues])
        agree = np.sign(v) * flips[:, 2]
        f = np.where(v >= 0, 1.0, -1.0)
        signed = rows * np.stack([np.ones_like(f), f, f], axis=1)[:, :, None]  # front-back by the cue, det +1
        out["cues"][name] = (max((agree > 0).mean(), (agree < 0).mean()), class_angles(signed))
    return out


def main(argv=None):
    from jaxpose import datasets

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
                r = measure(meshes)
                print(f"\n### {name} {cls} ({len(meshes)} meshes)\n")
                print(f"sign-free {r['sign_free'].mean():.1f} / {r['sign_free'].max():.1f}, up axis "
                      f"{r['up'].mean():.1f} / {r['up'].max():.1f} (mean / max degrees); up within 90 degrees of "
                      f"the class's mean up: {int((r['up'] < 90).sum())}/{len(meshes)}, opposite the core frame's "
                      f"feet axis: {int(r['against_core'].sum())}/{len(meshes)}; saddle persistence / head depth "
                      f"{r['relative_persistence'].min():.2f}-{r['relative_persistence'].max():.2f}")
                print("\n| front-back cue | agrees | raw mean / max |\n|---|---|---|")
                for cue, (agree, raw) in r["cues"].items():
                    print(f"| {cue} | {100 * agree:.0f}% | {raw.mean():.1f} / {raw.max():.1f} |")
            print(f"\n({name}: {time.perf_counter() - start:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
