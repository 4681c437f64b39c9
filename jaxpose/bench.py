"""``jaxpose bench``: timings of jaxpose against the scikit-learn pipeline, on the same points.

The scikit-learn pipeline is what a user would write without jaxpose:
``OneClassSVM(kernel="rbf", gamma, nu).fit(y)``, ``decision_function`` on an N^3 grid of
cell centers over a box that provably covers the region, then the centroid and the mean
distance of the cells with ``decision_function >= 0`` (the plain indicator of eqs. 4-5).
Both sides see the same pre-scaled points y = (x - mean) / s_ref (``pose.reference_frame``),
so gamma is the dimensionless gamma of ``normalize``.

Sections (``--sections``):

solver    fit alone: ``fit_svdd`` vs ``OneClassSVM.fit``; both dual objectives a^T K a in our
          scaling (libsvm's a = dual_coef / (nu m)), evaluated in float64 numpy, and their
          relative difference (ours - libsvm) / libsvm (negative: ours is lower, i.e. better).
end2end   per object: ``normalize`` (fit + grid volume + center + scale) vs fit + grid
          indicator; the center of each, compared with a high-resolution reference
          (fit tol 1e-4, 64^3 coarse grid refined 4x per axis near the boundary, up to 65,536
          cells at the first level: boundary resolution of a 256^3 grid).
batch     many objects: ``normalize_batch`` vs a loop of ``normalize`` vs a loop of the
          scikit-learn pipeline; objects per second.
scaling   in m (one subprocess per case, so peak memory ru_maxrss is per case) and in the
          grid resolution (moments alone vs ``decision_function`` on the grid).

Every timing is a median of warm runs, jaxpose and scikit-learn runs interleaved; jaxpose's
compile time is reported separately as first call minus the warm median. No timing is ever
asserted anywhere: the machine this runs on decides the numbers.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import platform
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

__all__ = [
    "SCHEMA_VERSION",
    "SECTIONS",
    "load_points",
    "prescale",
    "sklearn_available",
    "sklearn_pipeline",
    "dual_objective",
    "bench_solver",
    "bench_end2end",
    "bench_batch",
    "bench_scaling",
    "run",
    "format_table",
    "cli",
]

SCHEMA_VERSION = 1
SECTIONS = ("solver", "end2end", "batch", "scaling")
FAUST = Path(__file__).resolve().parents[2] / "shared" / "data" / "faust-dev"
UNAVAILABLE = "unavailable"
GAMMA, NU = 47.0, 0.5


# --------------------------------------------------------------------------- inputs
def _faust_dir():
    env = os.environ.get("JAXPOSE_FAUST")
    for d in ([Path(env)] if env else []) + [FAUST, Path.cwd().parent / "shared" / "data" / "faust-dev"]:
        if (d / "tr_reg_000.ply").exists():
            return d
    return None


def _geometry(index=0):
    """(mesh, name): FAUST tr_reg_{index:03d} when present, else the built-in example shape."""
    from . import mesh

    d = _faust_dir()
    if d is not None and (d / f"tr_reg_{index:03d}.ply").exists():
        return mesh.load(d / f"tr_reg_{index:03d}.ply"), f"faust/tr_reg_{index:03d}"
    return mesh.example_shape(), "example_shape"


def load_points(m, seed=0, index=0):
    """(m, 3) float64 surface samples scaled into the unit cube, and the source's name."""
    from . import mesh

    geom, name = _geometry(index)
    p = mesh.sample_surface(geom, int(m), seed=int(seed), method="even")
    lo, hi = p.min(axis=0), p.max(axis=0)
    return (p - lo) / float(np.max(hi - lo)), name


def prescale(points):
    """y = (x - mean) / s_ref exactly as ``normalize`` does (float64 numpy); -> y, mean, size."""
    from .pose import REFERENCE_RMS

    x = np.asarray(points, np.float64)
    mean = x.mean(axis=0)
    mean = mean + (x - mean).mean(axis=0)
    size = math.sqrt(np.mean(np.sum((x - mean) ** 2, axis=1))) / REFERENCE_RMS
    return (x - mean) / size, mean, size


def sklearn_available():
    try:
        import sklearn.svm  # noqa: F401
    except ImportError:
        return False
    return True


# --------------------------------------------------------------------------- timing
def _now():
    return time.perf_counter()


def _block(x):
    import jax

    return jax.block_until_ready(x)


