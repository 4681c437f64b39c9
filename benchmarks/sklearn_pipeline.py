"""The scikit-learn side of ``jaxpose bench``: what a user would write without jaxpose.

``OneClassSVM(kernel="rbf", gamma, nu).fit(y)``, ``decision_function`` on an N^3 grid of cell
centers over a box that provably covers the region, then the centroid and the mean distance of
the cells with ``decision_function >= 0``; and libsvm's solution mapped into our scaling.
"""
from __future__ import annotations

import math

import numpy as np

from .common import GAMMA, NU, now, prescale


def sk_fit(y, gamma, nu):
    from sklearn.svm import OneClassSVM

    return OneClassSVM(kernel="rbf", gamma=gamma, nu=nu).fit(y)


def sk_alpha(oc, m, nu):
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


def sk_grid(oc, y, gamma, nu, resolution):
    """(resolution^3, 3) cell centers over the box that covers libsvm's region."""
    lo, hi = _sk_domain(oc, y, gamma, nu)
    return _grid(lo, hi, int(resolution))[0]


def sklearn_pipeline(points, gamma=GAMMA, nu=NU, resolution=32):
    """Fit + grid indicator + centroid / mean distance with scikit-learn, in the units of points.

    Returns dict(center (3,), scale, fit_s, grid_s, n_support)."""
    y, mean, size = prescale(points)
    t0 = now()
    oc = sk_fit(y, gamma, nu)
    t1 = now()
    x = sk_grid(oc, y, gamma, nu, resolution)
    inside = oc.decision_function(x) >= 0
    xin = x[inside]
    if len(xin):
        c = xin.mean(axis=0)
        md = float(np.mean(np.linalg.norm(xin - c, axis=1)))
    else:
        c, md = np.full(3, np.nan), float("nan")
    t2 = now()
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


def feasibility(a, cap):
    a = np.asarray(a, np.float64)
    return {"sum_minus_1": float(a.sum() - 1.0), "min": float(a.min()), "max_over_cap": float(a.max() / cap - 1.0)}
