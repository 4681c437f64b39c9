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

from .._validate import InvalidInputError, check_array, is_real_dtype

__all__ = ["spread", "scale_spread"]

def spread(centers) -> dict:
    """``{"sigma_tr", "sigma_tr_axis"}`` of an (n, 3) array of one class's centers (module doc)."""
    c = np.asarray(check_array(centers, "centers", 1), dtype=np.float64)  # the library's (m, 3) rule and messages
    d = c - c.mean(axis=0)
    return {"sigma_tr": float(np.sqrt(np.mean(np.sum(d * d, axis=1)))),
            "sigma_tr_axis": float(np.mean(np.std(c, axis=0)))}


def scale_spread(scales) -> dict:
    """``{"sigma_scale", "cv_scale"}`` of the (n,) scales of one class (module doc)."""
    try:
        s = np.asarray(scales)
    except (TypeError, ValueError):  # ragged and the like
        s = None
    if (s is None or not is_real_dtype(s.dtype) or s.ndim != 1 or len(s) == 0 or not np.all(np.isfinite(s))
            or np.any(s <= 0)):
        raise InvalidInputError(f"scales must be an (n,) array of positive finite values, got {scales!r:.80}")
    s = s.astype(np.float64)
    sigma = float(np.std(s))
    return {"sigma_scale": sigma, "cv_scale": sigma / float(np.mean(s))}