def _summary(first, warm):
    warm = [float(t) for t in warm]
    if not warm:  # a single cold run: compile time and run time are not separated
        return {"median_s": float(first), "runs_s": [], "first_s": float(first), "cold_only": True}
    med = statistics.median(warm)
    out = {"median_s": med, "runs_s": warm}
    if first is not None:
        out["first_s"] = float(first)
        out["compile_s"] = max(float(first) - med, 0.0)
    return out


def _interleaved(cases, repeats):
    """cases: {name: callable}. One first call each (compile / warm-up), then ``repeats``
    rounds in which every case runs once, the order rotating each round.
    Returns {name: {"first_s", "runs_s", "median_s", "compile_s"}} and {name: last result}."""
    names = list(cases)
    first, last = {}, {}
    for n in names:
        t = _now()
        last[n] = _block(cases[n]())
        first[n] = _now() - t
    runs = {n: [] for n in names}
    for r in range(int(repeats)):
        k = r % len(names)
        for n in names[k:] + names[:k]:
            t = _now()
            last[n] = _block(cases[n]())
            runs[n].append(_now() - t)
    return {n: _summary(first[n], runs[n]) for n in names}, last


def _ratio(a, b):
    if not isinstance(a, dict) or not isinstance(b, dict):
        return None
    return a["median_s"] / b["median_s"] if b["median_s"] > 0 else None


def _maxrss_mb():
    """Peak resident memory of this process in MB: VmHWM (Linux; unlike ru_maxrss it is not
    inherited from the parent across fork + exec), else ru_maxrss."""
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    kb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return kb / 1024.0 if sys.platform != "darwin" else kb / 2**20


# --------------------------------------------------------------------------- the scikit-learn pipeline
def _sk_fit(y, gamma, nu):
    from sklearn.svm import OneClassSVM

    return OneClassSVM(kernel="rbf", gamma=gamma, nu=nu).fit(y)


def _sk_alpha(oc, m, nu):
    """libsvm's solution in our scaling: a = dual_coef / (nu m), (m,) float64."""
    a = np.zeros(m)
    a[oc.support_] = oc.dual_coef_[0] / (nu * m)
    return a


def _sk_domain(oc, y, gamma, nu):
    """The box of ``grid.domain`` for libsvm's solution (mu = 2 rho / (nu m))."""
    m = y.shape[0]
    mu = max(2.0 * float(np.ravel(oc.offset_)[0]) / (nu * m), np.finfo(float).tiny)
    r = math.sqrt(max(math.log(2.0 / mu), 0.0) / gamma)
    sv = y[oc.support_]
    return sv.min(axis=0) - r, sv.max(axis=0) + r


def _grid(lo, hi, n):
    h = (hi - lo) / n
    axes = [lo[k] + h[k] * (np.arange(n) + 0.5) for k in range(3)]
    return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3), h


def sklearn_pipeline(points, gamma=GAMMA, nu=NU, resolution=32):
    """Fit + grid indicator + centroid / mean distance with scikit-learn, in the units of points.

    Returns dict(center (3,), scale, fit_s, grid_s, n_support)."""
    y, mean, size = prescale(points)
    t0 = _now()
    oc = _sk_fit(y, gamma, nu)
    t1 = _now()
    lo, hi = _sk_domain(oc, y, gamma, nu)
    x, _ = _grid(lo, hi, int(resolution))
    inside = oc.decision_function(x) >= 0
    xin = x[inside]
    if len(xin):
        c = xin.mean(axis=0)
        md = float(np.mean(np.linalg.norm(xin - c, axis=1)))
    else:
        c, md = np.full(3, np.nan), float("nan")
    t2 = _now()
    return {"center": mean + size * c, "scale": size * md, "fit_s": t1 - t0, "grid_s": t2 - t1,
            "n_support": int(len(oc.support_))}


def dual_objective(y, a, gamma, block=2048):
    """a^T K a in float64, blocked over the support of a (memory O(block * |support|))."""
    a = np.asarray(a, np.float64)
    y = np.asarray(y, np.float64)
    s = np.flatnonzero(a != 0)
    ys, as_ = y[s], a[s]
    total = 0.0
    for i in range(0, len(s), block):
        yb = ys[i:i + block]
        d2 = np.sum(yb**2, 1)[:, None] + np.sum(ys**2, 1)[None, :] - 2.0 * yb @ ys.T
        total += float(as_[i:i + block] @ (np.exp(-gamma * np.maximum(d2, 0.0)) @ as_))
    return total


def _feasibility(a, cap):
    a = np.asarray(a, np.float64)
    return {"sum_minus_1": float(a.sum() - 1.0), "min": float(a.min()), "max_over_cap": float(a.max() / cap - 1.0)}


