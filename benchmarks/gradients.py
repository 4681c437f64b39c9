"""Derivatives of the pose in gamma and nu against finite differences of the public function, and their cost.

``python -m benchmarks.gradients [--json OUT] [--m 1000] [--tol 1e-6] [--no-timing] [--timing-only]``

1. Accuracy (float64): on FAUST dev meshes (tr_reg_000, tr_reg_013, when ../shared is there) and
   synthetic shapes (a sphere with an arm, the example shape), at (gamma, nu) = (20, 0.3),
   (47, 0.5), (10, 0.1): ``jax.jacfwd`` of ``normalize(..., method="ocsvm").center`` and ``.scale`` with the
   default derivative (``"trend"``) and with ``derivative="exact"``, against central finite
   differences of ``normalize`` itself at steps of 1 % and 2 % of gamma and of nu. A derivative
   passes where its center (vector) and its scale are within 20 % of the difference quotient,
   or within 1e-6 of it. ``--tol`` is the solver tolerance of every call (default 1e-6: a
   difference quotient over a 2 % interval needs function values that accurate).
2. Cost: wall time under jit of the forward call, ``jax.grad`` of a scalar of the pose in
   (gamma, nu) and ``jax.jacfwd`` of (center, scale), at m = 2000 samples and default options, in
   float32 and float64; medians of warm runs, the cases interleaved so that they share the
   machine's state; ratios to the forward call.

Prints markdown; asserts nothing.
"""
from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
PARAMS = ((20.0, 0.3), (47.0, 0.5), (10.0, 0.1))
STEPS = (0.01, 0.02)
RTOL, ATOL = 0.20, 1e-6


def shapes(m):
    """{name: (m, 3) float64 points}: FAUST dev meshes when present, and synthetic shapes."""
    sys.path.insert(0, str(ROOT / "tests"))
    from conftest import sphere_with_arm

    from benchmarks.common import faust_dir
    from jaxpose.mesh import example_shape, load, sample_surface

    out = {}
    d = faust_dir()
    if d is not None:
        for i in (0, 13):
            out[f"faust/tr_reg_{i:03d}"] = np.asarray(sample_surface(load(d / f"tr_reg_{i:03d}.ply"), m, seed=0))
    out["sphere_arm"] = sphere_with_arm(m, seed=1)
    out["example_shape"] = np.asarray(sample_surface(example_shape(), m, seed=1))
    return out


def agrees(j, fd):
    """Center (vector) and scale of a derivative j (4,) within RTOL of fd (4,), or within ATOL."""
    j, fd = np.asarray(j, np.float64), np.asarray(fd, np.float64)
    ec, es = np.linalg.norm(j[:3] - fd[:3]), abs(j[3] - fd[3])
    rc, rs = ec / max(np.linalg.norm(fd[:3]), 1e-300), es / max(abs(fd[3]), 1e-300)
    return bool((rc <= RTOL or ec <= ATOL) and (rs <= RTOL or es <= ATOL)), float(rc), float(rs)


def accuracy(m=1000, tol=1e-6, params=PARAMS, progress=print):
    """Rows per (shape, gamma, nu): derivatives, difference quotients, relative errors, verdicts."""
    import jax
    import jax.numpy as jnp

    import jaxpose

    rows = []
    for name, pts in shapes(m).items():
        def vec(g, n, **kw):
            p = jaxpose.normalize(pts, method="ocsvm", gamma=g, nu=n, tol=tol, **kw)
            return jnp.concatenate([p.center, p.scale[None]])

        for g, n in params:
            t0 = time.perf_counter()
            jac = {mode: np.asarray(jax.jacfwd(lambda t, mode=mode: vec(t[0], t[1], derivative=mode))(
                jnp.asarray([g, n]))) for mode in ("trend", "exact")}
            row = dict(shape=name, gamma=g, nu=n, trend=jac["trend"].tolist(), exact=jac["exact"].tolist())
            for k, (pname, th) in enumerate((("gamma", g), ("nu", n))):
                for e in STEPS:
                    hi, lo = (g * (1 + e), n) if k == 0 else (g, n * (1 + e)), (g * (1 - e), n) if k == 0 else (g, n * (1 - e))
                    fd = (np.asarray(vec(*hi)) - np.asarray(vec(*lo))) / (2 * th * e)
                    row[f"fd_{pname}_{e:g}"] = fd.tolist()
                    for mode in ("trend", "exact"):
                        ok, rc, rs = agrees(jac[mode][:, k], fd)
                        row[f"{mode}_{pname}_{e:g}"] = dict(ok=ok, center=rc, scale=rs)
            row["seconds"] = time.perf_counter() - t0
            rows.append(row)
            progress(f"{name} ({g:g}, {n:g}): " + ", ".join(
                f"{mode} d{p} {e:.0%} {'ok' if row[f'{mode}_{p}_{e:g}']['ok'] else 'FAIL'}"
                for mode in ("trend", "exact") for p in ("gamma", "nu") for e in STEPS))
    return rows


