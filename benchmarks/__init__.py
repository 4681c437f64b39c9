"""Benchmarks (``jaxpose bench`` or ``python -m benchmarks`` from a source checkout): timings of jaxpose against the scikit-learn pipeline, on the same points.

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
          cells at the first level: boundary resolution of a 256^3 grid, Richardson-extrapolated
          with the 128 level as ``volume_moments`` does by default).
batch     many objects: ``normalize_batch`` vs a loop of ``normalize`` vs a loop of the
          scikit-learn pipeline; objects per second.
scaling   in m (one subprocess per case, so peak memory ru_maxrss is per case) and in the
          grid resolution (moments alone vs ``decision_function`` on the grid).
accuracy  no timings: center and scale errors over many objects (FAUST tr_reg_000.. when present) of
          ``normalize`` and of the scikit-learn pipeline at 32^3, 48^3 and 64^3 against the
          end2end reference; median, max and how many are within 1e-3. It is why the
          scikit-learn side gets 64^3 by default (the coarsest within 1e-3 on most FAUST meshes).

Every timing is a median of warm runs, jaxpose and scikit-learn runs interleaved; jaxpose's
compile time is reported separately as first call minus the warm median. No timing is ever
asserted anywhere: the machine this runs on decides the numbers.
"""
from __future__ import annotations

# Layout: common (constants, input points, timing helpers), sklearn_pipeline (the scikit-learn
# pipeline and the dual objective), sections (solver, end2end, batch, accuracy), scaling (+ child, the
# subprocess that runs one scaling case: ``python -m benchmarks.child``), report (run,
# format_table, cli). To switch the scikit-learn side off in a test, patch
# ``benchmarks.common.sklearn_available``: every section asks through it.
from .common import FAUST, GAMMA, NU, UNAVAILABLE, load_points, prescale, sklearn_available
from .sklearn_pipeline import sk_alpha, sk_fit, dual_objective, sklearn_pipeline
from .report import FULL, QUICK, SCHEMA_VERSION, SECTIONS, cli, format_table, run
from .scaling import bench_scaling
from .sections import bench_accuracy, bench_batch, bench_end2end, bench_solver

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
    "bench_accuracy",
    "bench_batch",
    "bench_scaling",
    "run",
    "format_table",
    "cli",
]
