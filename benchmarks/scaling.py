"""The ``scaling`` section of ``jaxpose bench``: in m (one subprocess per case, so that peak
memory is per case) and in the grid resolution (moments alone vs ``decision_function``)."""
from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path
import sys

import numpy as np

from . import common
from .common import GAMMA, MARKER, NU, UNAVAILABLE, block, interleaved, ratio, load_points, prescale
from .sklearn_pipeline import sk_fit, sk_grid


def run_child(spec, timeout):
    """Run one case in a fresh interpreter (``python -m benchmarks.child``); its JSON result."""
    cmd = [sys.executable, "-m", "benchmarks.child", json.dumps(spec)]
    env = dict(os.environ)
    env.setdefault("PYTHONWARNINGS", "ignore")
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=env,
                              cwd=str(Path(__file__).resolve().parents[1]))
    except subprocess.TimeoutExpired:
        return {"kind": spec["kind"], "m": spec["m"], "error": f"timed out after {timeout} s"}
    for line in proc.stdout.splitlines()[::-1]:
        if line.startswith(MARKER):
            return json.loads(line[len(MARKER):])
    tail = " ".join((proc.stderr or "").strip().splitlines()[-3:])
    return {"kind": spec["kind"], "m": spec["m"], "error": f"exit {proc.returncode}: {tail}"}


def _timing(x):
    """x when it is a timing (has a median), else None."""
    return x if isinstance(x, dict) and "median_s" in x else None


def _scaling_in_m(ms, gamma, nu, repeats, sk, sk_max_m, timeout, x64, resolution, warm_max_m, max_iter, fit=None):
    rows = []
    for m in ms:
        # beyond the dense limit one fit takes minutes: one cold run only (compile not separated)
        spec = {"m": int(m), "repeats": repeats if m <= warm_max_m else 0, "max_iter": max_iter, "gamma": gamma,
                "nu": nu, "resolution": resolution, "sk_resolution": resolution, "fit": dict(fit or {})}
        row = {"m": int(m), "jaxpose": run_child({**spec, "kind": "jaxpose", "x64": x64}, timeout)}
        if not sk:
            row["sklearn"] = UNAVAILABLE
        elif m > sk_max_m:
            row["sklearn"] = f"skipped: m > {sk_max_m} (fit is superquadratic and the grid is single-threaded)"
        else:
            row["sklearn"] = run_child({**spec, "kind": "sklearn"}, timeout)
        row["ratio"] = ratio(_timing(row["jaxpose"]), _timing(row["sklearn"]))
        rows.append(row)
    return rows


def _scaling_in_resolution(resolutions, m_grid, gamma, nu, repeats, sk, sk_max_grid_points):
    """Moments alone (refine=1, plain grid) vs decision_function on the grid."""
    from jaxpose.moments import volume_moments
    from jaxpose.occupancy.svdd import fit_svdd

    points, _ = load_points(m_grid)
    y = prescale(points)[0]
    svdd = block(fit_svdd(y, gamma, nu))
    oc = sk_fit(y, gamma, nu) if sk else None
    rows = []
    for r in resolutions:
        cases = {"jaxpose": lambda r=r: volume_moments(svdd, resolution=int(r), refine=1)}
        extrapolated = False
        if sk:
            x = sk_grid(oc, y, gamma, nu, r)
            n = x.shape[0]
            if n > sk_max_grid_points:  # decision_function is linear in the number of points
                extrapolated = True
                x = x[np.random.default_rng(0).choice(n, sk_max_grid_points, replace=False)]
            cases["sklearn"] = lambda x=x: oc.decision_function(x)
        times, _ = interleaved(cases, repeats)
        row = {"resolution": int(r), "grid_points": int(r) ** 3, "jaxpose": times["jaxpose"]}
        if sk:
            s = dict(times["sklearn"])
            if extrapolated:
                f = (int(r) ** 3) / sk_max_grid_points
                s = {"median_s": s["median_s"] * f, "runs_s": [t * f for t in s["runs_s"]],
                     "extrapolated_from_points": sk_max_grid_points}
            s.pop("first_s", None)
            s.pop("compile_s", None)
            row["sklearn"] = s
            row["ratio"] = ratio(row["jaxpose"], s)
        else:
            row["sklearn"], row["ratio"] = UNAVAILABLE, None
        rows.append(row)
    return rows


def bench_scaling(ms=(1000, 2000, 4000, 8000, 16000), resolutions=(32, 64, 128), m_grid=2000, gamma=GAMMA, nu=NU,
                  repeats=1, sk_max_m=8000, sk_max_grid_points=32_768, use_sklearn=True, timeout=1800, x64=False,
                  resolution=32, warm_max_m=12_000, max_iter=None, fit=None):
    """Scaling in m (fit + moments per subprocess, with peak RSS) and in grid resolution.

    max_iter: cap the solver (memory only depends on shapes, so a capped run measures peak memory
    of large m in a fraction of the time; timings are then per capped run and marked)."""
    sk = use_sklearn and common.sklearn_available()
    in_m = _scaling_in_m(ms, gamma, nu, repeats, sk, sk_max_m, timeout, x64, resolution, warm_max_m, max_iter, fit)
    in_res = _scaling_in_resolution(resolutions, m_grid, gamma, nu, repeats, sk, sk_max_grid_points)
    return {"in_m": in_m, "in_m_resolution": resolution, "in_resolution": {"m": m_grid, "refine": 1, "rows": in_res},
            "sklearn_max_m": sk_max_m}
