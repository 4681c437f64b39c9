"""Within-class spreads of centers and scales (the paper's section 4.2 measures).

For one class with centers c_1..c_n (3-vectors) and scales s_1..s_n, c_bar and s_bar their means:

* ``sigma_tr`` = sqrt(1/n sum_k |c_k - c_bar|^2), the RMS distance of the centers from their mean;
* ``sigma_tr_axis`` = 1/3 sum_a sqrt(1/n sum_k (c_ka - c_bar_a)^2), the mean per-axis std (ddof 0);
* ``sigma_scale`` = sqrt(1/n sum_k (s_k - s_bar)^2), the population std of the scales;
* ``cv_scale`` = sigma_scale / s_bar.

All in the units of the meshes.
"""
from __future__ import annotations

import numpy as np

from .._validate import InvalidInputError

__all__ = ["spread", "scale_spread"]

def spread(centers) -> dict:
    """``{"sigma_tr", "sigma_tr_axis"}`` of an (n, 3) array of one class's centers (module doc)."""
    c = np.asarray(centers, dtype=np.float64)
    if c.ndim != 2 or c.shape[1] != 3 or len(c) == 0:
        raise InvalidInputError(f"centers must have shape (n, 3) with n >= 1, got {c.shape}")
    if not np.all(np.isfinite(c)):
        raise InvalidInputError("centers must be finite")
    d = c - c.mean(axis=0)
    return {"sigma_tr": float(np.sqrt(np.mean(np.sum(d * d, axis=1)))),
            "sigma_tr_axis": float(np.mean(np.std(c, axis=0)))}


def scale_spread(scales) -> dict:
    """``{"sigma_scale", "cv_scale"}`` of the (n,) scales of one class (module doc)."""
    s = np.asarray(scales, dtype=np.float64)
    if s.ndim != 1 or len(s) == 0 or not np.all(np.isfinite(s)) or np.any(s <= 0):
        raise InvalidInputError(f"scales must be an (n,) array of positive finite values, got {s!r}")
    sigma = float(np.std(s))
    return {"sigma_scale": sigma, "cv_scale": sigma / float(np.mean(s))}
