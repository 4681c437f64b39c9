"""The SVDD stop rule across gamma: the small-gamma limit, default tol against a tight solution, timing.

``python -m benchmarks.stop_rule [--json OUT] [--baseline DIR] [--m 400] [--repeats 5]`` (float64).

1. Minimum enclosing ball: ``volume_moments(fit_svdd(X, gamma=1e-3, nu=0))`` at the default tol
   against the miniball center, on unit-size clustered data (3 seeds, each solver).
2. Default tol against tol 1e-7: ``normalize`` at gamma in [1e-3, 500] and nu in {0, 0.5} on a
   sphere with an arm, a box and the example shape (FAUST tr_reg_000 when ../shared is there):
   the center and scale differences in units of the tight solution's scale, and the iterations.
3. Timing at the default (gamma, nu): ``normalize`` of m = 2000 samples, median of warm runs, in
   child processes that import jaxpose from this checkout and (``--baseline DIR``) from another
   checkout of the package, run in turn (A B A B ...) so the two share the machine's state.

Prints markdown; asserts nothing.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
GAMMAS = (1e-3, 1e-2, 0.1, 1.0, 2.0, 5.0, 20.0, 47.0, 100.0, 500.0)
NUS = (0.0, 0.5)
TIGHT = dict(tol=1e-7, max_iter=200_000)


def _shapes(m):
    sys.path.insert(0, str(ROOT / "tests"))
    from conftest import box_surface, sphere_with_arm

    from benchmarks.common import load_points

    pts, name = load_points(m, seed=1)
    return {"sphere_arm": sphere_with_arm(m, seed=1), "box": box_surface(m, seed=3), name: pts}


def minimum_ball(seeds=(0, 1, 2), m=400):
    """Distance of the gamma = 1e-3, nu = 0 region's centroid from the miniball center per seed and solver."""
    sys.path.insert(0, str(ROOT / "tests"))
    from conftest import clusters

    import jaxpose

    try:
        import miniball
    except ImportError:
        return None
    rows = []
    for seed in seeds:
        x = clusters(m, seed=seed)
        x = x / float(np.max(x.max(0) - x.min(0)))  # unit size
        c, _ = miniball.get_bounding_ball(x)
        for solver in ("pg", "smo", "auto"):
            s = jaxpose.fit_svdd(x, gamma=1e-3, nu=0.0, solver=solver)
            mom = jaxpose.volume_moments(s)
            rows.append(dict(seed=seed, solver=solver, iterations=int(s.iterations), converged=bool(s.converged),
                             distance=float(np.linalg.norm(np.asarray(mom.center) - c))))
    return rows


def tolerance_table(m=400, gammas=GAMMAS, nus=NUS):
    """normalize at the default tol against tol 1e-7, per shape, gamma and nu."""
    import jaxpose

    rows = []
    for name, pts in _shapes(m).items():
        for nu in nus:
            for g in gammas:
                a, b = jaxpose.normalize(pts, method="ocsvm", gamma=g, nu=nu), jaxpose.normalize(pts, method="ocsvm", gamma=g, nu=nu, **TIGHT)
                s = float(b.scale)
                rows.append(dict(shape=name, gamma=g, nu=nu, iterations=int(a.iterations),
                                 iterations_tight=int(b.iterations), converged_tight=bool(b.converged),
                                 center=float(np.linalg.norm(np.asarray(a.center) - np.asarray(b.center))) / s,
                                 scale=abs(float(a.scale) - s) / s))
    return rows


CHILD = """
import json, statistics, sys, time
import jax
jax.config.update("jax_enable_x64", True)
import numpy as np
import jaxpose
pts = np.load(sys.argv[1])
out = {}
for name, (g, n) in {"default (47, 0.5)": (47.0, 0.5), "(20, 0.3)": (20.0, 0.3)}.items():
    p = jaxpose.normalize(pts, method="ocsvm", gamma=g, nu=n)
    jax.block_until_ready(p.center)
    ts = []
    for _ in range(int(sys.argv[2])):
        t = time.perf_counter(); jax.block_until_ready(jaxpose.normalize(pts, method="ocsvm", gamma=g, nu=n).center); ts.append(time.perf_counter() - t)
    out[name] = dict(seconds=statistics.median(ts), iterations=int(p.iterations), scale=float(p.scale))
print("RESULT " + json.dumps(out))
"""


