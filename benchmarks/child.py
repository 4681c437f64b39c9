"""One case of the ``scaling`` section, run in a fresh interpreter so that its peak memory is its own.

``python -m benchmarks.child SPEC_JSON`` prints one line ``JAXPOSE_BENCH {json}``
(see ``scaling.run_child``). Not imported by the package, so ``-m`` runs it cleanly.
"""
from __future__ import annotations

import json
import sys

from .common import GAMMA, MARKER, NU, grid_opts, maxrss_mb, summary, timed, load_points, prescale
from .sklearn_pipeline import sklearn_pipeline


def child_main(spec_json):
    """Run one case (called in a fresh interpreter); prints one JSON line."""
    spec = json.loads(spec_json)
    if spec.get("x64"):
        import jax

        jax.config.update("jax_enable_x64", True)
    m, kind, repeats = int(spec["m"]), spec["kind"], int(spec.get("repeats", 1))
    points, _ = load_points(m)
    gamma, nu = float(spec.get("gamma", GAMMA)), float(spec.get("nu", NU))
    if kind == "jaxpose":
        from jaxpose.moments import volume_moments
        from jaxpose.occupancy.svdd import fit_svdd

        y = prescale(points)[0]
        base = maxrss_mb()

        fit_opts = {"max_iter": int(spec["max_iter"])} if spec.get("max_iter") else {}
        fit_opts.update(spec.get("fit") or {})  # solver, tol

        def fn():
            svdd = fit_svdd(y, gamma, nu, **fit_opts)
            mom = volume_moments(svdd, **grid_opts(spec.get("resolution"), spec.get("refine")))
            return svdd, mom
    else:
        base = maxrss_mb()
        import sklearn.svm  # noqa: F401

        def fn():
            return sklearn_pipeline(points, gamma, nu, int(spec.get("sk_resolution", 32)))

    first, res = timed(fn)
    runs = []
    for _ in range(repeats):
        t, res = timed(fn)
        runs.append(t)
    out = {"kind": kind, "m": m, **summary(first if kind == "jaxpose" else None, runs),
           "peak_rss_mb": maxrss_mb(), "baseline_rss_mb": base}
    if kind == "jaxpose":
        out["iterations"] = int(res[0].iterations)
        out["converged"] = bool(res[0].converged)
        out["kernel"] = "dense" if m <= 12_000 else "blocked"
        out["max_iter"] = spec.get("max_iter")
        out["fit"] = spec.get("fit") or {}
    else:
        out["fit_s_last"], out["grid_s_last"] = res["fit_s"], res["grid_s"]
    print(MARKER + json.dumps(out), flush=True)


if __name__ == "__main__":
    child_main(sys.argv[1])