# --------------------------------------------------------------------------- sections
def bench_solver(points, gamma=GAMMA, nu=NU, repeats=5, tol=1e-3, use_sklearn=True):
    """Fit alone, both sides, interleaved; dual objectives and their relative difference."""
    from .svdd import fit_svdd

    y, _, _ = prescale(points)
    m = y.shape[0]
    cases = {"jaxpose": lambda: fit_svdd(y, gamma, nu, tol=tol)}
    sk = use_sklearn and sklearn_available()
    if sk:
        cases["sklearn"] = lambda: _sk_fit(y, gamma, nu)
    times, last = _interleaved(cases, repeats)
    ours = last["jaxpose"]
    a = np.asarray(ours.alpha, np.float64)
    cap = 1.0 / (nu * m)
    out = {
        "m": m, "gamma": gamma, "nu": nu, "tol": tol, "dtype": str(ours.alpha.dtype),
        "jaxpose": {**times["jaxpose"], "iterations": int(ours.iterations),
                    "kkt_violation": float(ours.kkt_violation), "converged": bool(ours.converged),
                    "n_support": int(np.sum(a > 0)), "objective": dual_objective(y, a, gamma),
                    "feasibility": _feasibility(a, cap)},
    }
    if sk:
        oc = last["sklearn"]
        b = _sk_alpha(oc, m, nu)
        out["sklearn"] = {**times["sklearn"], "iterations": int(np.ravel(oc.n_iter_)[0]),
                          "n_support": int(len(oc.support_)), "objective": dual_objective(y, b, gamma),
                          "feasibility": _feasibility(b, cap)}
        o, s = out["jaxpose"]["objective"], out["sklearn"]["objective"]
        out["objective_rel_diff"] = (o - s) / s
        out["ratio"] = _ratio(out["jaxpose"], out["sklearn"])
    else:
        out["sklearn"] = UNAVAILABLE
        out["objective_rel_diff"] = out["ratio"] = None
    return out


def _reference(points, gamma, nu, resolution, refine, tol, max_iter):
    """High-resolution center/scale: tight fit, every boundary cell refined."""
    import jax.numpy as jnp

    from .moments import volume_moments
    from .svdd import fit_svdd

    y, mean, size = prescale(points)
    t = _now()
    svdd = fit_svdd(jnp.asarray(y), gamma, nu, tol=tol, max_iter=max_iter)
    mom = volume_moments(svdd, resolution=resolution, refine=refine, band=min(resolution**3, 65_536))
    center = mean + size * np.asarray(mom.center, np.float64)
    return {"center": center, "scale": size * float(mom.mean_distance), "fit_tol": tol,
            "resolution": resolution, "refine": refine, "boundary_resolution": resolution * refine,
            "converged": bool(svdd.converged), "kkt_violation": float(svdd.kkt_violation),
            "unrefined": int(mom.unrefined), "time_s": _now() - t}


def _grid_opts(resolution, refine):
    from .pose import DEFAULTS

    return {"resolution": int(resolution or DEFAULTS["resolution"]), "refine": int(refine or DEFAULTS["refine"])}


def bench_end2end(points, gamma=GAMMA, nu=NU, repeats=5, resolution=None, refine=None, sk_resolution=32,
                  ref_resolution=64, ref_refine=4, ref_tol=1e-4, ref_max_iter=20_000, use_sklearn=True):
    """normalize vs the scikit-learn pipeline, per object; centers against a reference.
    resolution / refine: None = the defaults of ``normalize``."""
    from .pose import normalize

    m = len(points)
    opts = _grid_opts(resolution, refine)
    resolution, refine = opts["resolution"], opts["refine"]
    cases = {"jaxpose": lambda: normalize(points, gamma, nu, **opts)}
    sk = use_sklearn and sklearn_available()
    if sk:
        cases["sklearn"] = lambda: sklearn_pipeline(points, gamma, nu, sk_resolution)
    times, last = _interleaved(cases, repeats)
    ref = _reference(points, gamma, nu, ref_resolution, ref_refine, ref_tol, ref_max_iter)
    pose = last["jaxpose"]
    center = np.asarray(pose.center, np.float64)
    scale = float(pose.scale)

    def accuracy(c, s):
        d = float(np.linalg.norm(np.asarray(c, np.float64) - ref["center"]))
        return {"center": [float(v) for v in c], "scale": float(s), "center_err": d,
                "center_err_rel_scale": d / ref["scale"], "scale_err_rel": abs(float(s) - ref["scale"]) / ref["scale"]}

    out = {
        "m": m, "gamma": gamma, "nu": nu,
        "jaxpose": {**times["jaxpose"], "resolution": resolution, "refine": refine,
                    "iterations": int(pose.iterations), "converged": bool(pose.converged),
                    **accuracy(center, scale)},
        "reference": {k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in ref.items()},
    }
    if sk:
        res = last["sklearn"]
        out["sklearn"] = {**times["sklearn"], "resolution": sk_resolution, "fit_s_last": res["fit_s"],
                          "grid_s_last": res["grid_s"], "n_support": res["n_support"],
                          **accuracy(res["center"], res["scale"])}
        out["ratio"] = _ratio(out["jaxpose"], out["sklearn"])
    else:
        out["sklearn"] = UNAVAILABLE
        out["ratio"] = None
    return out


