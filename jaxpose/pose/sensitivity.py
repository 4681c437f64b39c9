"""Derivatives of the OCSVM pose (center, scale) in gamma and nu, as NumPy values.

``pose`` is :func:`jaxpose.normalize` (whose default derivatives in gamma and nu follow the trend
of the pose over steps of 1 %, ``derivative="trend"``, see :mod:`jaxpose.occupancy.svdd.secant`);
``pose_sensitivity`` returns the four derivatives of the center and the scale at one (gamma, nu),
computed with ``jax.jacfwd`` of it.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from .. import _validate
from ..host import host_frame
from ..config import OCSVM, PoseConfig
from .pose import Pose, normalize
from .result import status_message

__all__ = ["pose", "pose_sensitivity", "NU_DELTA"]

NU_DELTA = PoseConfig().nu_delta  # relative half-width of the nu interval of the trend derivative


def pose(points, gamma=OCSVM.gamma, nu=OCSVM.nu, **options) -> Pose:
    """:func:`jaxpose.normalize`: the same values and, by default, the same trend derivatives.

    Args:
      points: (m, 3); gamma, nu: () (traceable); options: as ``normalize``, including
        ``derivative`` ("trend", "exact", "secant"), ``gamma_delta`` and ``nu_delta`` (relative
        half-widths of the intervals) and ``secant_iterations``; not ``method`` (the pose in gamma
        and nu is the OCSVM's: InvalidInputError).
    """
    if "method" in options:  # normalize's TypeError 'got multiple values for keyword argument 'method''
        raise _validate.InvalidInputError(
            f"method={options['method']!r}: the pose in gamma and nu is the OCSVM's (method='ocsvm'); the robust "
            "pose's derivative in its power is jax.grad of jaxpose.normalize(points, power=...)")
    return normalize(points, method="ocsvm", gamma=gamma, nu=nu, **options)


def pose_sensitivity(points, gamma=OCSVM.gamma, nu=OCSVM.nu, **options) -> dict:
    """Derivatives of the pose in gamma and nu, as NumPy values.

    Args:
      points: (m, 3) surface samples; gamma, nu: floats; options: as :func:`pose`; ``throw``
        (as :func:`jaxpose.normalize`'s) read on the concrete result: JaxposeError for a pose that
        is not valid, ConvergenceError where the solver hit max_iter.

    Returns:
      {"center" (3,), "scale" (), "dcenter_dgamma" (3,), "dcenter_dnu" (3,), "dscale_dgamma" (),
      "dscale_dnu" ()} as float64 NumPy arrays in the units of ``points`` (by default the trend over
      gamma (1 +- gamma_delta) and nu (1 +- nu_delta)), plus "converged" and "valid" (bools). The
      pose is computed as :func:`jaxpose.normalize` computes a concrete one, whatever JAX's default
      float: the points moved near the origin and scaled on the host in float64
      (:func:`jaxpose.host.host_frame`), the center and scale mapped back there in float64, so a
      center far from the origin keeps its digits (with x64 off it was float32: 6e-4 off at 1e5).

    Raises:
      InvalidInputError: bad points, gamma, nu or option; a traced one (a host function: under
        jit / vmap / grad take ``jax.jacfwd`` of :func:`jaxpose.normalize`).

    Example::

        points = jaxpose.sample_surface(mesh, 2000, seed=0)
        s = jaxpose.pose_sensitivity(points, gamma=47.0, nu=0.5)
        s["dcenter_dgamma"].shape, s["dscale_dnu"].shape, s["converged"]   # (3,), (), True
    """
    traced = [name for name, v in (("points", points), ("gamma", gamma), ("nu", nu)) if _validate.is_traced(v)]
    if traced:  # its results are NumPy values: np.asarray of a tracer would fail deep inside
        raise _validate.InvalidInputError(
            f"pose_sensitivity returns NumPy values and takes concrete inputs, got a traced {traced[0]}; "
            "under jit / vmap / grad use jax.jacfwd of jaxpose.normalize(points, method='ocsvm', gamma=..., nu=...)")
    _validate.check_gamma(gamma)
    _validate.check_nu(nu)
    throw = _validate.check_bool(options.pop("throw", False), "throw")  # read here, on the concrete result
    points = np.asarray(_validate.check_points(points))
    dtype = _validate.compute_dtype(points)  # float64 points without x64: float32
    theta = jnp.asarray([gamma, nu], dtype)
    # normalize's float64 path: its pose is traced here (gamma, nu are), and a traced pose is mapped back
    # to the points' units in JAX's default float; so the points are moved near the origin and scaled on the
    # host in float64 first (host_frame, as normalize moves concrete points), and the pose mapped back here
    shift, size = host_frame(points)
    moved = ((np.asarray(points, np.float64) - shift) / size).astype(dtype)

    def f(t):
        p = pose(moved, t[0], t[1], **options)
        return jnp.concatenate([p.center, p.scale[None]]), p

    J, p = jax.jacfwd(f, has_aux=True)(theta)
    if throw:  # (normalize's own throw cannot: its pose is traced under jacfwd)
        if not bool(p.converged):
            raise _validate.ConvergenceError(f"SVDD solver hit its iteration cap ({int(p.iterations)} iterations)")
        if not bool(p.valid):
            raise _validate.JaxposeError(f"no valid pose ({status_message(int(p.status))})")
    J = np.asarray(J, np.float64) * size  # center and scale scale with the points
    return {
        "center": shift + size * np.asarray(p.center, np.float64),
        "scale": size * np.asarray(p.scale, np.float64),
        "dcenter_dgamma": J[:3, 0],
        "dcenter_dnu": J[:3, 1],
        "dscale_dgamma": J[3, 0],
        "dscale_dnu": J[3, 1],
        "converged": bool(p.converged),
        "valid": bool(p.valid),
    }
