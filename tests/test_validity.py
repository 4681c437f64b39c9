"""When a pose is valid: each status code on a synthetic shape made to trigger it, the helpers
against scipy, and the messages that errors and warnings carry."""
import numpy as np
import pytest
import trimesh

import jaxpose
from jaxpose import InvalidInputError, InvalidPoseWarning, JaxposeError, Status
from jaxpose.pose import validity
from jaxpose.pose.validity import MAX_CELL, MAX_SPACING, median_distance, median_spacing, status_message
from conftest import sphere_with_arm

# test_gradients.py's small grid (the same options; other point counts, so not its compiled program):
# 8 coarse cells per axis, refined once
SMALL = dict(resolution=8, refine=2, band=256, tol=1e-4)


def test_helpers_match_scipy():
    from scipy.spatial import cKDTree

    rng = np.random.default_rng(0)
    y = rng.normal(size=(301, 3))
    mask = np.arange(301) < 250  # the last rows are padding
    nn = cKDTree(y[:250]).query(y[:250], k=2)[0][:, 1]
    assert float(median_spacing(y, mask, block=64)) == pytest.approx(np.sort(nn)[124], rel=1e-5)  # lower median
    d = np.linalg.norm(y[:250] - 0.1, axis=1)
    assert float(median_distance(y, np.full(3, 0.1), mask)) == pytest.approx(np.sort(d)[124], rel=1e-5)
    assert float(median_spacing(np.r_[y, y])) == 0.0  # repeated points


def test_status_codes_and_messages():
    assert [int(s) for s in Status] == list(range(13)) and Status(0) is Status.OK
    assert "too sparse" in status_message(np.int32(3)) and "does not resolve" in Status.UNRESOLVED_GRID.message
    assert "collapsed" in Status.COLLAPSED_REGION.message and "no extent" in Status.DEGENERATE_INPUT.message
    pose = jaxpose.Pose.from_center_scale(np.zeros(3), 1.0)
    assert int(pose.status) == 0 and pose.count is None
    assert int(jaxpose.Pose.from_center_scale(np.zeros(3), -1.0).status) == Status.NOT_FINITE


def test_status_message_refuses_what_is_no_status_code_by_name():
    """status_message reads one concrete code: True was BAD_PARAMETERS and 1.9 was 1 (int()), a traced
    code JAX's ConcretizationTypeError, a batch's codes NumPy's TypeError, 99 enum's ValueError."""
    import jax
    import jax.numpy as jnp

    assert status_message(jnp.int32(2)) == status_message(np.array(2)) == Status.DEGENERATE_INPUT.message
    for code, message in [(True, "^code must be an int"), (1.9, "^code must be an int"),
                          (np.array([0, 2]), "^code must be an int"), (99, r"^code 99 is no Status code; valid: 0 \.\.\. 12"),
                          (-1, "^code must be >= 0")]:
        with pytest.raises(InvalidInputError, match=message):
            status_message(code)
    with pytest.raises(InvalidInputError, match="^code must be a concrete int, not a traced value"):
        jax.jit(lambda c: len(status_message(c)) + c)(jnp.int32(2))


def test_too_few_samples_are_not_a_plain_number():
    """8 samples of a sphere: each sample's kernel is alone (spacing 7 kernel widths): not valid,
    with a warning; an error through normalize_mesh."""
    sphere = trimesh.creation.icosphere(subdivisions=2)
    points = jaxpose.sample_surface(sphere, 8, seed=0)
    with pytest.warns(InvalidPoseWarning, match="too sparse for gamma"):
        pose = jaxpose.normalize(points, method="ocsvm")
    assert not bool(pose.valid) and int(pose.status) == Status.SPARSE_SAMPLES and int(pose.count) == 8
    with pytest.raises(JaxposeError, match="no valid pose .*too sparse"):
        jaxpose.normalize(points, method="ocsvm", throw=True)
    with pytest.raises(JaxposeError, match="ocsvm estimator gave no valid pose: the samples are too sparse"):
        jaxpose.normalize_mesh(sphere, method="ocsvm", count=8)


