"""normalize(): equivariance, the minimum-enclosing-ball limit, grid convergence, Pose algebra."""
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxpose
from jaxpose.moments import volume_moments
from jaxpose.frame import reference_frame
from jaxpose.pose import Pose, normalize
from jaxpose.svdd import fit_svdd
from conftest import box_surface, clusters, faust_points, sphere_with_arm


def random_rotation(rng):
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q *= np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


# The grid follows the principal axes, so only float rounding (and the solver's tol) separates
# the two results: 1e-3 of the scale holds for thin shells (sampled sphere) and boxes alike.
@pytest.mark.parametrize("make,opts", [(box_surface, {}), (sphere_with_arm, {})])
def test_equivariance_under_similarities(x64, make, opts):
    rng = np.random.default_rng(0)
    pts = make(800)
    base = normalize(pts, **opts)
    for scale, shift in [(1e-3, 1e4), (1e3, -1e4), (0.37, 12.5)]:
        R = random_rotation(rng)
        t = rng.uniform(-1, 1, 3) * shift
        moved = normalize(scale * pts @ R.T + t, **opts)
        expect_c = scale * np.asarray(base.center) @ R.T + t
        s = scale * float(base.scale)
        assert np.linalg.norm(np.asarray(moved.center) - expect_c) < 1e-3 * s
        assert abs(float(moved.scale) - s) < 1e-3 * s


def test_invariant_to_point_order(x64):
    pts = clusters(600)
    perm = np.random.default_rng(1).permutation(600)
    a, b = normalize(pts), normalize(pts[perm])
    np.testing.assert_allclose(np.asarray(a.center), np.asarray(b.center), atol=1e-4 * float(a.scale))


def test_minimum_enclosing_ball_limit(x64):
    miniball = pytest.importorskip("miniball")
    for make in (sphere_with_arm, clusters, box_surface):
        pts = make(500)
        svdd = fit_svdd(pts, 1e-3, 0.0, tol=1e-9, max_iter=200_000)
        mom = volume_moments(svdd)
        c, _ = miniball.get_bounding_ball(pts, rng=np.random.default_rng(0))
        size = np.ptp(pts, axis=0).max()
        assert np.linalg.norm(np.asarray(mom.center) - c) < 1e-2 * size


@pytest.mark.slow
def test_default_resolution_converges_to_512_reference(x64):
    # three shapes, each scaled to size 1: the default grid against boundary resolution 512
    # (64^3 refined 3 levels), extrapolated and plain; those two agree to 4e-4 (float64)
    shapes = {"sphere_with_arm": sphere_with_arm(600), "box": box_surface(600)}
    try:
        shapes["faust"] = faust_points(600)
    except pytest.skip.Exception:
        shapes["clusters"] = clusters(600)
    errors = {}
    for name, pts in shapes.items():
        pts = pts / np.ptp(pts, axis=0).max()
        mean, size = reference_frame(jnp.asarray(pts))
        svdd = fit_svdd((pts - mean) / size, 47.0, 0.5, tol=1e-6)
        ref = volume_moments(svdd, resolution=64, refine=8, band=65536)
        plain = volume_moments(svdd, resolution=64, refine=8, band=65536, extrapolate=False)
        assert int(ref.unrefined) == 0
        assert float(size) * np.linalg.norm(np.asarray(plain.center - ref.center)) < 4e-4, name
        for preset, opts in {"default": {}, "fine": dict(resolution=32, refine=8, band=16384)}.items():
            mom = volume_moments(svdd, **opts)
            err = float(size) * np.linalg.norm(np.asarray(mom.center) - np.asarray(ref.center))
            errors[name, preset] = (err, float(mom.mean_distance) / float(ref.mean_distance) - 1, int(mom.unrefined))
    print("ERRORS", errors)
    # measured: default (64 x 2) 7.2e-4 / 3.4e-4 / 2.9e-5 (arm, box, faust; 32 x 4 before issue 5's
    # last-level band: 7.3e-4 / 3.4e-4 / 2.9e-5); plain (extrapolate=False) was 5.4e-3 / 3.0e-4 / 5.9e-4; fine <= 8.2e-5
    for (name, preset), (err, md, unrefined) in errors.items():
        assert unrefined == 0, (name, preset)  # the band held every cut cell
        assert err < (1e-3 if preset == "default" else 2e-4), (name, preset, err)
        assert abs(md) < (1e-3 if preset == "default" else 2e-4), (name, preset, md)


def test_pose_algebra(x64):
    pose = Pose.from_center_scale(jnp.array([1.0, -2.0, 3.0]), 2.5)
    x = np.random.default_rng(0).normal(size=(10, 3))
    y = np.asarray(pose.apply(x))
    np.testing.assert_allclose(y, (x - [1, -2, 3]) / 2.5)
    np.testing.assert_allclose(np.asarray(pose.inverse().apply(y)), x, atol=1e-12)
    h = np.c_[x, np.ones(10)] @ np.asarray(pose.matrix).T
    np.testing.assert_allclose(h[:, :3], y, atol=1e-12)
    np.testing.assert_allclose(np.asarray(pose.inverse().matrix) @ np.asarray(pose.matrix), np.eye(4), atol=1e-12)


def test_normalized_shape_has_unit_mean_distance(x64):
    pts = box_surface(800)
    pose = normalize(pts)
    assert bool(pose.valid) and bool(pose.converged)
    again = normalize(np.asarray(pose.apply(pts)))
    np.testing.assert_allclose(np.asarray(again.center), 0, atol=1e-3)
    np.testing.assert_allclose(float(again.scale), 1, atol=1e-3)


def test_float32_default_and_jit():
    pts = jnp.asarray(sphere_with_arm(500), jnp.float32)
    pose = normalize(pts)
    assert pose.center.dtype == jnp.float32 and bool(pose.valid)
    jitted = jax.jit(lambda p, g, n: normalize(p, g, n))(pts, 47.0, 0.5)
    np.testing.assert_allclose(np.asarray(jitted.center), np.asarray(pose.center), atol=1e-5)


def test_batch_matches_single(x64):
    sets = [sphere_with_arm(400, seed=0), clusters(300, seed=1), box_surface(350, seed=2)]
    batch = jaxpose.normalize_batch(sets)
    assert batch.center.shape == (3, 3)
    for i, p in enumerate(sets):
        single = normalize(p)
        np.testing.assert_allclose(np.asarray(batch.center[i]), np.asarray(single.center), atol=2e-3 * float(single.scale))


@pytest.mark.parametrize("bad", [np.zeros((10, 2)), np.full((10, 3), np.nan), np.ones((10, 3)), np.zeros((2, 3))])
def test_bad_points(bad):
    with pytest.raises(jaxpose.InvalidInputError):
        normalize(bad)


@pytest.mark.parametrize("kw", [dict(gamma=-1.0), dict(nu=2.0), dict(resolution=4), dict(refine=0), dict(kernel="x"),
                                dict(solver="x")])
def test_bad_options(kw):
    with pytest.raises(jaxpose.InvalidInputError):
        normalize(clusters(50), **kw)
