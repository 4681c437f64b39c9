"""The robust estimator's depth -> weights -> moments, on the host (NumPy) and in JAX, against scipy and
finite differences, and against each other."""
from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import trimesh
from scipy import ndimage

from jaxpose.pose import estimators
from jaxpose import mesh, moments
from jaxpose.occupancy import solid
from jaxpose.errors import InvalidInputError
from conftest import SHARED


def scipy_center_volume(sol, power):
    """The robust center and volume from scipy's distance transform (the oracle)."""
    d = np.maximum(ndimage.distance_transform_edt(sol.inside) - sol.bias, 0.0)[sol.inside]
    w = (d / d.max()) ** power if d.max() > 0 else np.ones_like(d)
    x = sol.origin + sol.pitch * (np.stack(np.nonzero(sol.inside), axis=1) + 0.5)
    n = float(sol.inside.sum()) - (0.0 if sol.occupied is None else 0.5 * float((sol.occupied & sol.inside).sum()))
    return ((w @ x) / w.sum()) @ sol.frame, n * sol.pitch**3


def jax_center_volume(sol, power):
    """The JAX path's center and volume (moments.solid_moments in JAX's float, mapped to the world)."""
    mom = moments.solid_moments(sol, power)
    center = (sol.origin + sol.pitch * np.asarray(mom.center, np.float64)) @ sol.frame
    return center, float(mom.volume) * sol.pitch**3


@pytest.fixture(scope="module")
def shape_solid():
    geometry, _ = estimators.centered(mesh.example_shape())
    return estimators._robust_solid(geometry, solid.RESOLUTION)


@pytest.mark.parametrize("power", [4.0, 1.0, 0.0])
def test_mesh_solid_matches_scipy(shape_solid, power):
    center, volume = scipy_center_volume(shape_solid, power)
    assert moments.solid_moments(shape_solid, power).center.dtype == jnp.float32
    host = estimators.solid_center_volume(shape_solid, power)  # NumPy, float64
    np.testing.assert_allclose(host[0], center, rtol=0, atol=1e-13)
    assert host[1] == volume  # voxel counts: exact
    world = jax_center_volume(shape_solid, power)  # JAX, float32
    np.testing.assert_allclose(world[0], center, atol=1e-6)
    assert world[1] == volume


def test_point_solid_counts_straddling_voxels_half():
    points, _ = trimesh.sample.sample_surface(trimesh.creation.capsule(height=1.0, radius=0.4), 6000, seed=0)
    sol = solid.robust_solid(points, with_depth=False)
    assert sol.bias == solid.POINT_BIAS and sol.depth is None and sol.occupied.any()
    center, volume = scipy_center_volume(sol, 4.0)
    for got, atol in ((estimators.solid_center_volume(sol, 4.0), 1e-13), (jax_center_volume(sol, 4.0), 1e-6)):
        np.testing.assert_allclose(got[0], center, rtol=0, atol=atol)
        assert got[1] == volume == sol.volume()


def test_float64(x64, shape_solid):
    center, volume = scipy_center_volume(shape_solid, 4.0)
    assert moments.solid_moments(shape_solid, 4.0).center.dtype == jnp.float64
    for got in (jax_center_volume(shape_solid, 4.0), estimators.solid_center_volume(shape_solid, 4.0)):
        np.testing.assert_allclose(got[0], center, rtol=0, atol=1e-13)
        assert got[1] == volume


def test_bad_power_is_refused(shape_solid):
    for power in (-1.0, float("nan"), "4", True):
        with pytest.raises(InvalidInputError, match="power"):
            estimators.solid_center_volume(shape_solid, power)
    for power in (-1.0, float("nan"), "4", np.array(True)):
        with pytest.raises(InvalidInputError, match="power"):
            moments.solid_moments(shape_solid, power)
    # a power given as a () NumPy or JAX array is its number (refused as "not a finite number >= 0")
    want_jax, want_host = moments.solid_moments(shape_solid, 4.0).center, estimators.solid_center_volume(shape_solid, 4.0)
    for power in (np.array(4.0), jnp.float32(4.0)):
        np.testing.assert_array_equal(moments.solid_moments(shape_solid, power).center, want_jax)
        np.testing.assert_array_equal(estimators.solid_center_volume(shape_solid, power)[0], want_host[0])


