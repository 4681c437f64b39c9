"""Shared pieces of ``jaxpose bench``: constants, the input points, timing helpers."""
from __future__ import annotations

import math
import os
import resource
import statistics
import sys
import time
from pathlib import Path

import numpy as np

FAUST = Path(__file__).resolve().parents[3] / "shared" / "data" / "faust-dev"
UNAVAILABLE = "unavailable"
MARKER = "JAXPOSE_BENCH "  # prefix of the result line a scaling child prints
GAMMA, NU = 47.0, 0.5


# --------------------------------------------------------------------------- inputs
def faust_dir():
    env = os.environ.get("JAXPOSE_FAUST")
    for d in ([Path(env)] if env else []) + [FAUST, Path.cwd().parent / "shared" / "data" / "faust-dev"]:
        if (d / "tr_reg_000.ply").exists():
            return d
    return None


def geometry(index=0):
    """(mesh, name): FAUST tr_reg_{index:03d} when present, else the built-in example shape."""
    from jaxpose import mesh

    d = faust_dir()
    if d is not None and (d / f"tr_reg_{index:03d}.ply").exists():
        return mesh.load(d / f"tr_reg_{index:03d}.ply"), f"faust/tr_reg_{index:03d}"
    return mesh.example_shape(), "example_shape"


def load_points(m, seed=0, index=0):
    """(m, 3) float64 surface samples scaled into the unit cube, and the source's name."""
    from jaxpose import mesh

    geom, name = geometry(index)
    p = mesh.sample_surface(geom, int(m), seed=int(seed), method="even")
    lo, hi = p.min(axis=0), p.max(axis=0)
    return (p - lo) / float(np.max(hi - lo)), name


def prescale(points):
    """y = (x - mean) / s_ref exactly as ``normalize`` does (float64 numpy); -> y, mean, size."""
    from jaxpose.pose.frame import REFERENCE_RMS

    x = np.asarray(points, np.float64)
    mean = x.mean(axis=0)
    mean = mean + (x - mean).mean(axis=0)
    size = math.sqrt(np.mean(np.sum((x - mean) ** 2, axis=1))) / REFERENCE_RMS
    return (x - mean) / size, mean, size


def sklearn_available():
    """Whether scikit-learn can be imported. Every section asks through this one function
    (``common.sklearn_available``), so patching it here switches the scikit-learn side off."""
    try:
        import sklearn.svm  # noqa: F401
    except ImportError:
        return False
    return True


def grid_opts(resolution, refine):
    """Grid options of ``normalize``; None = its defaults."""
    from jaxpose.config import GridConfig

    return {"resolution": int(resolution or GridConfig().resolution), "refine": int(refine or GridConfig().refine)}


# --------------------------------------------------------------------------- timing
def now():
    return time.perf_counter()


def block(x):
    import jax

    return jax.block_until_ready(x)


def timed(fn):
    """(seconds, result) of one call of fn, waiting for JAX's asynchronous results."""
    t = now()
    out = block(fn())
    return now() - t, out


def summary(first, warm):
    warm = [float(t) for t in warm]
    if not warm:  # a single cold run: compile time and run time are not separated
        return {"median_s": float(first), "runs_s": [], "first_s": float(first), "cold_only": True}
    med = statistics.median(warm)
    out = {"median_s": med, "runs_s": warm}
    if first is not None:
        out["first_s"] = float(first)
        out["compile_s"] = max(float(first) - med, 0.0)
    return out


def interleaved(cases, repeats):
    """cases: {name: callable}. One first call each (compile / warm-up), then ``repeats``
    rounds in which every case runs once, the order rotating each round.
    Returns {name: {"first_s", "runs_s", "median_s", "compile_s"}} and {name: last result}."""
    names = list(cases)
    first, last = {}, {}
    for n in names:
        first[n], last[n] = timed(cases[n])
    runs = {n: [] for n in names}
    for r in range(int(repeats)):
        k = r % len(names)
        for n in names[k:] + names[:k]:
            t, last[n] = timed(cases[n])
            runs[n].append(t)
    return {n: summary(first[n], runs[n]) for n in names}, last


def ratio(a, b):
    if not isinstance(a, dict) or not isinstance(b, dict):
        return None
    return a["median_s"] / b["median_s"] if b["median_s"] > 0 else None


def maxrss_mb():
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
