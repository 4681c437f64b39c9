"""Why the robust center and scale lose on four-legged animals, and what holds on every body (issue 34).

``python -m benchmarks.bodies [--variants plain,...] [--classes dog,horse,...] [--resolution 96]
[--every K] [--heads | --pitch | --volume-parts | --subvoxel | --grid-offsets | --grid-frame | --blend] [--core-weight vertices|area] [--json OUT]`` from a source checkout with ../shared beside it.

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

``--heads`` (plain meshes; the frame's research, docs/rotation.md): per class, every thick part
beyond a saddle of the depth field that could be the head (:func:`head_candidates`), where the
head is among them, the prototype head detector :func:`terminal_head` (the thickest part that
ends the body) and the ``head`` frame's geometry built on the head (:func:`head_frames`: three
rules for its axes, four for its front-back sign) against the class frame.
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
from scipy.spatial import cKDTree

from jaxpose import baselines, datasets
from jaxpose.rotation import parts
from jaxpose.evaluation import align_core, class_angles, make_class
from jaxpose.occupancy.solid import cap_holes, robust_solid
from jaxpose.evaluation.rotation import sign_free_angles
from jaxpose.rotation.parts import Parts, ends, find_parts, geodesic, merge_tree
from jaxpose.rotation.core import _grid_centers, _weights
from jaxpose.rotation.rotation import (CELL, SYMMETRY_POWER, frame_of, frame_solid, front_back_cues, head_chest, mirror_error,
                                       symmetry_scores)
from jaxpose.sample import lattice_points

from .consistency import class_folder

SHARED = Path(__file__).resolve().parents[2] / "shared" / "data"
CLASSES = ("person_a", "person_b", "kid_0001", "kid_0002", "dog", "horse")


def dev_classes(tmp, names=CLASSES, every=1, core_weight="vertices"):
    """{class: [aligned Trimesh]} of the six dev classes (``every``: keep every k-th instance;
    ``core_weight``: ``align_core``'s ``weight``, the stable core as a share of the vertices or of the area)."""
    out = {}
    for dataset in ("faust-dev", "kids-dev", "tosca-dev"):
        want = [n for n in names if n in _members(dataset)]
        if not want:
            continue
        loaded = datasets.load_folder(class_folder(dataset, tmp))
        for name in want:
            out[name] = align_core(loaded[name], weight=core_weight)[::every]
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


def capped_triangles(vertices, faces):
    """The corners (three (f + k, 3) arrays) of the mesh's triangles with every hole capped by a
    fan (``jaxpose.occupancy.solid.cap_holes``: k cap triangles)."""
    v, caps = cap_holes(np.asarray(vertices, np.float64), np.asarray(faces, np.int64))
    f = np.vstack([np.asarray(faces, np.int64), caps])
    return v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]


def capped_volume(vertices, faces):
    """Signed volume of the mesh with every hole capped (:func:`capped_triangles`), units^3."""
    a, b, c = capped_triangles(vertices, faces)
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