@pytest.mark.shared
def test_host_path_equals_the_jax_path_on_dev_shapes():
    """The host estimator (NumPy, scipy's EDT) and the JAX one give the same robust center and scale
    on real meshes of each dataset: within 1e-6 of the scale (float32 rounding of the JAX path)."""
    files = [SHARED / "data" / p for p in ("faust-dev/tr_reg_000.ply", "faust-dev/tr_reg_017.ply",
                                            "tosca-dev/dog/dog3.ply", "tosca-dev/horse/horse5.ply",
                                            "kids-dev/kid_0001/pose_03.ply", "kids-dev/kid_0002/pose_01.ply")]
    if not all(f.exists() for f in files):
        pytest.skip("../shared data is not available")
    for file in files:
        geometry, _ = estimators.centered(mesh.load(file))
        sol = estimators._robust_solid(geometry, solid.RESOLUTION)
        (c_host, v_host), (c_jax, v_jax) = estimators.solid_center_volume(sol), jax_center_volume(sol, estimators.ROBUST_POWER)
        scale = v_host ** (1.0 / 3.0)
        assert v_host == v_jax  # voxel counts times pitch^3: the same float64 product
        assert np.abs(c_host - c_jax).max() < 1e-6 * scale, file
        assert np.abs(c_host - scipy_center_volume(sol, estimators.ROBUST_POWER)[0]).max() < 1e-12 * scale, file


def test_vmap_over_a_batch_of_grids_equals_single_calls():
    rng = np.random.default_rng(0)
    grids = np.zeros((3, 16, 16, 16), bool)
    for b, r in enumerate((4, 5, 6)):
        idx = np.indices((16, 16, 16)) - 7.5 - rng.uniform(-1, 1, (3, 1, 1, 1))
        grids[b] = np.sum(idx**2, axis=0) < r * r
    occupied = np.zeros_like(grids)
    origin, pitch = jnp.zeros(3), jnp.float32(0.1)
    batched = jax.vmap(lambda g, o: moments.robust_moments(g, o, origin, pitch, 4.0, 0.5))(grids, occupied)
    for b in range(3):
        one = moments.robust_moments(grids[b], occupied[b], origin, pitch, 4.0, 0.5)
        np.testing.assert_allclose(np.asarray(batched.center[b]), np.asarray(one.center), rtol=1e-6)
        assert float(batched.volume[b]) == pytest.approx(float(one.volume), rel=1e-6)


def test_occupied_none_is_a_mesh_solids_no_straddling_voxels():
    """robust_moments(sol.inside, sol.occupied, ...) of a mesh Solid (occupied None) was JAX's
    TypeError "unsupported operand type(s) for &: 'DynamicJaxprTracer' and 'NoneType'"; None means
    no voxel straddles the surface: scipy's depth^4-weighted center and the voxel count's volume
    (the 16^3 grids of the vmap test above: its program)."""
    idx = np.indices((16, 16, 16)) - 7.5 - np.array([0.3, -0.2, 0.6])[:, None, None, None]
    grid = np.sum(idx**2, axis=0) < 5 * 5
    origin, pitch = jnp.zeros(3), jnp.float32(0.1)
    mom = moments.robust_moments(grid, None, origin, pitch, 4.0, 0.5)
    d = np.maximum(ndimage.distance_transform_edt(grid) - 0.5, 0.0)[grid]
    w = (d / d.max()) ** 4.0
    want = (w @ (0.1 * (np.stack(np.nonzero(grid), axis=1) + 0.5))) / w.sum()
    np.testing.assert_allclose(np.asarray(mom.center), want, atol=1e-6)
    assert float(mom.volume) == pytest.approx(grid.sum() * 0.1**3, rel=1e-6)


def power_gradients(sol, power=estimators.ROBUST_POWER, step=0.01):
    """jax.grad of the center (3,) and scale in the power, and 1 % central differences."""
    def center_scale(p):  # world units (the affine map of the voxel units, in JAX's float)
        mom = moments.solid_moments(sol, p)
        frame = jnp.asarray(sol.frame, mom.center.dtype)
        return (sol.origin + sol.pitch * mom.center) @ frame, sol.pitch * mom.volume ** (1.0 / 3.0)

    grad_c = jax.jacfwd(lambda p: center_scale(p)[0])(power)
    grad_s = jax.grad(lambda p: center_scale(p)[1])(power)
    hi, lo = center_scale(power * (1 + step)), center_scale(power * (1 - step))
    fd_c = (np.asarray(hi[0], float) - np.asarray(lo[0], float)) / (2 * step * power)
    fd_s = (float(hi[1]) - float(lo[1])) / (2 * step * power)
    return np.asarray(grad_c, float), float(grad_s), fd_c, fd_s


