"""Large point clouds, side by side: this checkout against a reference checkout (``--reference``).

Cases (each in its own subprocess per checkout, so imports and compilations do not leak):

robust N    ``normalize_mesh`` (the robust default) on a cloud of N surface samples of FAUST
            tr_reg_000 (or of a capsule without the data), min of ``--repeat`` runs after one warm-up.
ocsvm N     ``normalize(points, method="ocsvm")`` on such a cloud: the first call (compilation included) and the
            min of warm runs; the reference may need far longer (no subsampling), so it gets
            ``--timeout`` seconds and is reported as "> timeout" past them.

Usage::

    python -m benchmarks.bounded_cost --reference /path/to/other/checkout [--repeat 3]

The figures and how they were measured go to ``docs/performance.md``; nothing is asserted.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FAUST = Path("/work/shared/data/faust-dev/tr_reg_000.ply")

_CHILD = r"""
import json, sys, time
import numpy as np, trimesh
import jaxpose
from jaxpose import mesh
kind, n, repeat = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
path = sys.argv[4]
source = mesh.load(path) if path else trimesh.creation.capsule(height=1.0, radius=0.3, count=[32, 32])
points = np.asarray(mesh.sample_surface(source, n, seed=0, method="random"))
out = {}
if kind == "robust":
    cloud = trimesh.PointCloud(points)
    jaxpose.normalize_mesh(cloud)
    times = []
    for _ in range(repeat):
        t = time.perf_counter(); jaxpose.normalize_mesh(cloud); times.append(time.perf_counter() - t)
    out["min"] = min(times)
else:
    t = time.perf_counter(); pose = jaxpose.normalize(points, method="ocsvm"); np.asarray(pose.center)
    out["first"] = time.perf_counter() - t
    times = []
    for _ in range(repeat):
        t = time.perf_counter(); np.asarray(jaxpose.normalize(points, method="ocsvm").center); times.append(time.perf_counter() - t)
    out["min"] = min(times)
    out["count"] = int(np.asarray(getattr(pose, "count", n) if getattr(pose, "count", None) is not None else n))
print(json.dumps(out))
"""


def run_case(checkout, kind, n, repeat, timeout):
    env = {**os.environ, "PYTHONPATH": str(checkout), "PYTHONWARNINGS": "ignore", "PYTHONDONTWRITEBYTECODE": "1"}
    data = str(FAUST) if FAUST.exists() else ""
    try:
        done = subprocess.run([sys.executable, "-c", _CHILD, kind, str(n), str(repeat), data], capture_output=True,
                              text=True, env=env, cwd=checkout, timeout=timeout)
    except subprocess.TimeoutExpired:
        return {"timeout": timeout}
    if done.returncode != 0:
        return {"error": done.stderr.strip().splitlines()[-1] if done.stderr.strip() else "failed"}
    return json.loads(done.stdout.strip().splitlines()[-1])


def _fmt(r, key):
    if "timeout" in r:
        return f"> {r['timeout']:.0f} s"
    if "error" in r:
        return "-" if r["error"] == "-" else "error"
    return f"{r[key]:.2f} s"


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--reference", type=Path, help="another checkout to time side by side")
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--timeout", type=float, default=120.0)
    p.add_argument("--sizes", default="100000,200000,1000000")
    args = p.parse_args(argv)
    sizes = [int(s) for s in args.sizes.split(",")]
    cases = [("robust", n) for n in sizes] + [("ocsvm", 200_000)]
    print(f"{'case':<16} {'this':>12} {'reference':>12}  ratio")
    for kind, n in cases:
        this = run_case(ROOT, kind, n, args.repeat, args.timeout)
        ref = run_case(args.reference, kind, n, args.repeat, args.timeout) if args.reference else {"error": "-"}
        for key in (("first", "min") if kind == "ocsvm" else ("min",)):
            ratio = ""
            if key in this and key in ref:
                ratio = f"{this[key] / ref[key]:.2f}"
            label = f"{kind} {n:,}" + (f" {key}" if kind == "ocsvm" else "")
            print(f"{label:<16} {_fmt(this, key):>12} {_fmt(ref, key):>12}  {ratio}")
        if kind == "ocsvm" and "count" in this:
            print(f"{'':<16} fitted {this['count']} of {n:,} points")


if __name__ == "__main__":
    main()