def capped_area(vertices, faces):
    """Area (units^2) of the mesh with every hole capped (:func:`capped_triangles`)."""
    a, b, c = capped_triangles(vertices, faces)
    return float(np.linalg.norm(np.cross(b - a, c - a), axis=1).sum() / 2.0)


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
    p.add_argument("--heads", action="store_true",
                   help="the head candidates of each class and, on the animals, the head frame with the head given")
    p.add_argument("--pitch", action="store_true",
                   help="the voxel-volume scale's cv with the pitch set by the extent and by the area")
    p.add_argument("--volume-parts", action="store_true",
                   help="where a class's volume changes between poses: its solid split by the nearest of 12 vertex clusters")
    p.add_argument("--subvoxel", action="store_true",
                   help="the volume's cv with the boundary voxels counted by sub-samples against the surface")
    p.add_argument("--grid-offsets", action="store_true",
                   help="the robust center's sigma_tr and volume's cv on four grids shifted by half a voxel, and their mean")
    p.add_argument("--blend", action="store_true",
                   help="the cv of V^(w/3) (capped area)^((1-w)/2) for w = 0, 0.1, ..., 1, and how V and the area move together")
    p.add_argument("--grid-frame", action="store_true",
                   help="the robust pose on the input's axes and on the surface's principal axes, each also on randomly turned inputs")
    p.add_argument("--core-weight", choices=("vertices", "area"), default="vertices",
                   help="align each class on the stable share of its vertices (jaxpose evaluate's default) or of its area")
    p.add_argument("--json", default=None)
    args = p.parse_args(argv)
    if not SHARED.is_dir():
        print(f"no {SHARED}: nothing to measure", file=sys.stderr)
        return 0
    with tempfile.TemporaryDirectory() as tmp:
        classes = dev_classes(tmp, args.classes.split(","), args.every, args.core_weight)
    if args.volume_parts or args.subvoxel or args.grid_offsets or args.grid_frame or args.blend:
        study = (volume_parts if args.volume_parts else subvoxel_study if args.subvoxel else
                 grid_offsets if args.grid_offsets else blend_study if args.blend else grid_frame)
        record = {name: study(meshes, args.resolution, name) for name, meshes in classes.items()}
        if args.json:
            Path(args.json).write_text(json.dumps(record, indent=1))
        return 0
    if args.heads or args.pitch:
        record = heads(classes) if args.heads else pitch_study(classes, args.resolution)
        if args.json:
            Path(args.json).write_text(json.dumps(record, indent=1))
        return 0
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
                    fr = frame_of(shape, m, sol=sol if m in ("core", "head") else None)
                    sym = symmetry_scores(sol, fr.rotation @ sol.frame.T, (w2 @ y) / w2.sum())
                    found[m].append((fr.rotation, fr.ambiguity, sym))
            for m in methods:
                rs = np.stack([r for r, _, _ in found[m]])
                out[variant, name, m] = {"angles": class_angles(rs).tolist(),
                                         "ambiguity": [a for _, a, _ in found[m]],
                                         "mirror": [s.tolist() for _, _, s in found[m]]}
    return out


# ------------------------------------------------------------------ the head of an animal (--heads)
# Where the head's depth maximum lies in each animal class's aligned coordinates (the first pose's;
# read off the merge trees of its 8 plain poses): the research oracle of ``--heads``, which asks
# how good the head frame would be if the head were found. Never used by the library.
HEAD_AT = {"dog": (0.0, -45.0, 97.0), "horse": (0.0, -105.0, 170.0)}
_CUBE = np.ones((3, 3, 3), bool)


def _voxel(sol, flat):
    return np.array(np.unravel_index(int(flat), sol.inside.shape))


def _world(sol, index):
    return (np.asarray(sol.origin) + sol.pitch * (np.asarray(index, np.float64) + 0.5)) @ sol.frame


def part_beyond(sol, blob, saddle):
    """(shape) bool: the part of the solid beyond a saddle: the component holding ``blob`` of the
    kept voxels on the blob's side of the plane through ``saddle`` ((3,) voxel index) normal to
    the direction from the saddle to the blob's centroid."""
    idx = np.argwhere(sol.inside)
    u = np.argwhere(blob).mean(axis=0) - saddle
    u /= np.linalg.norm(u)
    half = np.zeros(sol.inside.shape, bool)
    half[tuple(idx[(idx - saddle) @ u > 0.5].T)] = True
    labels, _ = ndimage.label(half | blob, _CUBE)
    return labels == labels[tuple(np.argwhere(blob)[0])]


def head_candidates(sol, tree=None, neck=1.05, lowest=0.1):
    """Every thick part a head could be: one row per local maximum of the depth field (its merge
    tree, :func:`jaxpose.rotation.parts.merge_tree`) at least ``lowest`` times as deep as the
    deepest and ``neck`` times as deep as its saddle, whose part beyond the saddle
    (:func:`part_beyond`) does not hold the deepest voxel. Each row: ``constriction`` (birth /
    death), ``thickness`` (birth over the deepest), ``part`` (the share of the solid's voxels
    beyond the saddle), ``center`` (the maximum, world coordinates) and ``row`` (its tree row)."""
    tree = merge_tree(sol.inside, sol.depth) if tree is None else tree
    top = tree[:, 0].max()
    root = tuple(_voxel(sol, tree[tree[:, 1] == 0][0][2]))
    total = sol.inside.sum()
    out = []
    for row in tree:
        birth, death, peak, saddle, _ = row
        if death <= 0 or birth < neck * death or birth < lowest * top:
            continue
        labels, _ = ndimage.label(sol.depth > death, _CUBE)
        blob = labels == labels[tuple(_voxel(sol, peak))]
        part = part_beyond(sol, blob, _voxel(sol, saddle))
        if part[root]:
            continue
        out.append({"constriction": birth / death, "thickness": birth / top, "part": part.sum() / total,
                    "center": _world(sol, _voxel(sol, peak)), "row": row})
    return out


