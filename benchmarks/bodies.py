"""Why the robust center and scale lose on four-legged animals, and what holds on every body (issue 34).

``python -m benchmarks.bodies [--variants plain,...] [--classes dog,horse,...] [--resolution 96]
[--every K] [--json OUT]`` from a source checkout with ../shared beside it.

The six dev classes (faust-dev as its two people, kids-dev's two children, tosca-dev's dog and
horse), each rigid-core aligned (``jaxpose.evaluation.align_core``), every variant made as
``jaxpose evaluate`` makes it. For every shape one robust solid (``jaxpose.occupancy.solid.robust_solid``)
and, from it, candidate centers and scales (below); per class the spreads of
``jaxpose.evaluation`` (sigma_tr, cv), printed one table per class, and the averages over the
six classes. Nothing here is asserted; it is the record of the research behind the estimator.

Candidates (``d``: a voxel's depth to the outside, ``t``: its local thickness, the radius of the
largest inscribed ball that contains it; ``h``: the pitch):

* centers: ``depth^p`` (sum d^p x / sum d^p), ``thick^p`` (the same with t), the voxel solid's
  plain centroid, and the classical surface centroid, vertex mean, closed-form solid centroid;
* scales: ``volume`` (h^3 times the voxel count, cube root), ``depth_volume^p``
  ((h^3 sum d^p)^(1/(3+p))), ``capped_volume`` (the divergence-theorem volume of the mesh with
  every hole capped by a fan, cube root; meshes), ``sqrt_area``.
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy import ndimage

from jaxpose import baselines, datasets
from jaxpose.evaluation import align_core, class_angles, make_class
from jaxpose.occupancy.solid import cap_holes, robust_solid
from jaxpose.rotation.parts import find_parts
from jaxpose.rotation.rotation import SYMMETRY_POWER, _grid_centers, _weights, frame_of, frame_solid, symmetry_scores

from .consistency import class_folder

SHARED = Path(__file__).resolve().parents[2] / "shared" / "data"
CLASSES = ("person_a", "person_b", "kid_0001", "kid_0002", "dog", "horse")


def dev_classes(tmp, names=CLASSES, every=1):
    """{class: [aligned Trimesh]} of the six dev classes (``every``: keep every k-th instance)."""
    out = {}
    for dataset in ("faust-dev", "kids-dev", "tosca-dev"):
        want = [n for n in names if n in _members(dataset)]
        if not want:
            continue
        loaded = datasets.load_folder(class_folder(dataset, tmp))
        for name in want:
            out[name] = align_core(loaded[name])[::every]
    return out


def _members(dataset):
    return {"faust-dev": ("person_a", "person_b"), "kids-dev": ("kid_0001", "kid_0002"),
            "tosca-dev": ("dog", "horse")}[dataset]


def local_thickness(inside, depth_vox):
    """(shape) float: per voxel the radius (voxels) of the largest inscribed ball containing it.

    Ball centers are the voxels with depth >= r; the union of balls of radius r about them is the
    opening of the solid by a ball of radius r; t(x) = the largest r (in steps of half a voxel)
    whose opening holds x.
    """
    t = np.zeros(inside.shape)
    top = float(depth_vox.max())
    for r in np.arange(0.5, top + 0.5, 0.5):
        core = depth_vox >= r
        if not core.any():
            break
        opened = ndimage.distance_transform_edt(~core) <= r
        t[opened & inside] = r
    return t


def capped_volume(vertices, faces):
    """Signed volume of the mesh with every hole capped (``jaxpose.occupancy.solid.cap_holes``), units^3."""
    v, caps = cap_holes(np.asarray(vertices, np.float64), np.asarray(faces, np.int64))
    f = np.vstack([faces, caps])
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


def candidates(shape, resolution, powers=(1, 2, 4, 6, 8), thick=False):
    """{name: center (3,)} and {name: scale} of one shape (module docs)."""
    v, f = baselines.split_geometry(shape)
    sol = robust_solid(v, f, resolution=resolution)
    x = sol.centers()
    d = sol.depth[sol.inside] / sol.pitch  # voxels
    bias = 0.5 if f is not None else 1.0
    t = local_thickness(sol.inside, ndimage.distance_transform_edt(sol.inside) - bias)[sol.inside] if thick else None
    centers, scales = {}, {}
    for p in powers:
        w = (d / d.max()) ** p
        centers[f"depth^{p}"] = w @ x / w.sum()
        if thick:
            w = (t / t.max()) ** p
            centers[f"thick^{p}"] = w @ x / w.sum()
    centers["voxel_solid"] = x.mean(0)
    found = find_parts(sol)
    if found is not None:
        blob = found.head[sol.inside]
        centers["head"] = x[blob].mean(0)
        w = d[blob] ** 2
        centers["skull"] = w @ x[blob] / w.sum()
    else:
        centers["head"] = centers["skull"] = np.full(3, np.nan)
    h3 = sol.pitch ** 3
    scales["volume"] = sol.volume() ** (1 / 3)
    for p in (1, 2, 4):
        scales[f"depth_volume^{p}"] = (h3 * np.sum((d * sol.pitch) ** p)) ** (1 / (3 + p))
        if thick:
            scales[f"thick_volume^{p}"] = (h3 * np.sum((t * sol.pitch) ** p)) ** (1 / (3 + p))
    centers["vertex_mean"] = v.mean(0)
    if f is not None:
        centers["surface_centroid"] = baselines.center(shape, "surface_centroid")
        scales["capped_volume"] = abs(capped_volume(v, f)) ** (1 / 3)
        scales["sqrt_area"] = float(np.sqrt(shape.area))
    info = {"max_depth_vox": float(d.max()), "pitch": sol.pitch, "voxels": int(sol.inside.sum())}
    return centers, scales, info


def spreads(centers, scales):
    c = np.asarray(centers)
    s = np.asarray(scales)
    return float(np.sqrt(np.mean(np.sum((c - c.mean(0)) ** 2, axis=1)))), float(s.std() / s.mean())


def main(argv=None):
    p = argparse.ArgumentParser(prog="python -m benchmarks.bodies")
    p.add_argument("--variants", default="plain")
    p.add_argument("--classes", default=",".join(CLASSES))
    p.add_argument("--resolution", type=int, default=96)
    p.add_argument("--every", type=int, default=1)
    p.add_argument("--thick", action="store_true", help="also the local-thickness candidates (slow)")
    p.add_argument("--json", default=None)
    args = p.parse_args(argv)
    if not SHARED.is_dir():
        print(f"no {SHARED}: nothing to measure", file=sys.stderr)
        return 0
    with tempfile.TemporaryDirectory() as tmp:
        classes = dev_classes(tmp, args.classes.split(","), args.every)
    out = {}
    for variant in args.variants.split(","):
        out[variant] = {}
        for k, (name, meshes) in enumerate(classes.items()):
            k = CLASSES.index(name)  # the class index of jaxpose evaluate on its dataset
            start = time.perf_counter()
            found = [candidates(s, args.resolution, thick=args.thick) for s in make_class(meshes, variant, 0, k % 2)]
            cs = {m: [c[m] for c, _, _ in found] for m in found[0][0]}
            ss = {m: [s[m] for _, s, _ in found] for m in found[0][1]}
            info = {key: float(np.mean([i[key] for _, _, i in found])) for key in found[0][2]}
            rows = {m: spreads(cs[m], [1.0] * len(found))[0] for m in cs}
            cvs = {m: spreads([[0, 0, 0]] * len(found), ss[m])[1] for m in ss}
            out[variant][name] = {"sigma_tr": rows, "cv": cvs, "info": info,
                                  "centers": {m: np.asarray(v).tolist() for m, v in cs.items()},
                                  "scales": {m: np.asarray(v).tolist() for m, v in ss.items()},
                                  "seconds": time.perf_counter() - start}
            print(f"\n{variant} {name}: {info} ({time.perf_counter() - start:.0f} s)")
            low = min(rows.values())
            print("  sigma_tr " + "  ".join(f"{m} {v / low:.2f}" for m, v in sorted(rows.items(), key=lambda i: i[1])))
            low = min(cvs.values())
            print("  cv/low   " + "  ".join(f"{m} {v / low:.2f}" for m, v in sorted(cvs.items(), key=lambda i: i[1]))
                  + f"   (lowest {low:.5f})")
            sys.stdout.flush()
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())


# ------------------------------------------------------------------ frames and the mirror plane
def frame_rows(classes, variants=("plain",), methods=("head",)):
    """Per (variant, class, method): each instance's angle to the class frame (degrees), its flag,
    and the mirror self-overlap of its depth^2 solid about the planes normal to the frame's three
    axes (:func:`jaxpose.rotation.rotation.symmetry_scores`; axis 1 is left-right for every frame here)."""
    out = {}
    for variant in variants:
        for name, meshes in classes.items():
            k = CLASSES.index(name) % 2
            found = {m: [] for m in methods}
            for shape in make_class(meshes, variant, 0, k):
                v, f = baselines.split_geometry(shape)
                sol = frame_solid(v, f)
                y, d, _ = _grid_centers(sol)
                w2 = _weights(d, SYMMETRY_POWER)
                for m in methods:
                    fr = frame_of(shape, m, sol=sol)
                    sym = symmetry_scores(sol, fr.rotation @ sol.frame.T, (w2 @ y) / w2.sum())
                    found[m].append((fr.rotation, fr.ambiguity, sym))
            for m in methods:
                rs = np.stack([r for r, _, _ in found[m]])
                out[variant, name, m] = {"angles": class_angles(rs).tolist(),
                                         "ambiguity": [a for _, a, _ in found[m]],
                                         "mirror": [s.tolist() for _, _, s in found[m]]}
    return out
