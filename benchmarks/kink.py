"""The derivative of the center in nu where the pose has a kink: a step-size table.

``python -m benchmarks.kink [--m 800] [--gamma 20] [--nu 0.3] [--tol T] [--float32] [--json OUT]``

A sphere with one arm (``tests/conftest.py``, ``sphere_with_arm(m, seed=1)``), float64 (or JAX's
default float32 with ``--float32``), at ``normalize``'s default solver tol (or ``--tol``). Prints:

1. ``jax.jacfwd`` of ``normalize(..., method="ocsvm").center`` in nu with each derivative mode (``trend``: the
   secant of the SVDD solution over nu (1 +- 1 %) with the grid held fixed; ``exact``: the slope
   of the piece nu lies on; ``secant``).
2. Central differences (f(nu (1 + e)) - f(nu (1 - e))) / (2 nu e) of ``normalize`` itself at steps
   e from 0.1 % to 10 %, at the solver tol and at a tight one (1e-7), and the one-sided
   differences; each with its relative distance to the trend.
3. The center along nu on a fine lattice (steps of 0.1 % of nu over +-3 %): where the function
   jumps, and how much of a difference quotient one jump is.

Asserts nothing; docs/design.md ("How gradients flow") quotes its output.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
STEPS = (0.001, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1)


def _rel(a, b):
    a, b = np.asarray(a), np.asarray(b)
    return float(np.linalg.norm(a - b) / max(np.linalg.norm(b), 1e-300))


TIGHT = 1e-7


def measure(m=800, gamma=20.0, nu=0.3, tol=None, progress=print):
    import jax
    import jax.numpy as jnp

    import jaxpose

    sys.path.insert(0, str(ROOT / "tests"))
    from conftest import sphere_with_arm

    pts = jnp.asarray(sphere_with_arm(m, seed=1), jnp.result_type(float))
    opts = {} if tol is None else {"tol": tol}

    def center(n, t=tol, **kw):
        return np.asarray(jaxpose.normalize(pts, method="ocsvm", gamma=gamma, nu=n, **({} if t is None else {"tol": t}), **kw).center,
                          np.float64)

    out = {"m": m, "gamma": gamma, "nu": nu, "tol": tol, "dtype": str(pts.dtype), "jacfwd": {}, "central": [],
           "lattice": []}
    for mode in ("trend", "exact", "secant"):
        j = jax.jacfwd(lambda n: jaxpose.normalize(pts, method="ocsvm", gamma=gamma, nu=n, derivative=mode, **opts).center)(
            jnp.asarray(nu, pts.dtype))
        out["jacfwd"][mode] = np.asarray(j, np.float64).tolist()
        progress(f"jacfwd {mode}: {np.asarray(j)}")
    c0 = center(nu)
    trend = np.asarray(out["jacfwd"]["trend"])
    for e in STEPS:
        row = {"step": e}
        for label, t in (("tol", tol), ("tight", TIGHT)):
            hi, lo, mid = center(nu * (1 + e), t), center(nu * (1 - e), t), center(nu, t)
            row[f"central_{label}"] = ((hi - lo) / (2 * nu * e)).tolist()
            row[f"forward_{label}"] = ((hi - mid) / (nu * e)).tolist()
            row[f"backward_{label}"] = ((mid - lo) / (nu * e)).tolist()
        row["vs_trend"] = _rel(trend, row["central_tol"])
        row["tight_vs_trend"] = _rel(trend, row["central_tight"])
        row["tight_vs_tol"] = _rel(row["central_tight"], row["central_tol"])
        out["central"].append(row)
        progress(f"step {e:g}: central {np.round(row['central_tol'], 4)} (tight {np.round(row['central_tight'], 4)}), "
                 f"vs trend {row['vs_trend']:.2f}")
    for k in range(-30, 31):
        n = nu * (1 + 0.001 * k)
        out["lattice"].append({"nu": n, "center": (center(n) - c0).tolist()})
    progress("lattice done")
    return out


def markdown(out):
    j = out["jacfwd"]
    f = lambda v: "(" + ", ".join(f"{x:+.4f}" for x in v) + ")"
    tol = "normalize's default" if out["tol"] is None else f"{out['tol']:g}"
    lines = [f"sphere with one arm, m = {out['m']}, gamma {out['gamma']:g}, nu {out['nu']:g}, {out['dtype']}, solver tol "
             f"{tol}", "", "| derivative | d center / d nu | distance to the trend |", "|---|---|---|"]
    trend = np.asarray(j["trend"])
    for mode, v in j.items():
        lines.append(f"| jacfwd, derivative={mode!r} | {f(v)} | {_rel(v, trend):.2f} |")
    for r in out["central"]:
        lines.append(f"| central difference, step {r['step']:.1%} | {f(r['central_tol'])} | {r['vs_trend']:.2f} |")
    for r in out["central"]:
        lines.append(f"| central difference, step {r['step']:.1%}, tol {TIGHT:g} | {f(r['central_tight'])} | "
                     f"{r['tight_vs_trend']:.2f} |")
    lines += ["", "| step | forward difference | backward difference |", "|---|---|---|"]
    for r in out["central"]:
        lines.append(f"| {r['step']:.1%} | {f(r['forward_tol'])} | {f(r['backward_tol'])} |")
    lat = out["lattice"]
    x = np.array([r["center"] for r in lat])
    d = np.linalg.norm(np.diff(x, axis=0), axis=1)
    typical = float(np.median(d))
    jumps = [(lat[i]["nu"], lat[i + 1]["nu"], float(d[i])) for i in np.argsort(d)[::-1][:5]]
    lines += ["", f"center along nu in steps of 0.1 % of nu over +-3 %: median move per step {typical:.2e}; "
                  "largest moves:"]
    lines += [f"- nu {a:.4f} -> {b:.4f}: {v:.2e} ({v / max(typical, 1e-300):.0f}x the median)" for a, b, v in jumps]
    return "\n".join(lines)


def main(argv=None):
    p = argparse.ArgumentParser(prog="python -m benchmarks.kink", description=__doc__.splitlines()[0])
    p.add_argument("--m", type=int, default=800)
    p.add_argument("--gamma", type=float, default=20.0)
    p.add_argument("--nu", type=float, default=0.3)
    p.add_argument("--tol", type=float, default=None, help="solver tol (default: normalize's)")
    p.add_argument("--float32", action="store_true", help="JAX's default float32 (default: float64)")
    p.add_argument("--json", default=None)
    args = p.parse_args(argv)
    import jax

    jax.config.update("jax_enable_x64", not args.float32)
    out = measure(args.m, args.gamma, args.nu, args.tol, progress=lambda s: print(s, file=sys.stderr, flush=True))
    print(markdown(out))
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
