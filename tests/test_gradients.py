"""Derivatives of the pose in gamma and nu (issue 3).

Finite differences of the *production* function jump: the grid box follows the
support vectors' bounding box (grid.domain, not differentiated), so the
discretization error changes discontinuously with gamma and nu. The derivative
holds the grid fixed, so it is compared with finite differences of the same
pipeline on a frozen grid box (``frozen_box``), which is the function it is the
derivative of. The 5 shapes x 3 (gamma, nu) acceptance sweep is ``test_sweep``
(marked slow, skipped unless JAXPOSE_SLOW=1); ``python tests/test_gradients.py``
prints its table.
"""
from __future__ import annotations

import contextlib
import os

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import trimesh

import jaxpose
from jaxpose import grid, moments
from jaxpose.mesh import example_shape, sample_surface
from jaxpose.sensitivity import pose, pose_sensitivity

OPTS = dict(resolution=16, refine=2, band=2048, tol=1e-7, max_iter=200_000)


@pytest.fixture(autouse=True, scope="module")
def x64():
    old = jax.config.jax_enable_x64
    jax.config.update("jax_enable_x64", True)
    yield
    jax.config.update("jax_enable_x64", old)


@contextlib.contextmanager
def frozen_box(points, gamma, nu, pad=0.05, **opts):
    """Freeze moments.domain at the box of (gamma, nu), grown by pad (pre-scaled units)."""
    from jaxpose.pose import reference_frame
    from jaxpose.svdd import _fit

    mean, size = reference_frame(points)
    s = _fit((points - mean) / size, gamma, nu, None, None, tol=opts.get("tol", 1e-3),
             max_iter=opts.get("max_iter", 20_000), check_every=10, kernel="auto", block=2048)
    lo, hi = grid.domain(s)
    box = (lo - pad, hi + pad)
    old = moments.domain
    moments.domain = lambda _svdd: box
    try:
        yield
    finally:
        moments.domain = old


def _vec(p):
    return np.concatenate([np.asarray(p.center), [float(p.scale)]])


def _fn(points, **opts):
    # not jitted on purpose: the frozen box is a Python-level patch, so every call retraces
    from jaxpose.pose import _normalize

    def f(g, n):
        p = _normalize(points, None, jnp.asarray(g, points.dtype), jnp.asarray(n, points.dtype), **{**jaxpose.pose.DEFAULTS, **opts})
        return jnp.concatenate([p.center, p.scale[None]])

    return f


def _rel(a, b):
    """Relative error of the center (vector norm) and the scale, against FD b."""
    ec = np.linalg.norm(a[:3] - b[:3]) / max(np.linalg.norm(b[:3]), 1e-300)
    es = abs(a[3] - b[3]) / max(abs(b[3]), 1e-300)
    return ec, es


def _ok(a, b, rel, atol=1e-6):
    ec, es = _rel(a, b)
    return (ec <= rel or np.linalg.norm(a[:3] - b[:3]) <= atol) and (es <= rel or abs(a[3] - b[3]) <= atol)


@pytest.fixture(scope="module")
def shape_points(x64):
    return jnp.asarray(sample_surface(example_shape(), 400, seed=1))


@pytest.fixture(scope="module")
def small_points(x64):
    return jnp.asarray(sample_surface(example_shape(), 200, seed=2))


SMALL = dict(resolution=8, refine=2, band=256, tol=1e-4)


def test_gamma_derivative_matches_fd_on_frozen_grid(shape_points):
    g, n = 47.0, 0.5
    with frozen_box(shape_points, g, n, **OPTS):
        f = jax.jit(_fn(shape_points, **OPTS))  # traced inside the context: the frozen box is baked in
        J = np.asarray(jax.jacfwd(f, argnums=0)(g, n))
        eps = 1e-3
        fd = (np.asarray(f(g * (1 + eps), n)) - np.asarray(f(g * (1 - eps), n))) / (2 * g * eps)
    assert _ok(J, fd, 0.05), (J, fd, _rel(J, fd))