def _batch_objects(n, m, seed=0):
    """n point sets of slightly different sizes (m, 0.95 m, ...): distinct FAUST meshes if present."""
    sets, names = [], []
    for i in range(n):
        mi = max(8, int(round(m * (1.0 - 0.05 * (i % 4)))))
        p, name = load_points(mi, seed=seed + i, index=i if _faust_dir() is not None else 0)
        sets.append(p)
        names.append(name)
    return sets, names


def bench_batch(n_objects=8, m=1000, gamma=GAMMA, nu=NU, repeats=3, resolution=None, refine=None, sk_resolution=32,
                use_sklearn=True):
    """Objects per second: normalize_batch vs a loop of normalize vs a loop of the sklearn pipeline."""
    from .pose import normalize, normalize_batch

    sets, names = _batch_objects(n_objects, m)
    opts = _grid_opts(resolution, refine)
    cases = {
        "jaxpose_batch": lambda: normalize_batch(sets, gamma, nu, **opts),
        "jaxpose_loop": lambda: [normalize(p, gamma, nu, **opts) for p in sets],
    }
    sk = use_sklearn and sklearn_available()
    if sk:
        cases["sklearn_loop"] = lambda: [sklearn_pipeline(p, gamma, nu, sk_resolution) for p in sets]
    times, last = _interleaved(cases, repeats)
    bc = np.asarray(last["jaxpose_batch"].center, np.float64)
    lc = np.stack([np.asarray(p.center, np.float64) for p in last["jaxpose_loop"]])
    out = {"n_objects": n_objects, "m": [len(p) for p in sets], **opts, "sources": sorted(set(names)),
           "batch_vs_loop_max_center_diff": float(np.max(np.linalg.norm(bc - lc, axis=1)))}
    for k, v in times.items():
        out[k] = {**v, "objects_per_s": n_objects / v["median_s"]}
    if not sk:
        out["sklearn_loop"] = UNAVAILABLE
    out["ratio_batch_vs_sklearn"] = _ratio(out["jaxpose_batch"], out.get("sklearn_loop"))
    out["ratio_loop_vs_sklearn"] = _ratio(out["jaxpose_loop"], out.get("sklearn_loop"))
    out["ratio_batch_vs_loop"] = _ratio(out["jaxpose_batch"], out["jaxpose_loop"])
    return out


# ---- scaling: one subprocess per case for a clean ru_maxrss
def _child_main(spec_json):
    """Run one case (called in a fresh interpreter); prints one JSON line."""
    spec = json.loads(spec_json)
    if spec.get("x64"):
        import jax

        jax.config.update("jax_enable_x64", True)
    m, kind, repeats = int(spec["m"]), spec["kind"], int(spec.get("repeats", 1))
    points, _ = load_points(m)
    gamma, nu = float(spec.get("gamma", GAMMA)), float(spec.get("nu", NU))
    if kind == "jaxpose":
        import jax

        from .moments import volume_moments
        from .svdd import fit_svdd

        y = prescale(points)[0]
        base = _maxrss_mb()

        fit_opts = {"max_iter": int(spec["max_iter"])} if spec.get("max_iter") else {}

        def once():
            svdd = fit_svdd(y, gamma, nu, **fit_opts)
            mom = volume_moments(svdd, **_grid_opts(spec.get("resolution"), spec.get("refine")))
            return svdd, mom

        fn = once
    else:
        base = _maxrss_mb()
        import sklearn.svm  # noqa: F401

        def fn():
            return sklearn_pipeline(points, gamma, nu, int(spec.get("sk_resolution", 32)))

    t = _now()
    res = _block(fn())
    first = _now() - t
    runs = []
    for _ in range(repeats):
        t = _now()
        res = _block(fn())
        runs.append(_now() - t)
    out = {"kind": kind, "m": m, **_summary(first if kind == "jaxpose" else None, runs),
           "peak_rss_mb": _maxrss_mb(), "baseline_rss_mb": base}
    if kind == "jaxpose":
        out["iterations"] = int(res[0].iterations)
        out["converged"] = bool(res[0].converged)
        out["kernel"] = "dense" if m <= 12_000 else "blocked"
        out["max_iter"] = spec.get("max_iter")
    else:
        out["fit_s_last"], out["grid_s_last"] = res["fit_s"], res["grid_s"]
    print("JAXPOSE_BENCH " + json.dumps(out), flush=True)