def _time(fns, args, repeats):
    """Median warm wall time per function, the functions interleaved run by run."""
    import jax

    for k, fn in fns.items():
        jax.block_until_ready(fn(*args[k]))  # compile and first run
    times = {k: [] for k in fns}
    for _ in range(repeats):
        for k, fn in fns.items():
            t = time.perf_counter()
            jax.block_until_ready(fn(*args[k]))
            times[k].append(time.perf_counter() - t)
    return {k: statistics.median(v) for k, v in times.items()}


def timing(m=2000, repeats=5, x64=False):
    """Seconds and ratios to the forward call of grad / jacfwd under jit (default options)."""
    import jax
    import jax.numpy as jnp

    import jaxpose
    from benchmarks.common import load_points

    old = jax.config.jax_enable_x64
    jax.config.update("jax_enable_x64", bool(x64))
    try:
        pts, name = load_points(m, seed=0)
        dt = jnp.result_type(float)

        def vec(t, **kw):
            p = jaxpose.normalize(pts, method="ocsvm", gamma=t[0], nu=t[1], **kw)
            return jnp.concatenate([p.center, p.scale[None]])

        t0 = jnp.asarray([47.0, 0.5], dt)
        fns = {"forward": jax.jit(lambda t: jnp.sum(vec(t))),
               "grad (gamma, nu)": jax.jit(jax.grad(lambda t: jnp.sum(vec(t)))),
               "jacfwd (gamma, nu)": jax.jit(jax.jacfwd(vec)),
               "grad, derivative='exact'": jax.jit(jax.grad(lambda t: jnp.sum(vec(t, derivative="exact"))))}
        secs = _time(fns, {k: (t0,) for k in fns}, repeats)
        return dict(shape=name, m=m, dtype=str(dt), seconds=secs,
                    ratio={k: v / secs["forward"] for k, v in secs.items()})
    finally:
        jax.config.update("jax_enable_x64", old)


def markdown(result):
    lines = []
    rows = result.get("accuracy") or []
    if rows:
        lines += ["| case | trend d/dgamma 1 % | trend d/dnu 1 % | trend d/dgamma 2 % | trend d/dnu 2 % "
                  "| exact d/dgamma 1 % | exact d/dnu 1 % |", "|---|---|---|---|---|---|---|"]
        cell = lambda r: f"{r['center']:.2f} / {r['scale']:.2f} {'ok' if r['ok'] else '**no**'}"
        for r in rows:
            lines.append(f"| {r['shape']} ({r['gamma']:g}, {r['nu']:g}) | " + " | ".join(
                cell(r[k]) for k in ("trend_gamma_0.01", "trend_nu_0.01", "trend_gamma_0.02", "trend_nu_0.02",
                                     "exact_gamma_0.01", "exact_nu_0.01")) + " |")
        for mode in ("trend", "exact"):
            for e in STEPS:
                n_ok = sum(r[f"{mode}_gamma_{e:g}"]["ok"] and r[f"{mode}_nu_{e:g}"]["ok"] for r in rows)
                lines.append(f"\n{mode}, steps of {e:.0%}: {n_ok} of {len(rows)} cases within 20 % (center and scale, "
                             "gamma and nu)")
        lines.append("\nCells: relative error of the center / of the scale against the difference quotient.")
    for t in result.get("timing") or []:
        lines.append(f"\n{t['shape']}, m = {t['m']}, {t['dtype']}:")
        lines += [f"- {k}: {v:.3f} s, {t['ratio'][k]:.2f}x forward" for k, v in t["seconds"].items()]
    return "\n".join(lines)


def main(argv=None):
    p = argparse.ArgumentParser(prog="python -m benchmarks.gradients", description=__doc__.splitlines()[0])
    p.add_argument("--json", default=None)
    p.add_argument("--m", type=int, default=1000, help="points per shape in the accuracy part")
    p.add_argument("--tol", type=float, default=1e-6)
    p.add_argument("--repeats", type=int, default=5)
    p.add_argument("--no-timing", action="store_true")
    p.add_argument("--timing-only", action="store_true")
    args = p.parse_args(argv)
    import jax

    result = {}
    if not args.timing_only:
        jax.config.update("jax_enable_x64", True)
        result["accuracy"] = accuracy(args.m, args.tol, progress=lambda s: print(s, file=sys.stderr, flush=True))
        jax.config.update("jax_enable_x64", False)
    if not args.no_timing:
        result["timing"] = [timing(repeats=args.repeats, x64=x64) for x64 in (False, True)]
    print(markdown(result))
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