def parts_at(sol, row, head_peak=None):
    """:class:`jaxpose.rotation.parts.Parts` with the head on one side of the saddle of one
    merge-tree row: the side of its maximum (``head_peak`` None: the row's own peak, else the
    peak of that side, the row's peak or the one it joins)."""
    birth, death, peak, saddle, joins = row
    head_peak = peak if head_peak is None else head_peak
    other = joins if head_peak == peak else peak
    labels, _ = ndimage.label(sol.depth > death, _CUBE)
    head = labels == labels[tuple(_voxel(sol, head_peak))]
    trunk = labels == labels[tuple(_voxel(sol, other))]
    neck = np.asarray(sol.origin, np.float64) + sol.pitch * (_voxel(sol, saddle) + 0.5)
    return Parts(head, trunk, neck, float(sol.depth.ravel()[int(head_peak)]), float(death), float(birth / death), 1.0)


# The prototype of a head detector for every body (--heads): the head is the thickest part that
# ends the body, whatever its neck's constriction. As measured then (docs/rotation.md, "Bodies
# other than people": alone it loses a third of the children's heads); the library's
# jaxpose.rotation.parts.find_head keeps find_parts' head where it ends the body and falls back
# to this search (with its own geodesic and ends, imported here).
DISK = 3.0  # a part is cut off across its saddle by a disk of this many saddle depths in radius
BRANCH = 2.0  # a part ends the body when no two of its ends are more than this many part thicknesses apart


def part_across(sol, blob, saddle, death, disk=DISK):
    """(shape) bool: the part beyond a saddle, cut off by a disk (the library's
    :func:`jaxpose.rotation.parts.part_across` without the join check): the component holding
    ``blob`` of the kept voxels less the disk through ``saddle`` ((3,) voxel index), ``disk``
    times ``death`` (the saddle's depth, units) in radius."""
    return parts.part_across(sol, blob, saddle, death, None, disk)


def terminal_head(sol, tree=None, neck=1.05, lowest=0.1):
    """The prototype head: of the parts beyond the saddles of the depth field (each row of its
    merge tree at least ``neck`` times as deep as its saddle and ``lowest`` times as deep as the
    deepest; on the side whose blob at the saddle's depth is the smaller), cut off by
    :func:`part_across` without the other side's maximum, those that do not branch (:func:`ends`
    <= 1), the thickest.

    Returns:
      (row, head peak (flat index), part (shape bool)) or None."""
    tree = merge_tree(sol.inside, sol.depth) if tree is None else tree
    top = tree[:, 0].max()
    best = None
    for row in tree:
        birth, death, peak, saddle, joins = row
        if death <= 0 or birth < neck * death or birth < lowest * top:
            continue
        labels, _ = ndimage.label(sol.depth > death, _CUBE)
        blobs = {q: labels == labels[tuple(_voxel(sol, q))] for q in (peak, joins)}
        for mine, other in ((peak, joins), (joins, peak)):
            if blobs[mine].sum() > blobs[other].sum():  # the head is the smaller side
                continue
            thickness = sol.depth.ravel()[int(mine)]
            if best is not None and thickness <= best[0]:
                continue
            part = part_across(sol, blobs[mine], _voxel(sol, saddle), death)
            if part[tuple(_voxel(sol, other))] or ends(sol, part, _voxel(sol, saddle), thickness) > 1:
                continue
            best = (thickness, row, mine, part)
    return None if best is None else best[1:]