def _run_child(spec, timeout):
    cmd = [sys.executable, "-c", "import sys, jaxpose.bench as b; b._child_main(sys.argv[1])", json.dumps(spec)]
    env = dict(os.environ)
    env.setdefault("PYTHONWARNINGS", "ignore")
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=env)
    except subprocess.TimeoutExpired:
        return {"kind": spec["kind"], "m": spec["m"], "error": f"timed out after {timeout} s"}
    for line in proc.stdout.splitlines()[::-1]:
        if line.startswith("JAXPOSE_BENCH "):
            return json.loads(line[len("JAXPOSE_BENCH "):])
    tail = " ".join((proc.stderr or "").strip().splitlines()[-3:])
    return {"kind": spec["kind"], "m": spec["m"], "error": f"exit {proc.returncode}: {tail}"}


def bench_scaling(ms=(1000, 2000, 4000, 8000, 16000), resolutions=(32, 64, 128), m_grid=2000, gamma=GAMMA, nu=NU,
                  repeats=1, sk_max_m=8000, sk_max_grid_points=32_768, use_sklearn=True, timeout=1800, x64=False,
                  resolution=32, warm_max_m=12_000, max_iter=None):
    """max_iter: cap the solver (memory only depends on shapes, so a capped run measures peak memory
    of large m in a fraction of the time; timings are then per capped run and marked)."""
    """Scaling in m (fit + moments per subprocess, with peak RSS) and in grid resolution."""
    from .moments import volume_moments
    from .svdd import fit_svdd

    sk = use_sklearn and sklearn_available()
    in_m = []
    for m in ms:
        # beyond the dense limit one fit takes minutes: one cold run only (compile not separated)
        spec = {"m": int(m), "repeats": repeats if m <= warm_max_m else 0, "max_iter": max_iter, "gamma": gamma, "nu": nu, "resolution": resolution,
                "sk_resolution": resolution}
        row = {"m": int(m), "jaxpose": _run_child({**spec, "kind": "jaxpose", "x64": x64}, timeout)}
        if not sk:
            row["sklearn"] = UNAVAILABLE
        elif m > sk_max_m:
            row["sklearn"] = f"skipped: m > {sk_max_m} (fit is superquadratic and the grid is single-threaded)"
        else:
            row["sklearn"] = _run_child({**spec, "kind": "sklearn"}, timeout)
        row["ratio"] = _ratio(row["jaxpose"] if "median_s" in row["jaxpose"] else None,
                              row["sklearn"] if isinstance(row["sklearn"], dict) and "median_s" in row["sklearn"] else None)
        in_m.append(row)

    # in grid resolution: moments alone (refine=1, plain grid) vs decision_function on the grid
    points, _ = load_points(m_grid)
    y = prescale(points)[0]
    svdd = _block(fit_svdd(y, gamma, nu))
    oc = _sk_fit(y, gamma, nu) if sk else None
    in_res = []
    for r in resolutions:
        cases = {"jaxpose": lambda r=r: volume_moments(svdd, resolution=int(r), refine=1)}
        extrapolated = False
        if sk:
            lo, hi = _sk_domain(oc, y, gamma, nu)
            x, _ = _grid(lo, hi, int(r))
            n = x.shape[0]
            if n > sk_max_grid_points:  # decision_function is linear in the number of points
                extrapolated = True
                x = x[np.random.default_rng(0).choice(n, sk_max_grid_points, replace=False)]
            cases["sklearn"] = lambda x=x: oc.decision_function(x)
        times, _ = _interleaved(cases, repeats)
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
            row["ratio"] = _ratio(row["jaxpose"], s)
        else:
            row["sklearn"], row["ratio"] = UNAVAILABLE, None
        in_res.append(row)
    return {"in_m": in_m, "in_m_resolution": resolution, "in_resolution": {"m": m_grid, "refine": 1, "rows": in_res},
            "sklearn_max_m": sk_max_m}