def check_gradients(sol, scale):
    grad_c, grad_s, fd_c, fd_s = power_gradients(sol)
    assert np.all(np.isfinite(grad_c)) and np.isfinite(grad_s)
    # the center moves with the power (toward the deep part); the scale (a volume) does not depend on it
    assert np.linalg.norm(fd_c) > 1e-4 * scale
    np.testing.assert_allclose(grad_c, fd_c, rtol=0.1, atol=0.1 * np.linalg.norm(fd_c))
    assert grad_s == 0.0 and fd_s == 0.0


def test_power_gradient_matches_central_differences(shape_solid):
    check_gradients(shape_solid, 1.0)


@pytest.mark.shared
@pytest.mark.parametrize("path", ["faust-dev/tr_reg_000.ply", "faust-dev/tr_reg_015.ply", "kids-dev/kid_0001/pose_03.ply"])
def test_power_gradient_on_dev_shapes(path):
    file = SHARED / "data" / path
    if not file.exists():
        pytest.skip("../shared data is not available")
    geometry, _ = estimators.centered(mesh.load(file))
    sol = estimators._robust_solid(geometry, solid.RESOLUTION)
    check_gradients(sol, float(np.ptp(geometry.vertices, axis=0).max()))


def test_robust_moments_and_depth_weights_check_their_arguments():
    """moments.robust_moments and depth.depth_weights (public, jittable): arguments of other shapes
    and a bad power are refused by name before anything compiles; they were JAX's 'Incompatible
    shapes for broadcasting' (a (2,) power; occupied of another shape), an IndexError (a 2-D grid),
    a silently wrong center (a (2,) origin read as (o0, o1, o1)) or weights above 1 (power -2)."""
    from jaxpose import depth

    inside, occupied = np.ones((4, 4, 4), bool), np.zeros((4, 4, 4), bool)
    origin, pitch = np.zeros(3), 1.0
    refused = [
        (lambda: moments.robust_moments(inside[0], occupied[0], origin, pitch, 2.0, 0.5), r"^inside must be a 3-D grid"),
        (lambda: moments.robust_moments(inside, occupied[:3], origin, pitch, 2.0, 0.5), r"^occupied must have shape \(4, 4, 4\)"),
        (lambda: moments.robust_moments(inside, occupied, np.zeros(2), pitch, 2.0, 0.5), r"^origin must have shape \(3,\)"),
        (lambda: moments.robust_moments(inside, occupied, origin, np.ones(3), 2.0, 0.5), r"^pitch must have shape \(\)"),
        (lambda: moments.robust_moments(inside, occupied, origin, pitch, np.ones(2), 0.5), r"^power must be a finite number >= 0"),
        (lambda: moments.robust_moments(inside, occupied, origin, pitch, -2.0, 0.5), r"^power must be a finite number >= 0"),
        (lambda: jax.jit(lambda p: moments.robust_moments(inside, occupied, origin, pitch, p, 0.5).center)(np.ones(2)),
         r"^power must be a real scalar, got a traced float32\[2\]"),
        (lambda: depth.depth_weights(inside, -2.0), r"^power must be a finite number >= 0"),
        (lambda: depth.depth_weights(inside, 2.0, bias=np.ones(2)), r"^bias must be a scalar"),
        # a NaN bias weighed every cell 0 (moments of zero mass) without a word; a string was JAX's TypeError
        (lambda: depth.depth_weights(inside, 2.0, bias=np.nan), r"^bias must be a finite number >= 0, got nan"),
        (lambda: depth.depth_weights(inside, 2.0, bias="x"), r"^bias must be a finite number >= 0, got 'x'"),
        (lambda: moments.robust_moments(inside, occupied, origin, pitch, 2.0, np.nan), r"^bias must be a finite number >= 0"),
        (lambda: jax.jit(lambda p: depth.depth_weights(inside, p))(jnp.asarray(2.0 + 0j)),
         r"^power must be a real scalar, got a traced complex64\[\]"),
        # a (2,) extent of a 3-D grid was read as (e0, e1, e1) (JAX clamps the index): silently another grid
        (lambda: depth.distance(inside, np.array([4, 4])), r"^extent must have shape \(3,\), one count per axis"),
        (lambda: depth.depth_weights(inside, 2.0, extent=np.array([4, 4])), r"^extent must have shape \(3,\)"),
    ]
    for call, message in refused:
        with pytest.raises(InvalidInputError, match=message):
            call()