def test_forward_reverse_jit_vmap_agree(small_points):
    shape_points, opts = small_points, SMALL

    def cs(t):
        p = pose(shape_points, t[0], t[1], **opts)
        return jnp.concatenate([p.center, p.scale[None]])

    t = jnp.asarray([47.0, 0.5])
    Jf = jax.jacfwd(cs)(t)
    Jj = jax.jit(jax.jacrev(cs))(t)
    np.testing.assert_allclose(Jf, Jj, rtol=1e-6, atol=1e-10)
    assert np.all(np.isfinite(Jf)) and np.any(Jf[:, 1] != 0)
    # vmap over point sets (forward mode inside; reverse mode of the core under vmap is
    # covered by jax.grad in test_core_normalize_differentiable_in_gamma and tuning's jacfwd(vmap))
    P = jnp.stack([shape_points, shape_points + 1.0])
    from jaxpose.pose import DEFAULTS
    from jaxpose.sensitivity import _pose

    o = {**DEFAULTS, **opts}
    gs = jax.vmap(lambda p: jax.jacfwd(lambda t: _pose(p, t[0], t[1], **o).scale)(t))(P)
    np.testing.assert_allclose(gs[0], Jf[3], rtol=1e-6, atol=1e-10)
    np.testing.assert_allclose(gs[1], Jf[3], rtol=1e-5, atol=1e-9)  # translation invariance


def test_core_normalize_differentiable_in_gamma(small_points):
    shape_points, opts = small_points, SMALL
    f = lambda g: jaxpose.normalize(shape_points, g, 0.5, **opts).scale
    a = jax.grad(f)(47.0)
    b = jax.jacfwd(f)(47.0)
    np.testing.assert_allclose(a, b, rtol=1e-6)
    # pose() has the same forward values and the same gamma-derivative as normalize()
    p, q = pose(shape_points, 47.0, 0.5, **opts), jaxpose.normalize(shape_points, 47.0, 0.5, **opts)
    # (normalize pre-centers concrete points in float64 NumPy: equal up to rounding)
    np.testing.assert_allclose(np.asarray(p.center), np.asarray(q.center), rtol=1e-12, atol=1e-12)


def test_nu_secant_derivative_matches_fd(shape_points):
    """Secant nu-derivative vs central FD of the production center, steps 1.5 % of nu.

    Over this interval ~10 points change between free, bounded and zero (m = 400)."""
    g, n = 47.0, 0.5
    S = pose_sensitivity(shape_points, g, n, **OPTS)
    J = np.concatenate([S["dcenter_dnu"], [S["dscale_dnu"]]])
    eps = 0.015
    fd = (_vec(jaxpose.normalize(shape_points, g, n * (1 + eps), **OPTS))
          - _vec(jaxpose.normalize(shape_points, g, n * (1 - eps), **OPTS))) / (2 * n * eps)
    assert _ok(J, fd, 0.20), (J, fd, _rel(J, fd))


def test_pose_sensitivity_types(small_points):
    shape_points = small_points
    S = pose_sensitivity(np.asarray(shape_points), 30.0, 0.4, resolution=8, refine=2, band=256, tol=1e-4)
    for k in ("dcenter_dgamma", "dcenter_dnu", "center"):
        assert isinstance(S[k], np.ndarray) and S[k].shape == (3,) and np.all(np.isfinite(S[k]))
    for k in ("dscale_dgamma", "dscale_dnu", "scale"):
        assert np.shape(S[k]) == () and np.isfinite(S[k])
    assert S["converged"] and S["valid"]


def test_pose_rejects_bad_options(shape_points):
    with pytest.raises(jaxpose.InvalidInputError):
        pose(shape_points, 47.0, 0.5, nu_delta=0.0)
    with pytest.raises(jaxpose.InvalidInputError):
        pose(shape_points, 47.0, 0.5, bogus=1)


def test_float32_gradients_are_finite(small_points):
    shape_points = small_points
    """Regression: moments.occupancy gave NaN tangents in float32 (width^2 underflow)."""
    p32 = np.asarray(shape_points, np.float32)
    opts = SMALL
    g = jax.grad(lambda t: (lambda q: jnp.sum(q.center) + q.scale)(pose(p32, t[0], t[1], **opts)))(jnp.asarray([47.0, 0.5], jnp.float32))
    assert g.dtype == jnp.float32 and np.all(np.isfinite(np.asarray(g)))


# --------------------------------------------------------------------------- acceptance sweep
SWEEP_PARAMS = [(47.0, 0.5), (25.0, 0.3), (40.0, 0.7)]


