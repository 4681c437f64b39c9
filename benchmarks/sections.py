"""The per-object and many-object sections of ``jaxpose bench``: solver, end2end, batch, accuracy."""
from __future__ import annotations

import numpy as np

from . import common
from .common import GAMMA, NU, UNAVAILABLE, faust_dir, grid_opts, interleaved, now, ratio, load_points, prescale
from .sklearn_pipeline import feasibility, sk_alpha, sk_fit, dual_objective, sklearn_pipeline


def bench_solver(points, gamma=GAMMA, nu=NU, repeats=5, tol=1e-3, use_sklearn=True):
    """Fit alone, both sides, interleaved; dual objectives and their relative difference."""
    from jaxpose.occupancy.svdd import fit_svdd

    y, _, _ = prescale(points)
    m = y.shape[0]
    cases = {"jaxpose": lambda: fit_svdd(y, gamma, nu, tol=tol, solver="pg"),  # the default up to 2500 points
             "jaxpose_auto": lambda: fit_svdd(y, gamma, nu, tol=tol, solver="auto")}  # SMO (then PG if needed)
    sk = use_sklearn and common.sklearn_available()
    if sk:
        cases["sklearn"] = lambda: sk_fit(y, gamma, nu)
    times, last = interleaved(cases, repeats)
    ours = last["jaxpose"]
    a = np.asarray(ours.alpha, np.float64)
    cap = 1.0 / (nu * m)
    out = {
        "m": m, "gamma": gamma, "nu": nu, "tol": tol, "dtype": str(ours.alpha.dtype),
        "jaxpose": {**times["jaxpose"], "iterations": int(ours.iterations),
                    "kkt_violation": float(ours.kkt_violation), "converged": bool(ours.converged),
                    "n_support": int(np.sum(a > 0)), "objective": dual_objective(y, a, gamma),
                    "feasibility": feasibility(a, cap)},
    }
    pg = last["jaxpose_auto"]
    out["jaxpose_auto"] = {**times["jaxpose_auto"], "iterations": int(pg.iterations),
                         "kkt_violation": float(pg.kkt_violation), "converged": bool(pg.converged),
                         "objective": dual_objective(y, np.asarray(pg.alpha, np.float64), gamma)}
    if sk:
        oc = last["sklearn"]
        b = sk_alpha(oc, m, nu)
        out["sklearn"] = {**times["sklearn"], "iterations": int(np.ravel(oc.n_iter_)[0]),
                          "n_support": int(len(oc.support_)), "objective": dual_objective(y, b, gamma),
                          "feasibility": feasibility(b, cap)}
        o, s = out["jaxpose"]["objective"], out["sklearn"]["objective"]
        out["objective_rel_diff"] = (o - s) / s
        out["ratio"] = ratio(out["jaxpose"], out["sklearn"])
        out["ratio_auto"] = ratio(out["jaxpose_auto"], out["sklearn"])
        out["objective_rel_diff_auto"] = (out["jaxpose_auto"]["objective"] - s) / s
    else:
        out["sklearn"] = UNAVAILABLE
        out["objective_rel_diff"] = out["ratio"] = out["ratio_auto"] = out["objective_rel_diff_auto"] = None
    return out


def _reference(points, gamma, nu, resolution, refine, tol, max_iter):
    """High-resolution center/scale: tight fit, every boundary cell refined."""
    import jax.numpy as jnp

    from jaxpose.moments import volume_moments
    from jaxpose.occupancy.svdd import fit_svdd

    y, mean, size = prescale(points)
    t = now()
    svdd = fit_svdd(jnp.asarray(y), gamma, nu, tol=tol, max_iter=max_iter)
    mom = volume_moments(svdd, resolution=resolution, refine=refine, band=min(resolution**3, 65_536))
    center = mean + size * np.asarray(mom.center, np.float64)
    return {"center": center, "scale": size * float(mom.mean_distance), "fit_tol": tol,
            "resolution": resolution, "refine": refine, "boundary_resolution": resolution * refine,
            "converged": bool(svdd.converged), "kkt_violation": float(svdd.kkt_violation),
            "unrefined": int(mom.unrefined), "time_s": now() - t}