def test_weighted_moments_refuse_points_in_place_of_three_axes():
    """weighted.weighted_center / weighted_moments take 3 coordinate arrays; an (n, 3) array of
    points was read as n axes (a center of n coordinates, or NumPy's broadcasting error); refused
    with the fix. Its transpose gives the points' mean (NumPy's, the oracle)."""
    from jaxpose import weighted

    points, w = np.random.default_rng(0).normal(size=(10, 3)), np.ones(10)
    for call in (weighted.weighted_center, weighted.weighted_moments):
        with pytest.raises(InvalidInputError, match=r"^x must be 3 coordinate arrays .* shape \(10, 3\): pass points.T"):
            call(points, w)
        with pytest.raises(InvalidInputError, match=r"^x must be 3 coordinate arrays .*, got 2 arrays"):
            call([points[:, 0], points[:, 1]], w)
        np.testing.assert_allclose(call(points.T, w)[1], points.mean(axis=0), rtol=1e-12)


def test_grid_moments_checks_its_arguments():
    """weighted.grid_moments (public, NumPy and JAX) checked nothing: a (2,) origin was read as
    (o0, o1, o1) in JAX (its indexing clamps) and a (4,) one as its first three, an occupancy of
    another shape gave another grid's volume, a (3,) pitch NumPy's broadcasting error, a 2-D grid
    the same; integer weights failed in finfo ('not inexact'), bool weights in arange. Shapes are
    refused by name (while tracing too); integer and bool weights are taken as floats."""
    from jaxpose.weighted import grid_moments

    occ = np.zeros((8, 8, 8))
    occ[2:6, 2:6, 2:6] = 1.0
    origin = np.array([0.3, 0.3, 0.3])
    want = grid_moments(occ, occ, origin, 0.5)
    np.testing.assert_allclose(want.center, [2.3, 2.3, 2.3], rtol=1e-12)
    refused = [
        (lambda: grid_moments(jnp.asarray(occ), jnp.asarray(occ), jnp.array([0.3, 0.3]), 0.5), r"^origin must have shape \(3,\), got \(2,\)$"),
        (lambda: grid_moments(jnp.asarray(occ), jnp.asarray(occ), jnp.array([0.3, 0.3, 0.3, 9.0]), 0.5), r"^origin must have shape \(3,\)"),
        (lambda: grid_moments(occ[:4], occ, origin, 0.5), r"^occupancy must have shape \(8, 8, 8\), the shape of weights, got \(4, 8, 8\)$"),
        (lambda: grid_moments(occ, occ, origin, np.full(3, 0.5)), r"^pitch must have shape \(\), got \(3,\)$"),
        (lambda: grid_moments(occ[0], occ[0], origin, 0.5), r"^weights must be a 3-D grid \(nx, ny, nz\), got shape \(8, 8\)$"),
        (lambda: grid_moments(occ, occ + 1j, origin, 0.5), r"^weights must be real numbers, got dtype complex128$"),
        (lambda: jax.jit(lambda o: grid_moments(jnp.asarray(occ), jnp.asarray(occ), o, 0.5).center)(jnp.zeros(2)),
         r"^origin must have shape \(3,\), got \(2,\)"),
    ]
    for call, message in refused:
        with pytest.raises(InvalidInputError, match=message):
            call()
    for weights in (occ.astype(np.int64), occ.astype(bool)):
        got = grid_moments(occ, weights, origin, 0.5)
        assert got.center.dtype == np.float64
        np.testing.assert_allclose(got.center, want.center, rtol=1e-12)
        np.testing.assert_allclose(got.second_moment, want.second_moment, rtol=1e-12, atol=1e-15)
    got = grid_moments(jnp.asarray(occ), jnp.asarray(occ, jnp.int32), jnp.asarray(origin), 0.5)
    assert got.center.dtype == jnp.result_type(float)
    np.testing.assert_allclose(got.center, want.center, rtol=1e-6)


