"""A center on the head against the robust center, under both rigid cores (issue 34, the horse's σ_tr).

``python -m benchmarks.head_center [--variants plain,outliers,big_outliers,points,holes]
[--classes person_a,...] [--core-weight vertices,area] [--json OUT]`` or ``--head-size`` (plain
meshes, vertex core) from a source checkout with ../shared beside it.

The six dev classes as :mod:`benchmarks.bodies` loads them, rigid-core aligned with each core weight
of ``--core-weight`` (``jaxpose.evaluation.align_core``: the stable 30 % as a share of the vertices,
``jaxpose evaluate``'s default, or of the surface), every variant made as ``jaxpose evaluate`` makes
it (seed 0, the class index within its dataset). For every shape, four centers:

* ``robust``: the default (:func:`jaxpose.pose.estimators.robust_center_scale`, depth^4);
* ``head``: the head that the ``head`` frame finds (:func:`jaxpose.rotation.parts.find_head` on
  :func:`jaxpose.rotation.core.frame_solid`), its voxels weighted by depth^4 (the skull, not the
  snout or the neck); where no head is found, the robust center (counted in ``found``);
* ``vertex_mean`` and ``surface_centroid``: the classical centers that win a cell in the tables of
  ``jaxpose evaluate``.

``--head-size``: the cv over each class of sizes of the head (the skull is the one rigid part of a
vertebrate; on TOSCA's poses it is exactly rigid): its voxels' volume and the part beyond its neck's
(cube roots), its depth (the largest inscribed ball's radius), (h^3 sum d^2)^(1/5) over its voxels.

Per core, variant and class: sigma_tr of each center (``jaxpose.evaluation.measures.spread``) and how
many shapes had a head. Nothing is asserted: it is the record behind docs/estimators.md ("Nor by
the head"), which reads it ("A head is found now" under "Center").
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

from jaxpose import baselines
from jaxpose.evaluation import make_class
from jaxpose.evaluation.measures import scale_spread, spread
from jaxpose.pose.estimators import robust_center_scale
from jaxpose.rotation import parts
from jaxpose.rotation.core import frame_solid

from .bodies import CLASSES, SHARED, dev_classes

CENTERS = ("robust", "head", "vertex_mean", "surface_centroid")
HEAD_POWER = 4  # the head's voxels weighted by depth^4, as the robust center weighs the body's


def head_center(vertices, faces=None, power=HEAD_POWER):
    """The depth^power-weighted centroid (3,) of the head that the ``head`` frame finds, in world
    coordinates, or None where it finds none."""
    sol = frame_solid(vertices, faces)
    found = parts.find_head(sol)
    if found is None:
        return None
    index = np.stack(np.nonzero(found.head), axis=1)
    x = sol.origin + sol.pitch * (index + 0.5)  # the grid's frame
    w = sol.depth[found.head] ** power
    return (w @ x / w.sum()) @ sol.frame


def centers_of(shape):
    """{name: (3,) center} of one shape (module docs) and whether a head was found."""
    v, f = baselines.split_geometry(shape)
    robust = robust_center_scale(shape)[0]
    head = head_center(v, f)
    out = {"robust": robust, "head": robust if head is None else head, "vertex_mean": v.mean(axis=0)}
    if f is not None:
        out["surface_centroid"] = baselines.center(shape, "surface_centroid")
    return out, head is not None


def head_sizes(classes):
    """{class: {size: cv}} of the head's sizes (``--head-size``) on each class's meshes."""
    out = {}
    for name, meshes in classes.items():
        sizes = {"volume": [], "beyond_volume": [], "depth": [], "depth_volume^2": []}
        for mesh in meshes:
            v, f = baselines.split_geometry(mesh)
            sol = frame_solid(v, f)
            found = parts.find_head(sol)
            if found is None:
                continue
            h3, d = sol.pitch ** 3, sol.depth[found.head]
            beyond = found.head if found.beyond is None else found.beyond
            sizes["volume"].append((h3 * found.head.sum()) ** (1 / 3))
            sizes["beyond_volume"].append((h3 * beyond.sum()) ** (1 / 3))
            sizes["depth"].append(found.head_depth)
            sizes["depth_volume^2"].append((h3 * np.sum(d ** 2)) ** (1 / 5))
        out[name] = {k: scale_spread(np.asarray(s))["cv_scale"] for k, s in sizes.items()}
        print(f"  {name:10s} " + " ".join(f"{k} {c:.4f}" for k, c in out[name].items()), flush=True)
    return out


def main(argv=None):
    p = argparse.ArgumentParser(prog="python -m benchmarks.head_center")
    p.add_argument("--variants", default="plain,outliers,big_outliers,points,holes")
    p.add_argument("--classes", default=",".join(CLASSES))
    p.add_argument("--core-weight", default="vertices,area")
    p.add_argument("--head-size", action="store_true", help="the cv of the head's sizes (plain meshes, vertex core)")
    p.add_argument("--json", default=None)
    args = p.parse_args(argv)
    if not SHARED.is_dir():
        print(f"no {SHARED}: nothing to measure", file=sys.stderr)
        return 0
    if args.head_size:
        with tempfile.TemporaryDirectory() as tmp:
            record = head_sizes(dev_classes(tmp, args.classes.split(",")))
        if args.json:
            Path(args.json).write_text(json.dumps(record, indent=1))
        return 0
    record = {}
    for core in args.core_weight.split(","):
        with tempfile.TemporaryDirectory() as tmp:
            classes = dev_classes(tmp, args.classes.split(","), core_weight=core)
        record[core] = {}
        for variant in args.variants.split(","):
            record[core][variant] = {}
            print(f"\n{core} core, {variant}: sigma_tr of each center (found: shapes with a head)")
            print(f"  {'class':10s} " + " ".join(f"{c:>16s}" for c in CENTERS) + "   found")
            for name, meshes in classes.items():
                start = time.perf_counter()
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    rows = [centers_of(s) for s in make_class(meshes, variant, 0, CLASSES.index(name) % 2)]
                sigma = {c: spread(np.stack([r[c] for r, _ in rows]))["sigma_tr"] for c in CENTERS if c in rows[0][0]}
                found = sum(h for _, h in rows)
                record[core][variant][name] = {"sigma_tr": sigma, "found": found, "shapes": len(rows),
                                               "seconds": time.perf_counter() - start}
                print(f"  {name:10s} " + " ".join(f"{sigma[c]:16.5f}" if c in sigma else f"{'n/a':>16s}"
                                                  for c in CENTERS) + f"   {found}/{len(rows)}", flush=True)
    if args.json:
        Path(args.json).write_text(json.dumps(record, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