def test_a_grid_dependent_result_is_flagged(x64):
    """gamma = 200 on a 8^3 grid refined once: cells of 3 kernel widths. The center then depends
    on the grid (it moves by more than 1 % of the scale at 32^3, whose cells resolve the kernel):
    UNRESOLVED_GRID, not valid."""
    pts = sphere_with_arm(400, seed=1)
    with pytest.warns(InvalidPoseWarning, match="does not resolve the kernel"):
        coarse = jaxpose.normalize(pts, method="ocsvm", gamma=200.0, nu=0.5, **SMALL)
    assert int(coarse.status) == Status.UNRESOLVED_GRID and not bool(coarse.valid)
    fine = jaxpose.normalize(pts, method="ocsvm", gamma=200.0, nu=0.5, resolution=32)  # the pinned results' compilation
    assert bool(fine.valid)
    assert np.max(np.abs(np.asarray(coarse.center) - np.asarray(fine.center))) > 1e-2 * float(fine.scale)
    assert MAX_CELL == MAX_SPACING == 2.0


def test_status_per_object_of_a_batch():
    """Each object of a batch carries its own status; an error names the first invalid one."""
    pts = sphere_with_arm(400, seed=1)
    few = jaxpose.sample_surface(trimesh.creation.icosphere(subdivisions=2), 8, seed=0)
    with pytest.warns(InvalidPoseWarning, match=r"point set 1: the samples are too sparse"):
        batch = jaxpose.normalize_batch([pts, few], method="ocsvm", resolution=32)  # the pinned batch's compilation
    assert [int(s) for s in batch.status] == [Status.OK, Status.SPARSE_SAMPLES]
    assert [int(c) for c in batch.count] == [400, 8] and list(np.asarray(batch.valid)) == [True, False]
    with pytest.raises(JaxposeError, match=r"no valid pose \(point set 1: the samples are too sparse"):
        jaxpose.normalize_batch([pts, few], method="ocsvm", resolution=32, throw=True)


@pytest.mark.parametrize("call, message", [
    # empty points were "zero-size array to reduction operation min which has no identity" (or an
    # IndexError); other shapes JAX's broadcast or axis errors
    (lambda: median_spacing(np.zeros((0, 3))), r"^y needs at least 1 point, got 0"),
    (lambda: median_spacing(np.ones(3)), r"^y must have shape \(m, 3\), got \(3,\)"),
    (lambda: median_spacing(np.ones((5, 2))), r"^y must have shape \(m, 3\), got \(5, 2\)"),
    (lambda: median_spacing(np.ones((2, 3)), np.ones(3, bool)), r"^mask must have shape \(2,\), one flag per point of y"),
    (lambda: median_distance(np.zeros((0, 3)), np.zeros(3)), r"^y needs at least 1 point, got 0"),
    (lambda: median_distance(np.ones((2, 3)), np.zeros(2)), r"^center must have shape \(3,\), got \(2,\)"),
    (lambda: median_spacing(np.array([["a", "b", "c"]] * 2)), "^y must be real numbers, got dtype <U1"),
    (lambda: validity.no_extent(np.zeros((0, 3))), r"^points needs at least 1 point, got 0"),
    (lambda: validity.unresolved_size(np.zeros((0, 3))), r"^points needs at least 1 point, got 0"),
    (lambda: validity.unresolved_offset(np.zeros((0, 3))), r"^points needs at least 1 point, got 0"),
    (lambda: validity.unresolved_offset(np.ones((2, 2, 3))), r"^points must have shape \(m, 3\), got \(2, 2, 3\)"),
])
def test_checks_refuse_empty_and_misshapen_points_by_name(call, message):
    with pytest.raises(InvalidInputError, match=message):
        call()
    # one and two points are what they are: no other point (inf), the distance of the two
    two = np.array([[0.0, 0.0, 0.0], [3.0, 4.0, 0.0]])
    assert float(median_spacing(two)) == pytest.approx(np.linalg.norm(two[1] - two[0]))
    assert float(median_spacing(two[:1])) == np.inf and bool(validity.no_extent(two[:1]))


def test_range_and_offset_checks_of_integer_points():
    """validity.unresolved_size and unresolved_offset (docs/api.md) of integer points (real numbers,
    as every points argument takes them) leaked JAX's "data type <class 'numpy.int32'> not inexact"
    (finfo of an integer dtype). Integers are judged in the float dtype they compute in (float32
    here, as normalize casts them): the answers of their float32 cast."""
    pts = np.round(sphere_with_arm(64, seed=0) * 100).astype(np.int64)
    for check in (validity.unresolved_size, validity.unresolved_offset):
        assert bool(check(pts)) == bool(check(pts.astype(np.float32))) is False
        assert bool(check(pts, np.arange(64) < 60)) == bool(check(pts.astype(np.float32), np.arange(64) < 60))
    far = pts + 2 ** 20  # (float32's step there, eps 2**20 = 0.125, exceeds 1e-3 of their spread)
    assert bool(validity.unresolved_offset(far)) and bool(validity.unresolved_offset(far.astype(np.float32)))