def test_a_traced_power_out_of_range_weighs_every_voxel_zero():
    """depth_weights and robust_moments return no status, and a traced power cannot be refused: a
    negative one gave weights above 1 (-2: up to 9 on a 4-voxel-deep cube) and a center that looked
    like any other, NaN a NaN grid. Out of [0, inf) (negative, NaN, inf) every weight is 0 now, which
    no power in range gives: finite moments of zero mass (mean distance 0 beside a volume > 0), no
    NaN in the derivative (normalize, which has a status, reports such a power as BAD_PARAMETERS)."""
    from jaxpose import depth

    inside = np.zeros((10, 10, 10), bool)
    inside[2:8, 2:8, 2:8] = True
    occupied = np.zeros_like(inside)
    origin, pitch = np.zeros(3), 1.0
    weights = jax.jit(lambda p: depth.depth_weights(inside, p))
    moments_of = jax.jit(lambda p: moments.robust_moments(inside, occupied, origin, pitch, p, 0.5))
    good = moments_of(2.0)
    assert float(jnp.max(weights(2.0))) == 1.0 and float(good.mean_distance) > 0
    for bad in (-2.0, np.nan, np.inf, -np.inf):
        w = weights(bad)
        assert float(jnp.max(w)) == 0.0 and float(jnp.min(w)) == 0.0, bad
        mom = moments_of(bad)
        for name, value in mom._asdict().items():
            assert np.all(np.isfinite(np.asarray(value))), (bad, name)
        assert float(mom.mean_distance) == 0.0 and float(mom.volume) == float(good.volume) > 0, bad
        np.testing.assert_array_equal(mom.center, np.zeros(3))
        grad = jax.grad(lambda p: jnp.sum(depth.depth_weights(inside, p)) + moments.robust_moments(
            inside, occupied, origin, pitch, p, 0.5).center[0])(jnp.float32(bad))
        assert float(grad) == 0.0, (bad, grad)
    # in range, unchanged: the host's weights (scipy's distances) equal the JAX path's
    from jaxpose.weighted import depth_power_weights

    host = depth_power_weights(ndimage.distance_transform_edt(inside), inside, 2.0, 0.5)
    np.testing.assert_allclose(np.asarray(depth.depth_weights(inside, 2.0, 0.5)), host, rtol=1e-6)


@pytest.mark.parametrize("enable_x64", [False, True])
def test_lists_compute_as_their_numpy_arrays(enable_x64):
    """A Python list (concrete, of Python floats: float64) went to jax.numpy: with x64 off an origin
    [1e4 + 0.1, 0, 0] beside float64 NumPy grids gave a float32 center (10001.099609), and a list of
    weights or depths failed inside the arithmetic (TypeError). Now a list computes as its NumPy array,
    float64 on the host, with x64 on or off; a list holding a JAX value still goes to JAX."""
    from jaxpose import weighted
    from jaxpose.backend import array_namespace

    old = jax.config.jax_enable_x64
    jax.config.update("jax_enable_x64", enable_x64)
    try:
        occ = np.zeros((4, 4, 4))
        occ[1:3, 1:3, 1:3] = 1.0
        origin = [1e4 + 0.1, 0.0, 0.0]
        want = weighted.grid_moments(occ, occ, np.asarray(origin), 0.5)
        for args in ((occ, occ, origin, 0.5), (occ.tolist(), occ.tolist(), origin, 0.5)):
            got = weighted.grid_moments(*args)
            assert isinstance(got.center, np.ndarray) and got.center.dtype == np.float64
            np.testing.assert_array_equal(got.center, want.center)
        x = [[1e4 + 0.1, 1e4 + 0.3], [0.0, 1.0], [0.0, 0.0]]
        mass, center, _, _ = weighted.weighted_moments(x, [1.0, 1.0])
        assert center.dtype == np.float64 and center[0] == np.mean([1e4 + 0.1, 1e4 + 0.3])
        d = np.array([[[0.0, 1.0, 2.0]]])
        np.testing.assert_array_equal(weighted.depth_power_weights(d.tolist(), (d > 0).tolist(), 2.0),
                                      weighted.depth_power_weights(d, d > 0, 2.0))
        assert array_namespace([1.0, (2.0, np.float64(3.0))]) is np
        assert array_namespace([1.0, jnp.ones(())]) is jnp
    finally:
        jax.config.update("jax_enable_x64", old)
