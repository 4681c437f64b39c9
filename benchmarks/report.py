"""Driver, table and command line of ``jaxpose bench``: ``run``, ``format_table``, ``cli``."""
from __future__ import annotations

import argparse
import json
import os
import platform
import sys
from pathlib import Path

import numpy as np

from . import common
from .common import GAMMA, NU, UNAVAILABLE, load_points
from .scaling import bench_scaling
from .sections import bench_accuracy, bench_batch, bench_end2end, bench_solver


def fail(message, code=1) -> int:
    """``jaxpose bench``'s error: one line on stderr, as every jaxpose command writes it
    (``jaxpose.cli.common.fail``'s format; not imported: the command line runs this package, not the
    other way round). Returns ``code``."""
    print(f"jaxpose: error: {' '.join(str(message).split()) or 'failed'}", file=sys.stderr)
    return code


SCHEMA_VERSION = 1
SECTIONS = ("solver", "end2end", "batch", "scaling", "accuracy")

QUICK = dict(m=300, repeats=2, batch_objects=3, batch_m=200, scaling_m=(200,), resolutions=(16,),
             ref_resolution=32, ref_refine=2, sk_resolution=16, resolution=16, refine=2, accuracy_objects=2,
             accuracy_sk_resolutions=(16,))
FULL = dict(m=2000, repeats=5, batch_objects=8, batch_m=1000, scaling_m=(1000, 2000, 4000, 8000, 16000),
            resolutions=(32, 64, 128), ref_resolution=64, ref_refine=4, sk_resolution=64, resolution=None, refine=None,
            accuracy_objects=20, accuracy_sk_resolutions=(32, 48, 64))


# --------------------------------------------------------------------------- driver
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
        sk_max_m=8000, use_sklearn=True, x64=False, progress=None, scaling_max_iter=None, solver=None,
        solver_tol=None, refine=None, sk_resolution=None, objects=None, resolution=None):
    """Run the chosen sections; returns the JSON-ready result dict.

    solver, solver_tol: jaxpose's solver options in end2end, batch and scaling (the solver
    section always times both solvers at ``tol``); solver_tol None: normalize's default.
    resolution, refine: normalize's grid in end2end, batch and accuracy (None: its defaults); resolution
    is also the m-scaling's grid (None there: 32).
    sk_resolution: the scikit-learn pipeline's grid in end2end and batch (None: 64^3, the coarsest whose center is within 1e-3 on most FAUST meshes: 18 of 20, against 10
    at 48^3 and 5 at 32^3; the ``accuracy`` section measures it).
    objects: how many objects the accuracy section takes (None: 20; quick 2)."""
    cfg = dict(QUICK if quick else FULL)
    if m is not None:
        cfg["m"] = int(m)
    if repeats is not None:
        cfg["repeats"] = int(repeats)
    if scaling_m is not None:
        cfg["scaling_m"] = tuple(int(v) for v in scaling_m)
    if resolutions is not None:
        cfg["resolutions"] = tuple(int(v) for v in resolutions)
    if refine is not None:
        cfg["refine"] = int(refine)
    if resolution is not None:
        cfg["resolution"] = int(resolution)
    if sk_resolution is not None:
        cfg["sk_resolution"] = int(sk_resolution)
    if objects is not None:
        cfg["accuracy_objects"] = int(objects)
    unknown = set(sections) - set(SECTIONS)
    if unknown:
        raise ValueError(f"unknown sections {sorted(unknown)}; valid: {', '.join(SECTIONS)}")
    say = progress or (lambda s: None)
    points, source = load_points(cfg["m"])
    result = {"schema_version": SCHEMA_VERSION, "quick": bool(quick), "source": source, "gamma": GAMMA, "nu": NU,
              "repeats": cfg["repeats"], "environment": _environment(), "solver": solver, "solver_tol": solver_tol,
              "sklearn": ("available" if common.sklearn_available() else UNAVAILABLE) if use_sklearn else "disabled",
              "sections": {}}
    sk = use_sklearn
    fit = {"solver": solver, **({"tol": float(solver_tol)} if solver_tol is not None else {})}
    if "solver" in sections:
        say(f"solver (m={cfg['m']})")
        result["sections"]["solver"] = bench_solver(points, repeats=cfg["repeats"], tol=tol, use_sklearn=sk)
    if "end2end" in sections:
        say(f"end2end (m={cfg['m']})")
        result["sections"]["end2end"] = bench_end2end(
            points, repeats=cfg["repeats"], resolution=cfg["resolution"], refine=cfg["refine"], sk_resolution=cfg["sk_resolution"],
            ref_resolution=cfg["ref_resolution"], ref_refine=cfg["ref_refine"], use_sklearn=sk, fit=fit)
    if "batch" in sections:
        say(f"batch ({cfg['batch_objects']} objects, m<={cfg['batch_m']})")
        result["sections"]["batch"] = bench_batch(cfg["batch_objects"], cfg["batch_m"], repeats=cfg["repeats"],
                                                  resolution=cfg["resolution"], refine=cfg["refine"],
                                                  sk_resolution=cfg["sk_resolution"],
                                                  use_sklearn=sk, fit=fit)
    if "scaling" in sections:
        say(f"scaling (m in {cfg['scaling_m']}, resolution in {cfg['resolutions']})")
        result["sections"]["scaling"] = bench_scaling(
            cfg["scaling_m"], cfg["resolutions"], m_grid=min(cfg["m"], 2000), repeats=max(1, min(cfg["repeats"], 2)),
            sk_max_m=sk_max_m, use_sklearn=sk, x64=x64, resolution=cfg["resolution"] or 32,
            max_iter=scaling_max_iter, fit=fit)
    if "accuracy" in sections:
        say(f"accuracy ({cfg['accuracy_objects']} objects, m={cfg['m']})")
        result["sections"]["accuracy"] = bench_accuracy(
            cfg["accuracy_objects"], cfg["m"], resolution=cfg["resolution"], refine=cfg["refine"],
            sk_resolutions=cfg["accuracy_sk_resolutions"], ref_resolution=cfg["ref_resolution"],
            ref_refine=cfg["ref_refine"], use_sklearn=sk, fit=fit)
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