def _sweep_shapes():
    import trimesh.transformations as tf

    ell = trimesh.creation.icosphere(subdivisions=3)
    ell.apply_scale([1.0, 0.6, 0.35])
    tor = trimesh.creation.torus(major_radius=0.6, minor_radius=0.2)
    tor.apply_transform(tf.rotation_matrix(0.4, [1, 1, 0]))
    return {"example": example_shape(), "box": trimesh.creation.box([1.0, 0.6, 0.3]),
            "capsule": trimesh.creation.capsule(height=1.0, radius=0.3), "ellipsoid": ell, "torus": tor}


def sweep(m=400, opts=OPTS, report=print):
    """Rows: shape, gamma, nu, rel. errors (center, scale) of d/dgamma vs FD (frozen grid, steps 0.1 % and
    0.3 %, the closer one kept; both in the printed line),
    of d/dnu (secant) vs production FD at 1 % and 2 % steps, and the number of points changing
    status over +-2 % of nu."""
    from jaxpose.pose import reference_frame
    from jaxpose.svdd import _fit

    rows = []
    for name, mesh in _sweep_shapes().items():
        pts = jnp.asarray(sample_surface(mesh, m, seed=1))
        for g, n in SWEEP_PARAMS:
            with frozen_box(pts, g, n, **opts):
                f = _fn(pts, **opts)
                f = jax.jit(f)  # traced inside the context: the frozen box is baked in
                J = np.asarray(jax.jacfwd(f, argnums=0)(g, n))
                fds = [(np.asarray(f(g * (1 + e), n)) - np.asarray(f(g * (1 - e), n))) / (2 * g * e) for e in (1e-3, 3e-3)]
            # the frozen-grid function still has kinks (active-set changes, cells entering the
            # one-cell occupancy band): report both steps, accept if either agrees
            fd = min(fds, key=lambda v: max(_rel(J, v)))
            S = pose_sensitivity(pts, g, n, **opts)
            Jn = np.concatenate([S["dcenter_dnu"], [S["dscale_dnu"]]])
            errs = []
            for e in (0.01, 0.02):
                fdn = (_vec(jaxpose.normalize(pts, g, n * (1 + e), **opts))
                       - _vec(jaxpose.normalize(pts, g, n * (1 - e), **opts))) / (2 * n * e)
                errs.append((_rel(Jn, fdn), _ok(Jn, fdn, 0.20), fdn))
            mean, size = reference_frame(pts)
            y = (pts - mean) / size
            st = []
            for nn in (n * 0.98, n * 1.02):
                s = _fit(y, g, nn, None, None, tol=1e-7, max_iter=200_000, check_every=10, kernel="auto", block=2048)
                st.append(np.asarray((s.alpha > 0).astype(int) + (s.alpha >= s.cap).astype(int)))
            row = dict(shape=name, gamma=g, nu=n, gamma_rel=_rel(J, fd), gamma_ok=_ok(J, fd, 0.05),
                       dgamma=J, fd_gamma=fd, nu_rel_1=errs[0][0], nu_ok_1=errs[0][1], nu_rel_2=errs[1][0],
                       nu_ok_2=errs[1][1], dnu=Jn, fd_nu_1=errs[0][2], fd_nu_2=errs[1][2],
                       status_changes=int(np.sum(st[0] != st[1])))
            rows.append(row)
            r1, r3 = _rel(J, fds[0]), _rel(J, fds[1])
            report(f"{name:9s} g={g:4.0f} nu={n:.1f} | d/dgamma rel err 0.1%: c {r1[0]:.3f} s {r1[1]:.3f}, 0.3%: c {r3[0]:.3f} s {r3[1]:.3f} "
                   f"{'ok' if row['gamma_ok'] else 'FAIL'} | d/dnu vs FD 1%: c {errs[0][0][0]:.3f} s {errs[0][0][1]:.3f}, "
                   f"2%: c {errs[1][0][0]:.3f} s {errs[1][0][1]:.3f} | status changes +-2%: {row['status_changes']}")
    return rows


@pytest.mark.slow
@pytest.mark.skipif(not os.environ.get("JAXPOSE_SLOW"), reason="acceptance sweep (minutes): set JAXPOSE_SLOW=1")
def test_sweep():
    rows = sweep()
    assert all(r["gamma_ok"] for r in rows)
    assert all(r["nu_ok_1"] or r["nu_ok_2"] for r in rows)


if __name__ == "__main__":
    jax.config.update("jax_enable_x64", True)
    sweep(report=lambda line: print(line, flush=True))