def _child(root, path, repeats):
    env = {**os.environ, "PYTHONPATH": str(root)}
    proc = subprocess.run([sys.executable, "-c", CHILD, str(path), str(repeats)], capture_output=True, text=True,
                          env=env, cwd=str(root), check=True)
    line = [ln for ln in proc.stdout.splitlines() if ln.startswith("RESULT ")][-1]
    return json.loads(line[len("RESULT "):])


def timing(baseline=None, m=2000, repeats=5, rounds=2, tmp="/tmp"):
    """{label: [per-round results]} for this checkout and the baseline, alternated round by round."""
    from benchmarks.common import load_points

    pts, _ = load_points(m, seed=0)
    path = Path(tmp) / f"stop_rule_points_{os.getpid()}.npy"
    np.save(path, pts)
    roots = {"this checkout": ROOT} | ({"baseline": Path(baseline).resolve()} if baseline else {})
    out = {k: [] for k in roots}
    try:
        for _ in range(rounds):
            for label, root in roots.items():
                out[label].append(_child(root, path, repeats))
    finally:
        path.unlink(missing_ok=True)
    return out


def markdown(result):
    lines = []
    if result.get("minimum_ball"):
        lines += ["| seed | solver | iterations | converged | distance to the miniball center |", "|---|---|---|---|---|"]
        lines += [f"| {r['seed']} | {r['solver']} | {r['iterations']} | {r['converged']} | {r['distance']:.1e} |"
                  for r in result["minimum_ball"]]
        lines.append("")
    rows = result["tolerance"]
    lines += ["| shape | nu | " + " | ".join(f"{g:g}" for g in GAMMAS) + " |", "|---|---|" + "---|" * len(GAMMAS)]
    for shape in dict.fromkeys(r["shape"] for r in rows):
        for nu in NUS:
            sel = [r for r in rows if r["shape"] == shape and r["nu"] == nu]
            cells = [f"{max(r['center'], r['scale']):.1e} ({r['iterations']})" for r in sel]
            lines.append(f"| {shape} | {nu:g} | " + " | ".join(cells) + " |")
    worst = max(max(r["center"], r["scale"]) for r in rows)
    lines += ["", f"worst |difference| / scale: {worst:.2e} (acceptance: <= 1e-3); "
              f"tight solutions converged: {all(r['converged_tight'] for r in rows)}", ""]
    for label, runs in result.get("timing", {}).items():
        for case in runs[0]:
            secs = [r[case]["seconds"] for r in runs]
            lines.append(f"- {label}, {case}: {min(secs):.3f} s (min of {len(secs)} rounds' medians), "
                         f"{runs[0][case]['iterations']} iterations, scale {runs[0][case]['scale']:.6f}")
    return "\n".join(lines)


def main(argv=None):
    p = argparse.ArgumentParser(prog="python -m benchmarks.stop_rule", description=__doc__.splitlines()[0])
    p.add_argument("--json", default=None)
    p.add_argument("--baseline", default=None, help="another checkout (its root) to time side by side")
    p.add_argument("--m", type=int, default=400, help="points per shape in the tolerance table")
    p.add_argument("--repeats", type=int, default=5)
    p.add_argument("--no-timing", action="store_true")
    args = p.parse_args(argv)
    import jax

    jax.config.update("jax_enable_x64", True)
    start = time.perf_counter()
    result = {"minimum_ball": minimum_ball(), "tolerance": tolerance_table(args.m)}
    if not args.no_timing:
        result["timing"] = timing(args.baseline, repeats=args.repeats)
    result["seconds"] = time.perf_counter() - start
    print(markdown(result))
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
