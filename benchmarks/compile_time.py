"""Compilation time of a point pipeline (robust, or the OCSVM's), this checkout against others, side by side.

``python -m benchmarks.compile_time [--baseline DIR ...] [--rounds 3] [--points 5000] [--method robust|ocsvm]
[--x64] [--json OUT]``

Each round runs, for this checkout and every ``--baseline`` checkout (a root holding a
``jaxpose`` package) in turn, one fresh interpreter that imports that checkout's package with no
persistent compilation cache (``JAXPOSE_CACHE_DIR`` and ``JAX_COMPILATION_CACHE_DIR`` removed from
its environment, ``jax_compilation_cache_dir`` None), and measures on one cloud of ``--points``
points (FAUST ``tr_reg_000`` sampled with seed 0, float32, or float64 with ``--x64``; the built-in
example shape without ``../shared``):

- ``jax.jit(lambda x: jaxpose.normalize(x, method=METHOD).center).lower(x)``: seconds and the
  StableHLO text's length (characters);
- ``.compile()``: wall seconds and the process's CPU seconds (every thread; on a shared machine the
  CPU seconds move less with the load than the wall seconds), and the number of kernels XLA:CPU
  compiled for it (LLVM modules: identical fused kernels are compiled once; the compile time
  follows this count, which does not move with the load);
- the compiled program's warm run: median wall and CPU seconds of ``--repeats`` calls.

Prints a markdown table of the medians over the rounds and each checkout's commit; asserts nothing.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MARK = "JAXPOSE_COMPILE "
_CACHE_VARIABLES = ("JAXPOSE_CACHE_DIR", "JAX_COMPILATION_CACHE_DIR")

CHILD = r"""
import json, sys, time
import numpy as np
import jax
jax.config.update("jax_compilation_cache_dir", None)
points, repeats, data, method, x64 = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3], sys.argv[4], sys.argv[5] == "1"
jax.config.update("jax_enable_x64", x64)
import jaxpose
from jaxpose import mesh
source = mesh.load(data) if data else mesh.example_shape()
dtype = np.float64 if x64 else np.float32
x = jax.numpy.asarray(mesh.sample_surface(source, points, seed=0, method="random").astype(dtype))
t0 = time.perf_counter()
lowered = jax.jit(lambda x: jaxpose.normalize(x, method=method).center).lower(x)
lower_s = time.perf_counter() - t0
hlo = len(lowered.as_text())
c0, t0 = time.process_time(), time.perf_counter()
compiled = lowered.compile()
compile_s, compile_cpu_s = time.perf_counter() - t0, time.process_time() - c0
compiled(x).block_until_ready()
wall, cpu = [], []
for _ in range(repeats):
    c0, t0 = time.process_time(), time.perf_counter()
    compiled(x).block_until_ready()
    wall.append(time.perf_counter() - t0)
    cpu.append(time.process_time() - c0)
print("JAXPOSE_COMPILE " + json.dumps({"package": jaxpose.__file__, "lower_s": lower_s, "hlo_chars": hlo,
      "compile_s": compile_s, "compile_cpu_s": compile_cpu_s, "run_s": float(np.median(wall)),
      "run_cpu_s": float(np.median(cpu))}))
"""


def _data():
    path = ROOT.parent / "shared" / "data" / "faust-dev" / "tr_reg_000.ply"
    return str(path) if path.exists() else ""


def _commit(root):
    proc = subprocess.run(["git", "-C", str(root), "rev-parse", "--short", "HEAD"], capture_output=True, text=True)
    dirty = subprocess.run(["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no"],
                           capture_output=True, text=True).stdout.strip()
    return (proc.stdout.strip() or "?") + ("+changes" if dirty else "")


def child(root, points, repeats, data, method="robust", x64=False):
    """One fresh interpreter importing ``root``'s package: the measurements (module docs)."""
    env = {k: v for k, v in os.environ.items() if k not in _CACHE_VARIABLES}
    # XLA:CPU logs each kernel it compiles (one LLVM module each) at this verbosity, on stderr
    env.update(PYTHONPATH=str(root), TF_CPP_MIN_LOG_LEVEL="0", TF_CPP_VMODULE="ir_compiler=1")
    proc = subprocess.run([sys.executable, "-c", CHILD, str(points), str(repeats), data, method, "1" if x64 else "0"],
                          capture_output=True, text=True, env=env, cwd=str(root))
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith(MARK)]
    if proc.returncode != 0 or not lines:
        raise RuntimeError(f"child for {root} failed:\n{proc.stderr[-2000:]}")
    out = json.loads(lines[-1][len(MARK):])
    out["kernels"] = proc.stderr.count("Compiled LLVM module")  # every program the child compiled; the pipeline's most
    out["load"] = os.getloadavg()[0]
    return out


def run(baselines=(), rounds=3, points=5000, repeats=5, method="robust", x64=False):
    """{root: {"commit", "rounds": [child results]}}, the checkouts alternated round by round."""
    roots = [ROOT] + [Path(b).resolve() for b in baselines]
    data = _data()
    out = {str(r): {"commit": _commit(r), "rounds": []} for r in roots}
    for k in range(int(rounds)):
        order = roots[k % len(roots):] + roots[:k % len(roots)]
        for r in order:
            out[str(r)]["rounds"].append(child(r, points, repeats, data, method, x64))
    return out


def markdown(result):
    import numpy as np

    lines = ["| checkout | commit | compile, wall s | compile, CPU s | kernels | lower s | HLO chars | warm run, s |"
             " warm run, CPU s | load average |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for root, r in result.items():
        rows = r["rounds"]

        def med(key, rows=rows):
            return float(np.median([x[key] for x in rows]))

        lines.append(f"| {root} | {r['commit']} | {med('compile_s'):.2f} | {med('compile_cpu_s'):.2f} | "
                     f"{int(med('kernels'))} | {med('lower_s'):.2f} | {int(med('hlo_chars'))} | {med('run_s'):.3f} | {med('run_cpu_s'):.3f} | "
                     f"{min(x['load'] for x in rows):.1f}-{max(x['load'] for x in rows):.1f} |")
    lines.append("")
    lines.append(f"(medians of {len(next(iter(result.values()))['rounds'])} rounds, one fresh process per checkout "
                 "and round, the checkouts alternated)")
    return "\n".join(lines)


def main(argv=None):
    p = argparse.ArgumentParser(prog="python -m benchmarks.compile_time", description=__doc__.splitlines()[0])
    p.add_argument("--baseline", action="append", default=[], help="another checkout's root (repeatable)")
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--points", type=int, default=5000)
    p.add_argument("--repeats", type=int, default=5, help="warm calls timed per process")
    p.add_argument("--method", choices=("robust", "ocsvm"), default="robust")
    p.add_argument("--x64", action="store_true", help="float64 points (jax_enable_x64)")
    p.add_argument("--json", default=None)
    args = p.parse_args(argv)
    result = run(args.baseline, args.rounds, args.points, args.repeats, args.method, args.x64)
    print(markdown(result))
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