def _accuracy(center, scale, ref):
    """Center and scale errors against the reference ``ref`` (a ``_reference`` result)."""
    d = float(np.linalg.norm(np.asarray(center, np.float64) - ref["center"]))
    return {"center": [float(v) for v in center], "scale": float(scale), "center_err": d,
            "center_err_rel_scale": d / ref["scale"], "scale_err_rel": abs(float(scale) - ref["scale"]) / ref["scale"]}


def bench_end2end(points, gamma=GAMMA, nu=NU, repeats=5, resolution=None, refine=None, sk_resolution=64,
                  ref_resolution=64, ref_refine=4, ref_tol=1e-4, ref_max_iter=20_000, use_sklearn=True, fit=None):
    """normalize vs the scikit-learn pipeline, per object; centers against a reference.
    resolution / refine: None = the defaults of ``normalize``."""
    from jaxpose.pose.pose import normalize
    from jaxpose.occupancy.svdd import pick_solver

    m = len(points)
    opts = grid_opts(resolution, refine)
    resolution, refine = opts["resolution"], opts["refine"]
    opts = {**opts, **(fit or {})}  # solver options of the jaxpose side
    cases = {"jaxpose": lambda: normalize(points, method="ocsvm", gamma=gamma, nu=nu, **opts)}
    sk = use_sklearn and common.sklearn_available()
    if sk:
        cases["sklearn"] = lambda: sklearn_pipeline(points, gamma, nu, sk_resolution)
    times, last = interleaved(cases, repeats)
    ref = _reference(points, gamma, nu, ref_resolution, ref_refine, ref_tol, ref_max_iter)
    pose = last["jaxpose"]
    center = np.asarray(pose.center, np.float64)
    scale = float(pose.scale)
    out = {
        "m": m, "gamma": gamma, "nu": nu,
        "jaxpose": {**times["jaxpose"], "resolution": resolution, "refine": refine,
                    "fit": {**(fit or {}), "solver": pick_solver((fit or {}).get("solver"), m)},  # None -> by size
                    "iterations": int(pose.iterations), "converged": bool(pose.converged),
                    **_accuracy(center, scale, ref)},
        "reference": {k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in ref.items()},
    }
    if sk:
        res = last["sklearn"]
        out["sklearn"] = {**times["sklearn"], "resolution": sk_resolution, "fit_s_last": res["fit_s"],
                          "grid_s_last": res["grid_s"], "n_support": res["n_support"],
                          **_accuracy(res["center"], res["scale"], ref)}
        out["ratio"] = ratio(out["jaxpose"], out["sklearn"])
    else:
        out["sklearn"] = UNAVAILABLE
        out["ratio"] = None
    return out


def _batch_objects(n, m, seed=0):
    """n point sets of slightly different sizes (m, 0.95 m, ...): distinct FAUST meshes if present."""
    sets, names = [], []
    for i in range(n):
        mi = max(8, int(round(m * (1.0 - 0.05 * (i % 4)))))
        p, name = load_points(mi, seed=seed + i, index=i if faust_dir() is not None else 0)
        sets.append(p)
        names.append(name)
    return sets, names


def bench_batch(n_objects=8, m=1000, gamma=GAMMA, nu=NU, repeats=3, resolution=None, refine=None, sk_resolution=64,
                use_sklearn=True, fit=None):
    """Objects per second: normalize_batch vs a loop of normalize vs a loop of the sklearn pipeline."""
    from jaxpose.pose.pose import normalize, normalize_batch

    sets, names = _batch_objects(n_objects, m)
    opts = {**grid_opts(resolution, refine), **(fit or {})}
    cases = {
        "jaxpose_batch": lambda: normalize_batch(sets, method="ocsvm", gamma=gamma, nu=nu, **opts),
        "jaxpose_loop": lambda: [normalize(p, method="ocsvm", gamma=gamma, nu=nu, **opts) for p in sets],
    }
    sk = use_sklearn and common.sklearn_available()
    if sk:
        cases["sklearn_loop"] = lambda: [sklearn_pipeline(p, gamma, nu, sk_resolution) for p in sets]
    times, last = interleaved(cases, repeats)
    bc = np.asarray(last["jaxpose_batch"].center, np.float64)
    lc = np.stack([np.asarray(p.center, np.float64) for p in last["jaxpose_loop"]])
    out = {"n_objects": n_objects, "m": [len(p) for p in sets], **opts, "sources": sorted(set(names)),
           "batch_vs_loop_max_center_diff": float(np.max(np.linalg.norm(bc - lc, axis=1)))}
    for k, v in times.items():
        out[k] = {**v, "objects_per_s": n_objects / v["median_s"]}
    if not sk:
        out["sklearn_loop"] = UNAVAILABLE
    out["ratio_batch_vs_sklearn"] = ratio(out["jaxpose_batch"], out.get("sklearn_loop"))
    out["ratio_loop_vs_sklearn"] = ratio(out["jaxpose_loop"], out.get("sklearn_loop"))
    out["ratio_batch_vs_loop"] = ratio(out["jaxpose_batch"], out["jaxpose_loop"])
    return out


