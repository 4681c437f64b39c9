"""A vmapped batch of point clouds against a Python loop of single jitted calls, side by side.

``python -m benchmarks.batch_speed [--clouds 32] [--points 5000] [--method robust] [--repeats 2] [--json OUT]``

Inputs: ``--clouds`` clouds of ``--points`` area-weighted surface samples (seeded) of the FAUST
dev meshes (``../shared``; the built-in example shape without it), each moved and scaled
differently. Cases, interleaved in one process (:func:`benchmarks.common.interleaved`):

* ``batch``: ``jaxpose.normalize_batch(clouds, method=..., strategy="vmap")``: padded, masked,
  ``jax.vmap`` over the batch in one compiled call, the clouds in lock-step;
* ``loop``: ``[jaxpose.normalize(c, method=...) for c in clouds]``: one jitted call per cloud
  (the same compiled program each time: the clouds share a row bucket), each call's result
  checked on the host before the next starts (as ``normalize`` does), so one cloud at a time;
* ``map``: ``normalize_batch(clouds, method=...)`` with its default ``strategy="auto"``, which on
  CPU is ``"map"``: the same padded batch in one compiled call, cut into one ``lax.map`` chain per
  core of the process (``chains``), which XLA's CPU runtime may run at the same time.

Reported: seconds per cloud (median of the warm rounds) and the ratios loop / batch and
loop / map (the target of issue 33 is >= 2), the first call's extra time (compilation) apart, the
process's CPU seconds per cloud (median of the warm rounds; every thread, XLA's pool too, spinning included),
the load average before and after (the cores are shared), and the largest difference between the
batch results and the loop's (in units of each cloud's scale). Prints markdown; asserts nothing.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import resource
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

    from jaxpose.pose import pose as pose_module

    data, source = clouds(count, points, seed)
    cpu = {"batch": [], "loop": [], "map": []}  # CPU seconds of each call; the first (compiling) one left out below

    def counted(name, fn):
        def run_case():
            start = _cpu_s()
            out = np.asarray(fn())
            cpu[name].append(_cpu_s() - start)
            return out
        return run_case

    cases = {
        "batch": counted("batch", lambda: jaxpose.normalize_batch(data, method=method, strategy="vmap").center),
        "loop": counted("loop", lambda: np.stack([jaxpose.normalize(c, method=method).center for c in data])),
        "map": counted("map", lambda: jaxpose.normalize_batch(data, method=method).center),
    }
    load_before = os.getloadavg()
    start = now()
    timings, last = interleaved(cases, repeats)
    wall = now() - start
    load_after = os.getloadavg()
    single_scale = np.asarray([jaxpose.normalize(c, method=method).scale for c in data])
    diff = {k: float(np.max(np.max(np.abs(np.asarray(last[k]) - np.asarray(last["loop"])), axis=1) / single_scale))
            for k in ("batch", "map")}
    per = {k: v["median_s"] / count for k, v in timings.items()}
    return {
        "source": source, "clouds": count, "points": points, "method": method, "repeats": repeats,
        "backend": jax.default_backend(), "device": str(jax.devices()[0]), "cpu": platform.processor() or platform.machine(),
        "cores": pose_module._cores(), "chains": min(count, pose_module._cores()) if jax.default_backend() == "cpu" else 1,
        "load_before": load_before, "load_after": load_after,
        "timings": timings, "per_cloud_s": per, "ratio_loop_over_batch": per["loop"] / per["batch"],
        "ratio_loop_over_map": per["loop"] / per["map"],
        "cpu_per_cloud_s": {k: float(np.median(v[1:] or v)) / count for k, v in cpu.items()},
        "compile_s": {k: v.get("compile_s") for k, v in timings.items()},
        "max_difference_over_scale": diff, "wall_s": wall, "maxrss_mb": maxrss_mb(),
    }


def _cpu_s():
    """CPU seconds of this process so far, every thread (user + system)."""
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def report(r):
    lines = [f"# batch vs loop: {r['clouds']} clouds of {r['points']} points ({r['source']}), method={r['method']}",
             "", f"backend {r['backend']} ({r['device']}), {r['cores']} cores, map in {r['chains']} chains, "
             f"{r['repeats']} warm rounds, interleaved; load average {r['load_before'][0]:.1f} before, "
             f"{r['load_after'][0]:.1f} after", "",
             "| case | s per cloud (warm median) | whole call (s) | first call extra (compile, s) | CPU s per cloud |",
             "|---|---|---|---|---|"]
    names = {"batch": "batch (`strategy=\"vmap\"`)", "loop": "loop of jitted `normalize`",
             "map": "map (default `\"auto\"`: `\"map\"` on CPU)"}
    for k in ("batch", "loop", "map"):
        t = r["timings"][k]
        lines.append(f"| {names[k]} | {r['per_cloud_s'][k]:.4f} | {t['median_s']:.3f} | "
                     f"{t.get('compile_s', float('nan')):.2f} | {r['cpu_per_cloud_s'][k]:.3f} |")
    d = r["max_difference_over_scale"]
    lines += ["", f"loop / batch, per cloud: **{r['ratio_loop_over_batch']:.2f}x** (target >= 2); "
              f"loop / map: **{r['ratio_loop_over_map']:.2f}x**",
              f"largest center difference from the loop: batch {d['batch']:.2e}, map {d['map']:.2e} of the scale",
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