def _solver_lines(r):
    j, k = r["jaxpose"], r["sklearn"]
    lines = ["", f"[solver]  m={r['m']}  tol={r['tol']:g}  dtype={r['dtype']}",
             f"  jaxpose pg    {_t(j):>12}  compile {_c(j)}  iterations {j['iterations']}  "
             f"kkt {j['kkt_violation']:.2g}  objective {j['objective']:.10g}"]
    au = r.get("jaxpose_auto")
    if isinstance(au, dict):
        lines.append(f"  jaxpose auto  {_t(au):>12}  compile {_c(au)}  iterations {au['iterations']}  "
                     f"kkt {au['kkt_violation']:.2g}  objective {au['objective']:.10g}  (solver='auto': SMO)")
    if isinstance(k, dict):
        lines.append(f"  sklearn fit   {_t(k):>12}  iterations {k['iterations']}  objective {k['objective']:.10g}")
        lines.append(f"  ratio {_r(r['ratio'])}   objective (ours - libsvm) / libsvm = {r['objective_rel_diff']:.3g}")
        if r.get("ratio_auto") is not None:
            lines.append(f"  ratio auto {_r(r['ratio_auto'])}   objective (auto - libsvm) / libsvm = "
                         f"{r['objective_rel_diff_auto']:.3g}")
    else:
        lines.append("  sklearn       unavailable")
    return lines


def _fit(j):
    f = j.get("fit") or {}
    return "".join(f"{k} {v}  " for k, v in sorted(f.items()) if v is not None)


def _end2end_lines(r):
    j, k, ref = r["jaxpose"], r["sklearn"], r["reference"]
    lines = ["", f"[end2end]  m={r['m']}  reference: fit tol {ref['fit_tol']:g}, {ref['resolution']}^3 refined "
                 f"{ref['refine']}^3 on the boundary (= {ref['boundary_resolution']}^3, extrapolated)",
             f"  jaxpose normalize  {_t(j):>12}  compile {_c(j)}  {_fit(j)}grid {j['resolution']}^3 x refine "
             f"{j['refine']}  center err {j['center_err']:.2e} ({j['center_err_rel_scale']:.2e} of scale)"]
    if isinstance(k, dict):
        lines.append(f"  sklearn pipeline   {_t(k):>12}  grid {k['resolution']}^3 indicator  (fit {k['fit_s_last']:.3g} s"
                     f" + grid {k['grid_s_last']:.3g} s)  center err {k['center_err']:.2e} "
                     f"({k['center_err_rel_scale']:.2e} of scale)")
        lines.append(f"  ratio {_r(r['ratio'])}")
    else:
        lines.append("  sklearn            unavailable")
    return lines


def _batch_lines(r):
    lines = ["", f"[batch]  {r['n_objects']} objects, m = {min(r['m'])}..{max(r['m'])}"]
    for name in ("jaxpose_batch", "jaxpose_loop", "sklearn_loop"):
        v = r.get(name)
        if isinstance(v, dict):
            lines.append(f"  {name:<14} {_t(v):>12}  {v['objects_per_s']:.3g} objects/s  compile {_c(v)}")
        else:
            lines.append(f"  {name:<14} unavailable")
    lines.append(f"  ratios: batch/sklearn {_r(r['ratio_batch_vs_sklearn'])}  loop/sklearn "
                 f"{_r(r['ratio_loop_vs_sklearn'])}  batch/loop {_r(r['ratio_batch_vs_loop'])}  "
                 f"max |center batch - loop| {r['batch_vs_loop_max_center_diff']:.2e}")
    return lines