# --------------------------------------------------------------------------- driver
QUICK = dict(m=300, repeats=2, batch_objects=3, batch_m=200, scaling_m=(200,), resolutions=(16,),
             ref_resolution=32, ref_refine=2, sk_resolution=16, resolution=16, refine=2)
FULL = dict(m=2000, repeats=5, batch_objects=8, batch_m=1000, scaling_m=(1000, 2000, 4000, 8000, 16000),
            resolutions=(32, 64, 128), ref_resolution=64, ref_refine=4, sk_resolution=32, resolution=None, refine=None)


def _environment():
    import jax

    env = {"python": platform.python_version(), "jax": jax.__version__, "backend": jax.default_backend(),
           "devices": [str(d) for d in jax.devices()], "x64": bool(jax.config.jax_enable_x64),
           "cpu_count": os.cpu_count(), "platform": platform.platform()}
    try:
        import sklearn

        env["sklearn"] = sklearn.__version__
    except ImportError:
        env["sklearn"] = UNAVAILABLE
    return env


def run(sections=SECTIONS, quick=False, m=None, repeats=None, scaling_m=None, resolutions=None, tol=1e-3,
        sk_max_m=8000, use_sklearn=True, x64=False, progress=None, scaling_max_iter=None):
    """Run the chosen sections; returns the JSON-ready result dict."""
    cfg = dict(QUICK if quick else FULL)
    if m is not None:
        cfg["m"] = int(m)
    if repeats is not None:
        cfg["repeats"] = int(repeats)
    if scaling_m is not None:
        cfg["scaling_m"] = tuple(int(v) for v in scaling_m)
    if resolutions is not None:
        cfg["resolutions"] = tuple(int(v) for v in resolutions)
    unknown = set(sections) - set(SECTIONS)
    if unknown:
        raise ValueError(f"unknown sections {sorted(unknown)}; valid: {', '.join(SECTIONS)}")
    say = progress or (lambda s: None)
    points, source = load_points(cfg["m"])
    result = {"schema_version": SCHEMA_VERSION, "quick": bool(quick), "source": source, "gamma": GAMMA, "nu": NU,
              "repeats": cfg["repeats"], "environment": _environment(),
              "sklearn": ("available" if sklearn_available() else UNAVAILABLE) if use_sklearn else "disabled",
              "sections": {}}
    sk = use_sklearn
    if "solver" in sections:
        say(f"solver (m={cfg['m']})")
        result["sections"]["solver"] = bench_solver(points, repeats=cfg["repeats"], tol=tol, use_sklearn=sk)
    if "end2end" in sections:
        say(f"end2end (m={cfg['m']})")
        result["sections"]["end2end"] = bench_end2end(
            points, repeats=cfg["repeats"], resolution=cfg["resolution"], refine=cfg["refine"], sk_resolution=cfg["sk_resolution"],
            ref_resolution=cfg["ref_resolution"], ref_refine=cfg["ref_refine"], use_sklearn=sk)
    if "batch" in sections:
        say(f"batch ({cfg['batch_objects']} objects, m<={cfg['batch_m']})")
        result["sections"]["batch"] = bench_batch(cfg["batch_objects"], cfg["batch_m"], repeats=cfg["repeats"],
                                                  resolution=cfg["resolution"], refine=cfg["refine"],
                                                  sk_resolution=cfg["sk_resolution"],
                                                  use_sklearn=sk)
    if "scaling" in sections:
        say(f"scaling (m in {cfg['scaling_m']}, resolution in {cfg['resolutions']})")
        result["sections"]["scaling"] = bench_scaling(
            cfg["scaling_m"], cfg["resolutions"], m_grid=min(cfg["m"], 2000), repeats=max(1, min(cfg["repeats"], 2)),
            sk_max_m=sk_max_m, use_sklearn=sk, x64=x64, resolution=cfg["resolution"] or 32,
            max_iter=scaling_max_iter)
    return result


# --------------------------------------------------------------------------- table
def _t(x):
    if not isinstance(x, dict) or "median_s" not in x:
        return "n/a" if not isinstance(x, str) else ("n/a" if x == UNAVAILABLE else "skipped")
    return f"{x['median_s']:.4g} s"


def _r(x):
    return "n/a" if x is None else f"{x:.3g}x"


def _c(x):
    if isinstance(x, dict) and x.get("cold_only"):
        return "incl."
    return f"{x['compile_s']:.3g} s" if isinstance(x, dict) and "compile_s" in x else "-"