def head_mirror_normal(surface, a, b, steps=36):
    """The normal of the best mirror plane of the head's surface points (n, 3) through their
    centroid among the directions cos t a + sin t b (a, b orthonormal, across up): ``steps`` over
    half a turn, then ``steps // 3`` within one step of the best. A head is bilaterally symmetric
    and rigid in every pose: the normal is its left-right axis."""
    center = surface.mean(axis=0)

    def best(angles):
        dirs = np.cos(angles)[:, None] * a + np.sin(angles)[:, None] * b
        errors = [mirror_error(surface, center, e) for e in dirs]
        return angles[int(np.argmin(errors))], dirs[int(np.argmin(errors))]

    t, _ = best(np.linspace(0.0, np.pi, steps, endpoint=False))
    step = np.pi / steps
    return best(t + np.linspace(-step, step, steps // 3 + 1))[1]


def head_frames(sol, vertices, faces, found):
    """{(axis rule, sign rule): (3, 3) rotation} of the ``head`` frame's geometry
    (:func:`jaxpose.rotation.rotation.head_chest`) from the parts ``found``: up from the chest to
    the head; front-back across up the chest's thinner axis (``thin``, the library's rule) or the
    one of the chest's two axes whose plane does not mirror the body best (``mirror``: the other
    is left-right); its sign where the jaw lies (``jaw``, the library's), where the head's surface
    reaches farther (``reach``), the sign of its third moment (``skew``), or where the part beyond
    the neck lies from the skull's center (``part``: a snout, a face); or left-right the normal of
    the head's own best mirror plane across up (``head``, :func:`head_mirror_normal`)."""
    geo = head_chest(sol, found, lattice_points(vertices, faces, CELL * sol.pitch))
    if geo is None:
        return {}
    across = np.eye(3) - np.outer(geo.up, geo.up)
    _, vec = np.linalg.eigh(across @ geo.cov @ across)  # ascending: up, thinner, wider
    w2 = _weights(geo.depth, SYMMETRY_POWER)
    sym = symmetry_scores(sol, np.stack([vec[:, 1], vec[:, 2], geo.up]), (w2 @ geo.centers) / w2.sum())
    part = part_beyond(sol, found.head, (found.neck - sol.origin) / sol.pitch - 0.5)
    part_center = (np.asarray(sol.origin) + sol.pitch * (np.argwhere(part) + 0.5)).mean(axis=0)
    left_right = head_mirror_normal(geo.surface, vec[:, 1], vec[:, 2]) if len(geo.surface) >= 4 else vec[:, 2]
    out = {}
    for axis_rule, fb in (("thin", vec[:, 1]), ("mirror", vec[:, 1] if sym[1] >= sym[0] else vec[:, 2]),
                          ("head", np.cross(geo.up, left_right))):
        jaw, reach, _ = front_back_cues(geo, fb)
        z = (geo.surface - geo.skull) @ fb
        for sign_rule, cue in (("jaw", jaw), ("reach", reach), ("skew", np.mean(z ** 3)),
                               ("part", (part_center - geo.skull) @ fb)):
            ahead = (fb if cue > 0 else -fb) @ sol.frame
            down = -geo.up @ sol.frame
            out[axis_rule, sign_rule] = np.stack([down, np.cross(ahead, down), ahead])
    return out


def heads(classes, out=print):
    """``--heads``: per class (plain meshes), the head candidates of every pose, the head marked
    (the maximum nearest :data:`HEAD_AT` on the animals, the library's head,
    :func:`jaxpose.rotation.parts.find_parts`, on the people), and the angles to the class frame
    of :func:`head_frames` with that head (poses where the library finds none are left out).
    Returns {class: record}."""
    record = {}
    for name, meshes in classes.items():
        rows, frames, proto_frames, found_by_prototype = [], {}, {}, []
        for k, shape in enumerate(meshes):
            v, f = baselines.split_geometry(shape)
            sol = frame_solid(v, f)
            tree = merge_tree(sol.inside, sol.depth)
            cands = head_candidates(sol, tree)
            if name in HEAD_AT:
                rows_with_saddle = tree[tree[:, 1] > 0]
                at = np.array([_world(sol, _voxel(sol, p)) for p in rows_with_saddle[:, 2]])
                best = rows_with_saddle[np.argmin(np.linalg.norm(at - HEAD_AT[name], axis=1))]
                for key, r in head_frames(sol, v, f, parts_at(sol, best)).items():
                    frames.setdefault(key, []).append(r)
                is_head = [c["row"][2] == best[2] for c in cands]
            else:
                lib = find_parts(sol)
                is_head = [lib is not None and bool(lib.head[tuple(_voxel(sol, c["row"][2]))]) for c in cands]
                for key, r in (head_frames(sol, v, f, lib) if lib is not None else {}).items():
                    frames.setdefault(key, []).append(r)
            proto = terminal_head(sol, tree)
            if name in HEAD_AT:
                truth = parts_at(sol, best).head
            else:
                truth = lib.head if lib is not None else np.zeros(sol.inside.shape, bool)
            hit = proto is not None and bool(truth[tuple(_voxel(sol, proto[1]))])
            found_by_prototype.append(hit)
            if proto is not None:
                for key, r in head_frames(sol, v, f, parts_at(sol, proto[0], proto[1])).items():
                    proto_frames.setdefault(key, []).append(r)
            for c, h in zip(cands, is_head):
                rows.append({"pose": k, "head": bool(h), **{key: (val.tolist() if isinstance(val, np.ndarray) else val)
                                                          for key, val in c.items()}})
        record[name] = {"candidates": rows}
        head = [r for r in rows if r["head"]]
        thinnest = min([h["thickness"] for h in head] or [1])
        other = [r for r in rows if not r["head"] and r["thickness"] >= thinnest]
        thinner = [r for r in rows if not r["head"] and r["thickness"] < thinnest]
        out(f"\n{name}: the head found among the candidates in {len({r['pose'] for r in head})} of {len(meshes)} poses")
        for label, group in (("head", head), ("others at least as thick", other), ("others thinner", thinner)):
            if group:
                out(f"  {label:25s} constriction {_span(group, 'constriction')}  thickness {_span(group, 'thickness')}"
                    f"  part {_span(group, 'part', 3)}  ({len(group)} rows)")
        record[name]["prototype_found"] = found_by_prototype
        out(f"  the prototype (terminal_head) finds that head in {sum(found_by_prototype)} of {len(meshes)} poses")
        for label, group, field in (("head given", frames, "frames"),
                                    ("prototype's head", proto_frames, "prototype_frames")):
            record[name][field] = {}
            for key, rs in group.items():
                raw = class_angles(np.stack(rs))
                free, _ = sign_free_angles(np.stack(rs))
                record[name][field]["/".join(key)] = {"raw": raw.tolist(), "sign_free": free.tolist()}
                out(f"  {label} ({len(rs)}), axes {key[0]:6s} sign {key[1]:5s}: raw {raw.mean():5.1f} / "
                    f"{raw.max():5.1f}   sign-free {free.mean():5.1f} / {free.max():5.1f}   raw per pose "
                    f"{np.round(raw).astype(int).tolist()}")
    return record


def _span(rows, key, digits=2):
    values = [r[key] for r in rows]
    return f"{min(values):.{digits}f}-{max(values):.{digits}f}"


# ------------------------------------------------------------------ a pitch set by the area (--pitch)
def pitch_study(classes, resolution=96, out=print):
    """``--pitch``: the cv of the voxel-volume scale V^(1/3) per class (plain meshes) with the pitch
    set by each shape's extent (the library: ``resolution`` voxels along the largest extent) and by
    its area (the same median grid, each shape's resolution scaled by its extent / sqrt(area), so
    that the pitch is a fixed share of sqrt(area) within the class), beside sqrt(area)'s cv.
    Returns {class: {"extent", "area", "sqrt_area": cv}}."""
    record = {}
    for name, meshes in classes.items():
        geometry = [baselines.split_geometry(m) for m in meshes]
        area = np.array([m.area for m in meshes])
        extent = np.array([np.ptp(v, axis=0).max() for v, _ in geometry])
        ratio = extent / np.sqrt(area)
        by_area = np.rint(resolution * ratio / np.median(ratio)).astype(int)
        s_extent = [robust_solid(v, f, resolution=resolution).volume() ** (1 / 3) for v, f in geometry]
        s_area = [robust_solid(v, f, resolution=int(r)).volume() ** (1 / 3) for (v, f), r in zip(geometry, by_area)]
        cv = {"extent": spreads([[0, 0, 0]] * len(meshes), s_extent)[1],
              "area": spreads([[0, 0, 0]] * len(meshes), s_area)[1],
              "sqrt_area": spreads([[0, 0, 0]] * len(meshes), np.sqrt(area))[1]}
        record[name] = cv
        out(f"{name}: cv of V^(1/3), pitch by extent {cv['extent']:.5f}, by area {cv['area']:.5f}; "
            f"sqrt(area) {cv['sqrt_area']:.5f} (resolutions {by_area.min()}-{by_area.max()})")
    return record


# ------------------------------------------------------------------ where the volume changes (--volume-parts, --subvoxel)
def _voxel_index(sol):
    """(m, 3) int grid indices of the solid's inside voxels and (3,) the world position of index 0."""
    index = np.argwhere(sol.inside)
    return index, (sol.centers() - index * sol.pitch).mean(axis=0)


def volume_parts(meshes, resolution=96, name="", parts=12, out=print):
    """``--volume-parts``: split a class into ``parts`` clusters of its vertices (k-means, seed 0, of
    the vertices' median positions over the poses); in each pose give every voxel of the robust
    solid to the cluster of its nearest vertex and sum each cluster's volume and surface area.
    Per cluster: its share of the volume, the cv of its volume and of its area over the poses, and
    its share of the total volume's variance (cov(part, total) / var(total); they sum to 1).
    Returns {"clusters": [...], "total_cv": float}."""
    from scipy.cluster.vq import kmeans2

    geometry = [baselines.split_geometry(m) for m in meshes]
    median = np.median([v for v, _ in geometry], axis=0)
    middle, label = kmeans2(median, parts, seed=0, minit="++")
    volume, area = np.zeros((len(meshes), parts)), np.zeros((len(meshes), parts))
    for k, (mesh, (v, f)) in enumerate(zip(meshes, geometry)):
        sol = robust_solid(v, f, resolution=resolution)
        _, near = cKDTree(v).query(sol.centers())
        np.add.at(volume[k], label[near], sol.pitch ** 3)
        np.add.at(area[k], label[np.asarray(f)[:, 0]], mesh.area_faces)
    total = volume.sum(axis=1)
    share = ((volume - volume.mean(0)) * (total - total.mean())[:, None]).sum(0) / np.sum((total - total.mean()) ** 2)
    rows = [{"middle": middle[c].round(1).tolist(), "volume_share": float(volume[:, c].mean() / total.mean()),
             "volume_cv": float(volume[:, c].std() / volume[:, c].mean()),
             "area_cv": float(area[:, c].std() / area[:, c].mean()), "variance_share": float(share[c])}
            for c in range(parts)]
    out(f"{name}: total voxel volume cv {total.std() / total.mean():.4f}; clusters by their share of its variance")
    for row in sorted(rows, key=lambda r: -r["variance_share"]):
        out(f"  at {row['middle']}: volume {row['volume_share']:.3f} of the body, cv {row['volume_cv']:.3f}; "
            f"area cv {row['area_cv']:.3f}; variance share {row['variance_share']:+.3f}")
    return {"clusters": rows, "total_cv": float(total.std() / total.mean())}


def subvoxel_study(meshes, resolution=96, name="", sub=3, out=print):
    """``--subvoxel``: the cv of V^(1/3) with the voxels within 2 of the solid's boundary (both sides)
    counted by ``sub``^3 sub-samples, each inside where it lies behind the plane of the nearest of
    dense surface samples (spacing 0.15 pitch, the hole caps included), beside the voxel count and
    the capped closed-form volume. Returns {"voxels", "subvoxel", "capped": cv}."""
    import trimesh

    cuts = (np.arange(sub) + 0.5) / sub - 0.5
    offsets = np.stack(np.meshgrid(cuts, cuts, cuts, indexing="ij"), -1).reshape(-1, 3)
    counted, refined, capped = [], [], []
    for mesh in meshes:
        v, f = baselines.split_geometry(mesh)
        sol = robust_solid(v, f, resolution=resolution)
        h, inside = sol.pitch, sol.inside
        _, zero = _voxel_index(sol)
        vc, caps = cap_holes(np.asarray(v, np.float64), np.asarray(f, np.int64))
        closed = trimesh.Trimesh(vc, np.vstack([f, caps]) if len(caps) else f, process=False)
        points, face = trimesh.sample.sample_surface(closed, int(closed.area / (0.15 * h) ** 2), seed=0)
        normals = closed.face_normals[face]
        band = (inside & ~ndimage.binary_erosion(inside, iterations=2)) | (ndimage.binary_dilation(inside, iterations=2) & ~inside)
        index = np.argwhere(band)
        query = (zero + index[:, None, :] * h + offsets[None] * h).reshape(-1, 3)
        _, near = cKDTree(points).query(query)
        behind = np.einsum("ij,ij->i", query - points[near], normals[near]) < 0
        fraction = behind.reshape(len(index), -1).mean(axis=1)
        counted.append(sol.volume())
        refined.append((inside.sum() - band[inside].sum() + fraction.sum()) * h ** 3)
        capped.append(abs(capped_volume(v, f)))
    cv = {key: spreads([[0, 0, 0]] * len(meshes), np.asarray(values) ** (1 / 3))[1]
          for key, values in (("voxels", counted), ("subvoxel", refined), ("capped", capped))}
    out(f"{name}: cv of V^(1/3): voxel count {cv['voxels']:.5f}, sub-voxel boundary {cv['subvoxel']:.5f}, "
        f"capped closed form {cv['capped']:.5f}")
    return cv


#: Grid shifts (in pitches) of ``--grid-offsets``: the library's grid and three shifted by half a
#: voxel along two axes each (together they sample every half-voxel parity once per axis pair).
GRID_SHIFTS = ((0.0, 0.0, 0.0), (0.5, 0.5, 0.0), (0.5, 0.0, 0.5), (0.0, 0.5, 0.5))


def grid_offsets(meshes, resolution=96, name="", out=print):
    """``--grid-offsets``: the robust center (depth^4) and volume of each shape on the library's
    grid and on grids shifted by :data:`GRID_SHIFTS` (``jaxpose.occupancy.solid.GRID_OFFSET``
    moved for the call, restored after), per grid the class's sigma_tr and cv of V^(1/3), and the
    same for the mean over the four grids of each shape's center and volume.
    Returns {"sigma_tr": [per grid], "cv": [per grid], "mean_sigma_tr", "mean_cv"}."""
    from jaxpose.occupancy import solid as solid_module
    from jaxpose.pose.estimators import solid_center_volume

    base = solid_module.GRID_OFFSET
    centers = np.zeros((len(GRID_SHIFTS), len(meshes), 3))
    volumes = np.zeros((len(GRID_SHIFTS), len(meshes)))
    try:
        for j, shift in enumerate(GRID_SHIFTS):
            solid_module.GRID_OFFSET = base + np.asarray(shift)
            for k, mesh in enumerate(meshes):
                v, f = baselines.split_geometry(mesh)
                centers[j, k], volumes[j, k] = solid_center_volume(robust_solid(v, f, resolution=resolution), 4)
    finally:
        solid_module.GRID_OFFSET = base
    one = [spreads(c, v ** (1 / 3)) for c, v in zip(centers, volumes)]
    mean = spreads(centers.mean(0), volumes.mean(0) ** (1 / 3))
    out(f"{name}: sigma_tr per grid {' '.join(f'{s:.5g}' for s, _ in one)}, mean of the grids {mean[0]:.5g}; "
        f"cv per grid {' '.join(f'{c:.5f}' for _, c in one)}, mean of the grids {mean[1]:.5f}")
    return {"sigma_tr": [s for s, _ in one], "cv": [c for _, c in one], "mean_sigma_tr": mean[0], "mean_cv": mean[1]}


BLEND_WEIGHTS = np.round(np.arange(0.0, 1.01, 0.1), 2)


def blend_study(meshes, resolution=96, name="", out=print):
    """``--blend``: per shape the robust solid's voxel volume V and the capped mesh area A; the
    class's cv of the blends V^(w/3) A^((1-w)/2) (w of :data:`BLEND_WEIGHTS`: 0 is √A, the area
    alone; 1 is V^(1/3), the default scale), the correlation of log V and log A over the class,
    and the slope of log V^(1/3) against log A^(1/2) (least squares): how much the volume's size
    moves per unit of the area's. With errors of the two that were independent a blend would beat
    both; where they move together (correlation near 1) every blend lies between them.
    Returns {"weights", "cv" (per weight), "corr", "slope", "range_volume", "range_area"}."""
    volumes, areas = [], []
    for mesh in meshes:
        v, f = baselines.split_geometry(mesh)
        volumes.append(robust_solid(v, f, resolution=resolution).volume())
        areas.append(capped_area(v, f))
    volumes, areas = np.asarray(volumes), np.asarray(areas)
    cvs = [spreads(np.zeros((len(meshes), 3)), volumes ** (w / 3) * areas ** ((1 - w) / 2))[1] for w in BLEND_WEIGHTS]
    lv, la = np.log(volumes) / 3, np.log(areas) / 2
    corr, slope = float(np.corrcoef(lv, la)[0, 1]), float(np.polyfit(la, lv, 1)[0])
    out(f"{name}: cv for w = {' '.join(f'{w:g}' for w in BLEND_WEIGHTS)}: {' '.join(f'{c:.5f}' for c in cvs)}; "
        f"corr(log V, log A) {corr:+.2f}, slope {slope:.2f}, range V {100 * (volumes.max() / volumes.min() - 1):.1f} %, "
        f"A {100 * (areas.max() / areas.min() - 1):.1f} %")
    return {"weights": BLEND_WEIGHTS.tolist(), "cv": cvs, "corr": corr, "slope": slope,
            "range_volume": float(volumes.max() / volumes.min() - 1), "range_area": float(areas.max() / areas.min() - 1)}


def principal_frame(vertices, faces):
    """(3, 3) rows: the principal axes of a mesh's surface (its exact second moments about the area
    centroid), largest first, each signed so that the surface's third moment along it is >= 0,
    right-handed: a frame that turns with the input."""
    tri = np.asarray(vertices, np.float64)[np.asarray(faces)]
    a = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1) / 2
    c = (a @ tri.mean(1)) / a.sum()
    z = tri - c
    second = z.sum(1)[:, :, None] * z.sum(1)[:, None, :] + np.einsum("tki,tkj->tij", z, z)
    axes = np.linalg.eigh(np.einsum("t,tij->ij", a / 12, second))[1][:, ::-1].T
    for k in range(3):
        if np.sum(a * ((tri.mean(1) - c) @ axes[k]) ** 3) < 0:
            axes[k] = -axes[k]
    if np.linalg.det(axes) < 0:
        axes[2] = -axes[2]
    return axes


def grid_frame(meshes, resolution=96, name="", out=print, seed=0):
    """``--grid-frame``: the robust center (depth^4) and V^(1/3) of each shape with the voxel grid
    along the input's axes (the library's) and along the surface's principal axes
    (:func:`principal_frame`, ``robust_solid(frame=...)``), each on the aligned meshes and on each
    mesh turned by its own random rotation (seeded; the center turned back). Prints per grid the
    class's sigma_tr and cv, and how far the library's pose moves when its input turns (center
    shift / scale, mean and largest; scale change, largest).
    Returns {"axes", "principal", "axes_turned", "principal_turned": (sigma_tr, cv), "shift": [...], "scale_change": [...]}."""
    from scipy.spatial.transform import Rotation

    from jaxpose.pose.estimators import solid_center_volume

    rng = np.random.default_rng(seed)
    found = {k: ([], []) for k in ("axes", "principal", "axes_turned", "principal_turned")}
    for mesh in meshes:
        v, f = baselines.split_geometry(mesh)
        turn = Rotation.random(random_state=rng).as_matrix()
        for key, x, frame in (("axes", v, None), ("principal", v, principal_frame(v, f)),
                              ("axes_turned", v @ turn.T, None), ("principal_turned", v @ turn.T, principal_frame(v @ turn.T, f))):
            c, vol = solid_center_volume(robust_solid(x, f, resolution=resolution, frame=frame), 4)
            found[key][0].append(c @ turn if key.endswith("turned") else c)
            found[key][1].append(vol ** (1 / 3))
    record = {k: spreads(np.asarray(c), np.asarray(s)) for k, (c, s) in found.items()}
    scale = np.asarray(found["axes"][1])
    shift = np.linalg.norm(np.asarray(found["axes_turned"][0]) - np.asarray(found["axes"][0]), axis=1) / scale
    change = np.abs(np.asarray(found["axes_turned"][1]) / scale - 1)
    record["shift"], record["scale_change"] = shift.tolist(), change.tolist()
    out(f"{name}: sigma_tr / cv, input's axes {record['axes'][0]:.5g} / {record['axes'][1]:.5f}, principal axes "
        f"{record['principal'][0]:.5g} / {record['principal'][1]:.5f}; turned inputs: input's axes "
        f"{record['axes_turned'][0]:.5g} / {record['axes_turned'][1]:.5f}, principal axes "
        f"{record['principal_turned'][0]:.5g} / {record['principal_turned'][1]:.5f}; the library's center moves "
        f"{100 * shift.mean():.2f} % of the scale on average ({100 * shift.max():.2f} % at most), its scale "
        f"{100 * change.max():.2f} % at most")
    return record


if __name__ == "__main__":
    raise SystemExit(main())