ACCURACY_BAR = 1e-3  # the center within 1e-3 of the reference (units of the unit-cube points)


def bench_accuracy(n_objects=20, m=2000, gamma=GAMMA, nu=NU, resolution=None, refine=None, sk_resolutions=(32, 48, 64),
                   ref_resolution=64, ref_refine=4, ref_tol=1e-4, ref_max_iter=20_000, use_sklearn=True, fit=None):
    """Center and scale errors over many objects (no timings): ``normalize`` and the scikit-learn
    pipeline at each grid of sk_resolutions, against ``_reference``; median, max and how many centers
    are within ``ACCURACY_BAR``. Objects: FAUST tr_reg_000.. when present, else samplings of the example shape
    with seeds 0.. . Answers which scikit-learn grid is as accurate as ``normalize`` (one mesh can
    mislead: the indicator's error jumps with the grid's offset). An object whose scikit-learn region holds
    no point of a grid (too coarse) has null errors there and is counted in that grid's ``empty``."""
    from jaxpose.pose.pose import normalize

    faust = faust_dir() is not None
    grid = grid_opts(resolution, refine)
    sk = use_sklearn and common.sklearn_available()
    sk_resolutions = tuple(int(r) for r in sk_resolutions) if sk else ()
    names, rows = [], []
    for i in range(int(n_objects)):
        points, name = load_points(m, seed=0 if faust else i, index=i if faust else 0)
        names.append(name if faust else f"{name}/seed{i}")
        ref = _reference(points, gamma, nu, ref_resolution, ref_refine, ref_tol, ref_max_iter)
        pose = normalize(points, method="ocsvm", gamma=gamma, nu=nu, **grid, **(fit or {}))  # as in end2end
        row = {"jaxpose": _accuracy(np.asarray(pose.center, np.float64), float(pose.scale), ref)}
        for r in sk_resolutions:
            res = sklearn_pipeline(points, gamma, nu, r)
            row[r] = _accuracy(res["center"], res["scale"], ref)
        rows.append(row)

    def stats(k):
        # an object whose region holds no grid point (a grid too coarse for the scikit-learn
        # indicator: no center) is counted as ``empty``, its errors null; the summary is over the others
        v = np.array([row[k]["center_err"] for row in rows], np.float64)
        sc = np.array([row[k]["scale_err_rel"] for row in rows], np.float64)
        ok = np.isfinite(v) & np.isfinite(sc)
        summary = lambda f, x: float(f(x[ok])) if ok.any() else None
        return {"center_err": [float(e) if good else None for e, good in zip(v, ok)],
                "median": summary(np.median, v), "max": summary(np.max, v),
                "within_bar": int(np.sum(v[ok] <= ACCURACY_BAR)), "empty": int(np.sum(~ok)),
                "scale_err_rel": [float(e) if good else None for e, good in zip(sc, ok)],
                "scale_median": summary(np.median, sc), "scale_max": summary(np.max, sc)}

    return {"n_objects": int(n_objects), "m": int(m), "bar": ACCURACY_BAR, "objects": names, **grid,
            "fit": {k: v for k, v in (fit or {}).items() if v is not None},
            "reference": {"resolution": ref_resolution, "refine": ref_refine, "fit_tol": ref_tol},
            "jaxpose": stats("jaxpose"),
            "sklearn": {str(r): stats(r) for r in sk_resolutions} if sk else UNAVAILABLE}