def format_table(result):
    lines = [f"jaxpose bench  source={result['source']}  gamma={result['gamma']:g} nu={result['nu']:g}  "
             f"repeats={result['repeats']}  backend={result['environment']['backend']}  sklearn={result['sklearn']}",
             "ratio = jaxpose / sklearn (median of warm runs; < 1 means jaxpose is faster)"]
    s = result["sections"]
    if "solver" in s:
        r = s["solver"]
        j, k = r["jaxpose"], r["sklearn"]
        lines += ["", f"[solver]  m={r['m']}  tol={r['tol']:g}  dtype={r['dtype']}",
                  f"  jaxpose fit   {_t(j):>12}  compile {_c(j)}  iterations {j['iterations']}  "
                  f"kkt {j['kkt_violation']:.2g}  objective {j['objective']:.10g}"]
        if isinstance(k, dict):
            lines.append(f"  sklearn fit   {_t(k):>12}  iterations {k['iterations']}  objective {k['objective']:.10g}")
            lines.append(f"  ratio {_r(r['ratio'])}   objective (ours - libsvm) / libsvm = {r['objective_rel_diff']:.3g}")
        else:
            lines.append("  sklearn       unavailable")
    if "end2end" in s:
        r = s["end2end"]
        j, k, ref = r["jaxpose"], r["sklearn"], r["reference"]
        lines += ["", f"[end2end]  m={r['m']}  reference: fit tol {ref['fit_tol']:g}, {ref['resolution']}^3 refined "
                      f"{ref['refine']}^3 on the boundary (= {ref['boundary_resolution']}^3)",
                  f"  jaxpose normalize  {_t(j):>12}  compile {_c(j)}  grid {j['resolution']}^3 x refine "
                  f"{j['refine']}  center err {j['center_err']:.2e} ({j['center_err_rel_scale']:.2e} of scale)"]
        if isinstance(k, dict):
            lines.append(f"  sklearn pipeline   {_t(k):>12}  grid {k['resolution']}^3 indicator  (fit {k['fit_s_last']:.3g} s"
                         f" + grid {k['grid_s_last']:.3g} s)  center err {k['center_err']:.2e} "
                         f"({k['center_err_rel_scale']:.2e} of scale)")
            lines.append(f"  ratio {_r(r['ratio'])}")
        else:
            lines.append("  sklearn            unavailable")
    if "batch" in s:
        r = s["batch"]
        lines += ["", f"[batch]  {r['n_objects']} objects, m = {min(r['m'])}..{max(r['m'])}"]
        for name in ("jaxpose_batch", "jaxpose_loop", "sklearn_loop"):
            v = r.get(name)
            if isinstance(v, dict):
                lines.append(f"  {name:<14} {_t(v):>12}  {v['objects_per_s']:.3g} objects/s  compile {_c(v)}")
            else:
                lines.append(f"  {name:<14} unavailable")
        lines.append(f"  ratios: batch/sklearn {_r(r['ratio_batch_vs_sklearn'])}  loop/sklearn "
                     f"{_r(r['ratio_loop_vs_sklearn'])}  batch/loop {_r(r['ratio_batch_vs_loop'])}  "
                     f"max |center batch - loop| {r['batch_vs_loop_max_center_diff']:.2e}")
    if "scaling" in s:
        r = s["scaling"]
        n = r.get("in_m_resolution", 32)
        lines += ["", f"[scaling in m]  fit + moments ({n}^3, default refine) vs sklearn fit + {n}^3 indicator; "
                      "one process per case, peak = VmHWM",
                  f"  {'m':>6} {'jaxpose':>12} {'compile':>9} {'iters':>6} {'peak MB':>8} {'sklearn':>12} {'peak MB':>8} {'ratio':>8}"]
        for row in r["in_m"]:
            j, k = row["jaxpose"], row["sklearn"]
            jm = f"{j['peak_rss_mb']:.0f}" if "peak_rss_mb" in j else j.get("error", "?")[:30]
            km = f"{k['peak_rss_mb']:.0f}" if isinstance(k, dict) and "peak_rss_mb" in k else "-"
            lines.append(f"  {row['m']:>6} {_t(j):>12} {_c(j):>9} {j.get('iterations', '-')!s:>6} {jm:>8} "
                         f"{_t(k):>12} {km:>8} {_r(row['ratio']):>8}")
        if any(isinstance(row["jaxpose"], dict) and row["jaxpose"].get("max_iter") for row in r["in_m"]):
            lines.append("  (solver capped by --scaling-max-iter: times are per capped run; peak memory is unaffected)")
        skipped = [row["m"] for row in r["in_m"] if isinstance(row["sklearn"], str) and row["sklearn"].startswith("skipped")]
        if skipped:
            lines.append(f"  sklearn skipped for m > {r['sklearn_max_m']}: {skipped}")
        g = r["in_resolution"]
        lines += [f"[scaling in resolution]  m={g['m']}, moments on a plain grid (refine 1) vs decision_function",
                  f"  {'N':>5} {'points':>9} {'jaxpose':>12} {'sklearn':>12} {'ratio':>8}"]
        for row in g["rows"]:
            k = row["sklearn"]
            ext = " (extrapolated)" if isinstance(k, dict) and "extrapolated_from_points" in k else ""
            lines.append(f"  {row['resolution']:>5} {row['grid_points']:>9} {_t(row['jaxpose']):>12} {_t(k):>12} "
                         f"{_r(row['ratio']):>8}{ext}")
    return "\n".join(lines)


