"""A vmapped batch of point clouds against a Python loop of single jitted calls, side by side.

``python -m benchmarks.batch_speed [--clouds 32] [--points 5000] [--method robust] [--repeats 2] [--json OUT]``

Inputs: ``--clouds`` clouds of ``--points`` area-weighted surface samples (seeded) of the FAUST
dev meshes (``../shared``; the built-in example shape without it), each moved and scaled
differently. Cases, interleaved in one process (:func:`benchmarks.common.interleaved`):

* ``batch``: ``jaxpose.normalize_batch(clouds, method=...)``: padded, masked, ``jax.vmap`` over
  the batch in one compiled call (``strategy="vmap"``);
* ``loop``: ``[jaxpose.normalize(c, method=...) for c in clouds]``: one jitted call per cloud
  (the same compiled program each time: the clouds share a row bucket);
* ``map`` (for comparison): ``normalize_batch(..., strategy="map")``: the same padded batch in one
  compiled call, the clouds one after another (``lax.map``) instead of in lock-step.

Reported: seconds per cloud (median of the warm rounds), their ratio loop / batch (the target is
>= 2), the first call's extra time (compilation) apart, and the largest difference between the two
results (in units of each cloud's scale). Prints markdown; asserts nothing.
"""
from __future__ import annotations

import argparse
import json
import platform
import sys

import numpy as np

from benchmarks.common import faust_dir, interleaved, maxrss_mb, now


def clouds(count, points, seed=0):
    """[(points, 3) float64] * count and the source's name."""
    from jaxpose import mesh

    d = faust_dir()
    sources = [mesh.load(d / f"tr_reg_{i:03d}.ply") for i in range(20)] if d is not None else [mesh.example_shape()]
    rng = np.random.default_rng(seed)
    out = []
    for k in range(count):
        p = mesh.sample_surface(sources[k % len(sources)], points, seed=seed + k, method="random")
        out.append(p * rng.uniform(0.5, 2.0) + rng.normal(size=3))
    return out, ("faust-dev" if d is not None else "example_shape")


def run(count=32, points=5000, method="robust", repeats=2, seed=0):
    import jax

    import jaxpose

    data, source = clouds(count, points, seed)
    cases = {
        "batch": lambda: jaxpose.normalize_batch(data, method=method, strategy="vmap").center,
        "loop": lambda: np.stack([jaxpose.normalize(c, method=method).center for c in data]),
        "map": lambda: jaxpose.normalize_batch(data, method=method, strategy="map").center,
    }
    start = now()
    timings, last = interleaved(cases, repeats)
    wall = now() - start
    single_scale = np.asarray(jaxpose.normalize_batch(data, method=method, strategy="vmap").scale)
    diff = np.max(np.abs(np.asarray(last["batch"]) - np.asarray(last["loop"])), axis=1) / single_scale
    per = {k: v["median_s"] / count for k, v in timings.items()}
    return {
        "source": source, "clouds": count, "points": points, "method": method, "repeats": repeats,
        "backend": jax.default_backend(), "device": str(jax.devices()[0]), "cpu": platform.processor() or platform.machine(),
        "timings": timings, "per_cloud_s": per, "ratio_loop_over_batch": per["loop"] / per["batch"],
        "ratio_loop_over_map": per["loop"] / per["map"],
        "compile_s": {k: v.get("compile_s") for k, v in timings.items()},
        "max_difference_over_scale": float(diff.max()), "wall_s": wall, "maxrss_mb": maxrss_mb(),
    }


def report(r):
    lines = [f"# batch vs loop: {r['clouds']} clouds of {r['points']} points ({r['source']}), method={r['method']}",
             "", f"backend {r['backend']} ({r['device']}), {r['repeats']} warm rounds, interleaved", "",
             "| case | s per cloud (warm median) | whole call (s) | first call extra (compile, s) |",
             "|---|---|---|---|"]
    for k in ("batch", "loop", "map"):
        t = r["timings"][k]
        lines.append(f"| {k} | {r['per_cloud_s'][k]:.4f} | {t['median_s']:.3f} | {t.get('compile_s', float('nan')):.2f} |")
    lines += ["", f"loop / batch, per cloud: **{r['ratio_loop_over_batch']:.2f}x** (target >= 2); "
              f"loop / map: {r['ratio_loop_over_map']:.2f}x",
              f"largest |batch - loop| center difference: {r['max_difference_over_scale']:.2e} of the scale",
              f"peak memory {r['maxrss_mb']:.0f} MB, wall {r['wall_s']:.0f} s"]
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--clouds", type=int, default=32)
    ap.add_argument("--points", type=int, default=5000)
    ap.add_argument("--method", default="robust", choices=("robust", "ocsvm"))
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--json")
    a = ap.parse_args(argv)
    r = run(a.clouds, a.points, a.method, a.repeats)
    print(report(r))
    if a.json:
        with open(a.json, "w") as fh:
            json.dump(r, fh, indent=1, default=float)
    return 0


if __name__ == "__main__":
    sys.exit(main())