def _scaling_lines(r):
    n = r.get("in_m_resolution", 32)
    lines = ["", f"[scaling in m]  fit + moments ({n}^3, default refine) vs sklearn fit + {n}^3 indicator; "
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
    return lines


def _accuracy_lines(r):
    def row(name, v):
        if v["median"] is None:
            return f"  {name:<30} no object's region holds a grid point ({v['empty']} empty)"
        empty = f"  ({v['empty']} empty: no grid point inside)" if v.get("empty") else ""
        return (f"  {name:<30} center median {v['median']:.2e}  max {v['max']:.2e}  within {r['bar']:g}: "
                f"{v['within_bar']}/{r['n_objects']}  |  scale median {v['scale_median']:.2e}  max {v['scale_max']:.2e}"
                + empty)

    lines = ["", f"[accuracy]  {r['n_objects']} objects, m={r['m']}, errors against the reference (scale: relative) "
                 f"(fit tol {r['reference']['fit_tol']:g}, {r['reference']['resolution']}^3 x {r['reference']['refine']})",
             row(f"jaxpose {_fit(r)}{r['resolution']}^3 x {r['refine']}", r["jaxpose"])]
    if isinstance(r["sklearn"], dict):
        lines += [row(f"sklearn {res}^3 indicator", v) for res, v in r["sklearn"].items()]
    else:
        lines.append("  sklearn                        unavailable")
    return lines


_SECTION_LINES = {"solver": _solver_lines, "end2end": _end2end_lines, "batch": _batch_lines, "scaling": _scaling_lines,
                  "accuracy": _accuracy_lines}


def format_table(result):
    lines = [f"jaxpose bench  source={result['source']}  gamma={result['gamma']:g} nu={result['nu']:g}  "
             f"repeats={result['repeats']}  backend={result['environment']['backend']}  sklearn={result['sklearn']}",
             "ratio = jaxpose / sklearn (median of warm runs; < 1 means jaxpose is faster)"]
    for name in SECTIONS:
        if name in result["sections"]:
            lines += _SECTION_LINES[name](result["sections"][name])
    return "\n".join(lines)


# --------------------------------------------------------------------------- command line
def _parser():
    p = argparse.ArgumentParser(prog="jaxpose bench", description="timings of jaxpose against scikit-learn")
    p.add_argument("--quick", action="store_true", help=f"small sizes, {QUICK['repeats']} repeats (well under a minute)")
    p.add_argument("--json", help="write the full result as JSON here")
    p.add_argument("--m", type=int, default=None, help=f"points per object for solver / end2end (default {FULL['m']}; quick {QUICK['m']})")
    p.add_argument("--repeats", type=int, default=None, help=f"warm runs per case (default {FULL['repeats']}; quick {QUICK['repeats']})")
    p.add_argument("--sections", default=",".join(SECTIONS), help=f"comma list of {','.join(SECTIONS)}")
    p.add_argument("--scaling-m", default=None, help="comma list of m for the scaling section "
                   f"(default {_listed(FULL['scaling_m'])}; quick {_listed(QUICK['scaling_m'])})")
    p.add_argument("--resolutions", default=None, help=f"comma list of grid resolutions (default {_listed(FULL['resolutions'])}; quick "
                   f"{_listed(QUICK['resolutions'])})")
    p.add_argument("--sklearn-max-m", type=int, default=8000, help="largest m the sklearn side runs in scaling (default 8000)")
    p.add_argument("--tol", type=float, default=1e-3, help="solver tolerance in the solver section (default 1e-3)")
    p.add_argument("--solver", choices=("pg", "smo", "auto"), default=None,
                   help="jaxpose's solver in end2end, batch and scaling (default: normalize's, pg up to 2500 "
                        "points, auto above; the solver section times pg and auto)")
    p.add_argument("--solver-tol", type=float, default=None,
                   help="jaxpose's solver tol in end2end, batch and scaling (default: normalize's, 1e-3)")
    p.add_argument("--scaling-max-iter", type=int, default=None,
                   help="cap solver iterations in scaling (peak memory of large m without the full run time)")
    p.add_argument("--resolution", type=int, default=None,
                   help="normalize's resolution in end2end, batch and accuracy (default: normalize's, 64; quick "
                        f"{QUICK['resolution']}), and the m-scaling's grid (default 32; quick {QUICK['resolution']})")
    p.add_argument("--refine", type=int, default=None,
                   help="normalize's refine in end2end, batch and accuracy (default: normalize's, 2)")
    p.add_argument("--sk-resolution", type=int, default=None,
                   help="scikit-learn pipeline's grid per axis in end2end and batch "
                        f"(default {FULL['sk_resolution']}; quick {QUICK['sk_resolution']})")
    p.add_argument("--objects", type=int, default=None,
                   help=f"objects in the accuracy section (default {FULL['accuracy_objects']}: FAUST tr_reg_000.. when "
                        f"present; quick {QUICK['accuracy_objects']})")
    p.add_argument("--no-sklearn", action="store_true", help="time jaxpose only")
    p.add_argument("--x64", action="store_true", help="enable float64 in JAX (default float32)")
    p.add_argument("--force", action="store_true", help="overwrite an existing --json file")
    return p


def _listed(values):
    """(1000, 2000, 4000) -> '1000,2000,4000' (a help text's default, as the option takes it)."""
    return ",".join(str(v) for v in values)


def _ints(text):
    return [int(v) for v in text.split(",") if v.strip()] if text else None


def _usage_problem(args):
    """What else the run would take wrongly or fail on after starting, or None: a negative --repeats
    (taken as 0: one cold run), comma lists that are not ints of their least size (ValueError after
    the start), tolerances that are not finite and > 0 (refused by the solver after the first
    section started), --scaling-max-iter below 1."""
    import math

    if args.repeats is not None and args.repeats < 0:
        return f"--repeats must be >= 0 (0: one cold run each), got {args.repeats}"
    for name, text, least in (("--scaling-m", args.scaling_m, 8), ("--resolutions", args.resolutions, 8)):
        try:
            values = _ints(text)
        except ValueError:
            return f"{name} must be a comma list of ints, got {text!r}"
        if values is not None and (not values or min(values) < least):
            return f"{name} must list ints >= {least}, got {text!r}"
    for name, value in (("--tol", args.tol), ("--solver-tol", args.solver_tol)):
        if value is not None and not (math.isfinite(value) and value > 0):
            return f"{name} must be finite and > 0, got {value}"
    if args.scaling_max_iter is not None and args.scaling_max_iter < 1:
        return f"--scaling-max-iter must be >= 1, got {args.scaling_max_iter}"
    return None


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
        return fail(f"unknown sections {bad}; valid: {','.join(SECTIONS)}", code=2)
    if args.json:  # before the work: an existing file, a folder that cannot be made or written
        from jaxpose.io.atomic import check_output_file
        from jaxpose.errors import InvalidInputError

        try:
            check_output_file(args.json, args.force, "--json")
        except InvalidInputError as exc:
            return fail(exc, code=2)  # a usage error, as the other checks before the work
    if args.m is not None and args.m < 8:
        return fail("--m must be >= 8", code=2)
    if args.refine is not None and (args.refine < 1 or args.refine & (args.refine - 1)):
        return fail("--refine must be a power of 2", code=2)
    if args.resolution is not None and args.resolution < 8:
        return fail("--resolution must be >= 8", code=2)
    if args.sk_resolution is not None and args.sk_resolution < 2:
        return fail("--sk-resolution must be >= 2", code=2)
    if args.objects is not None and args.objects < 1:
        return fail("--objects must be >= 1", code=2)
    problem = _usage_problem(args)
    if problem:
        return fail(problem, code=2)
    if args.x64:
        import jax

        jax.config.update("jax_enable_x64", True)
    result = run(sections, quick=args.quick, m=args.m, repeats=args.repeats, scaling_m=_ints(args.scaling_m),
                 resolutions=_ints(args.resolutions), tol=args.tol, sk_max_m=args.sklearn_max_m,
                 use_sklearn=not args.no_sklearn, x64=args.x64, scaling_max_iter=args.scaling_max_iter,
                 solver=args.solver, solver_tol=args.solver_tol, refine=args.refine, resolution=args.resolution,
                 sk_resolution=args.sk_resolution, objects=args.objects, progress=lambda s: print(f"jaxpose bench: {s}", file=sys.stderr, flush=True))
    print(format_table(result))
    if args.json:
        from jaxpose.mesh import write_atomic

        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        from jaxpose.io.jsontext import json_text

        # strict JSON: a result that is not a number (a baseline's empty region) is null, not NaN
        write_atomic(args.json, json_text(json.loads(json.dumps(result, default=_jsonable))), force=args.force)
        print(f"wrote {args.json}")
    return 0


def _jsonable(x):
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, (np.floating, np.integer, np.bool_)):
        return x.item()
    raise TypeError(f"not JSON serializable: {type(x).__name__}")