# --------------------------------------------------------------------------- command line
def _parser():
    p = argparse.ArgumentParser(prog="jaxpose bench", description="timings of jaxpose against scikit-learn")
    p.add_argument("--quick", action="store_true", help="small sizes, 2 repeats (well under a minute)")
    p.add_argument("--json", help="write the full result as JSON here")
    p.add_argument("--m", type=int, default=None, help="points per object for solver / end2end (default 2000)")
    p.add_argument("--repeats", type=int, default=None, help="warm runs per case (default 5; quick 2)")
    p.add_argument("--sections", default=",".join(SECTIONS), help=f"comma list of {','.join(SECTIONS)}")
    p.add_argument("--scaling-m", default=None, help="comma list of m for the scaling section (default 1000..16000)")
    p.add_argument("--resolutions", default=None, help="comma list of grid resolutions (default 32,64,128)")
    p.add_argument("--sklearn-max-m", type=int, default=8000, help="largest m the sklearn side runs in scaling")
    p.add_argument("--tol", type=float, default=1e-3, help="solver tolerance in the solver section (default 1e-3)")
    p.add_argument("--scaling-max-iter", type=int, default=None,
                   help="cap solver iterations in scaling (peak memory of large m without the full run time)")
    p.add_argument("--no-sklearn", action="store_true", help="time jaxpose only")
    p.add_argument("--x64", action="store_true", help="enable float64 in JAX (default float32)")
    p.add_argument("--force", action="store_true", help="overwrite an existing --json file")
    return p


def _ints(text):
    return [int(v) for v in text.split(",") if v.strip()] if text else None


def cli(argv=None) -> int:
    """``jaxpose bench [--quick] [--json PATH] [--m M] [--repeats N] [--sections ...]``."""
    p = _parser()
    try:
        args = p.parse_args(argv)
    except SystemExit as exc:
        return int(exc.code or 0)
    sections = [s.strip() for s in args.sections.split(",") if s.strip()]
    bad = [s for s in sections if s not in SECTIONS]
    if bad or not sections:
        print(f"jaxpose bench: error: unknown sections {bad}; valid: {','.join(SECTIONS)}", file=sys.stderr)
        return 2
    if args.json and Path(args.json).exists() and not args.force:
        print(f"jaxpose bench: error: {args.json} exists (use --force to overwrite)", file=sys.stderr)
        return 1
    if args.m is not None and args.m < 8:
        print("jaxpose bench: error: --m must be >= 8", file=sys.stderr)
        return 2
    if args.x64:
        import jax

        jax.config.update("jax_enable_x64", True)
    result = run(sections, quick=args.quick, m=args.m, repeats=args.repeats, scaling_m=_ints(args.scaling_m),
                 resolutions=_ints(args.resolutions), tol=args.tol, sk_max_m=args.sklearn_max_m,
                 use_sklearn=not args.no_sklearn, x64=args.x64, scaling_max_iter=args.scaling_max_iter,
                 progress=lambda s: print(f"jaxpose bench: {s}", file=sys.stderr, flush=True))
    print(format_table(result))
    if args.json:
        from .mesh import write_atomic

        write_atomic(args.json, json.dumps(result, indent=2, default=_jsonable) + "\n", force=args.force)
        print(f"wrote {args.json}")
    return 0


def _jsonable(x):
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, (np.floating, np.integer, np.bool_)):
        return x.item()
    raise TypeError(f"not JSON serializable: {type(x).__name__}")


if __name__ == "__main__":
    raise SystemExit(cli(sys.argv[1:]))
