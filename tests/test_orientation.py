"""The frame's pieces: proper rotations, eigen-axes and gaps, the sign rule, the ambiguity, the traced frame."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import jaxpose
from jaxpose import orientation


def test_proper_negates_the_last_row_of_a_reflection():
    q = Rotation.random(random_state=0).as_matrix()
    np.testing.assert_array_equal(orientation.proper(q), q)
    m = q * np.array([1.0, 1.0, -1.0])[:, None]
    r = orientation.proper(m)
    assert np.linalg.det(r) == pytest.approx(1.0)
    np.testing.assert_allclose(r, q, atol=0)


def test_descending_axes_and_relative_gaps_of_a_known_covariance():
    q = Rotation.random(random_state=1).as_matrix()
    lam, axes = orientation.descending_axes(q.T @ np.diag([9.0, 4.0, 1.0]) @ q)
    np.testing.assert_allclose(lam, [9.0, 4.0, 1.0], rtol=1e-12)
    np.testing.assert_allclose(np.abs(axes @ q.T), np.eye(3), atol=1e-12)  # rows = the rows of q, up to sign
    np.testing.assert_allclose(orientation.relative_gaps(lam), [5.0 / 9.0, 3.0 / 4.0], rtol=1e-12)


def test_gaps_of_degenerate_point_sets_lie_in_0_1():
    """A PCA frame of 2 points reported the gap (l2 - l3) / l2 = 1.068 (l2 = 2.8e-17 and l3 =
    -1.9e-18: rounding of two zero eigenvalues). Gaps lie in [0, 1]; eigenvalues at rounding level
    are 0, and two zeros have gap 0 (the minor axes of a straight set are not determined)."""
    from jaxpose import baselines

    rng = np.random.default_rng(0)
    line = np.outer(rng.normal(size=50), [1.0, 0.3, 0.7]) + [5.0, -2.0, 1.0]
    flat = np.column_stack([rng.normal(size=(50, 2)) * [2.0, 1.0], np.zeros(50)]) @ Rotation.random(random_state=4).as_matrix()
    two = np.array([[0.0, 0.0, 0.0], [1.0, 0.3, 0.7]])
    for points, expected in ((two, [1.0, 0.0]), (line, [1.0, 0.0]), (flat[:3], None), (flat, None)):
        gaps = baselines.pca_vertices_frame(points).gaps
        assert np.all((gaps >= 0) & (gaps <= 1)), gaps
        if expected is not None:
            np.testing.assert_array_equal(gaps, expected)
        else:  # a flat set: its normal is determined
            assert gaps[1] == 1.0
    np.testing.assert_array_equal(orientation.relative_gaps([0.395, 2.8e-17, -1.9e-18]), [1.0, 0.0])
    np.testing.assert_array_equal(orientation.relative_gaps([4.0, 1.0, -1e-15]), [0.75, 1.0])


def test_complete_signs_follows_the_stats_and_completes_by_det():
    axes = np.eye(3)
    r, margins, k = orientation.complete_signs(axes, [-0.5, 0.3, 0.01])
    assert k == 2 and np.linalg.det(r) == pytest.approx(1.0)
    np.testing.assert_array_equal(r[0], [-1, 0, 0])  # flipped to its positive stat
    np.testing.assert_array_equal(r[1], [0, 1, 0])
    np.testing.assert_array_equal(r[2], [0, 0, -1])  # the weakest axis completes det = +1
    np.testing.assert_array_equal(margins, [0.5, 0.3, 0.0])
    # a chosen axis, and grid axes given in world coordinates
    world = Rotation.random(random_state=2).as_matrix()
    r2, _, k2 = orientation.complete_signs(axes, [-0.5, 0.3, 0.01], completed=1, to_world=world)
    assert k2 == 1 and np.linalg.det(r2) == pytest.approx(1.0)
    np.testing.assert_allclose(r2[0], -world[0], atol=1e-15)
    np.testing.assert_allclose(r2[2], world[2], atol=1e-15)


@pytest.mark.parametrize("gaps, sign, contrast, expected", [
    ((0.5, 0.5), 3.0, None, 0.0),                      # every cue clears its threshold
    ((0.05, 0.5), 3.0, None, 0.5),                     # half the eigen-gap threshold
    ((0.5, 0.5), 0.25, None, 0.75),                    # a quarter of the sign threshold
    ((0.5, 0.5), 3.0, 0.5 * orientation.SYMMETRY_MIN, 0.5),
    ((0.0, 0.5), 3.0, None, 1.0),                      # equal eigenvalues: undetermined
])
def test_ambiguity_is_the_weakest_cue_against_its_threshold(gaps, sign, contrast, expected):
    assert orientation.ambiguity(np.array(gaps), sign, contrast) == pytest.approx(expected)


def test_region_frame_of_a_known_moment_and_skewed_points(x64):
    """The traced frame: axes of the second moment, signs by the samples' third moments, det +1,
    mapped to the world by the pre-frame's axes; a skew-free input is flagged."""
    import jax.numpy as jnp

    rng = np.random.default_rng(0)
    y = rng.normal(size=(4000, 3)) * [3.0, 2.0, 1.0]
    y[:, 0] = np.abs(y[:, 0]) - 1.0   # skewed along +x
    y[:, 1] = -np.abs(y[:, 1]) + 1.0  # skewed along -y
    second = np.diag([9.0, 4.0, 1.0])
    world = Rotation.random(random_state=3).as_matrix()  # columns: pre-frame axes in the world
    rot, amb = orientation.region_frame(jnp.asarray(second), jnp.zeros(3), jnp.asarray(y), None, jnp.asarray(world))
    rot = np.asarray(rot)
    assert np.linalg.det(rot) == pytest.approx(1.0)
    np.testing.assert_allclose(rot[0], world[:, 0], atol=1e-12)
    np.testing.assert_allclose(rot[1], -world[:, 1], atol=1e-12)
    assert float(amb) == 0.0
    sym = np.concatenate([y * [1, 1, 1], y * [-1, -1, 1]])  # point-symmetric in x, y: no skew
    _, amb_sym = orientation.region_frame(jnp.asarray(second), jnp.zeros(3), jnp.asarray(sym), None, jnp.asarray(world))
    assert float(amb_sym) > 0.0


@pytest.mark.parametrize("call, message", [
    # each was NumPy's IndexError, LinAlgError, broadcast error or abs()'s TypeError, naming no argument
    (lambda: orientation.relative_gaps([2.0, 1.0]), r"^lam must be real numbers of shape \(3,\), got float64 of shape \(2,\)"),
    (lambda: orientation.relative_gaps([]), r"^lam must be .* shape \(0,\)"),
    (lambda: orientation.relative_gaps(np.eye(3)), r"^lam must be .* shape \(3, 3\)"),  # NumPy's 'truth value ... ambiguous'
    (lambda: orientation.ambiguity([0.5], 1.0), r"^gaps must be real numbers of shape \(2,\)"),
    (lambda: orientation.ambiguity([0.5, 0.5], [1.0, 2.0, 3.0]), r"^sign_ratio must be real numbers of shape \(\)"),
    (lambda: orientation.ambiguity([0.5, 0.5], 1.0, [0.1, 0.2]), r"^contrast must be real numbers of shape \(\)"),
    (lambda: orientation.proper(np.ones(3)), r"^r must be real numbers of shape \(3, 3\)"),
    (lambda: orientation.descending_axes(np.eye(2)), r"^cov must be real numbers of shape \(3, 3\)"),
    (lambda: orientation.descending_axes(np.full((3, 3), np.nan)), "^cov must be finite"),  # 'Eigenvalues did not converge'
    (lambda: orientation.complete_signs(np.eye(3), [1.0, 2.0]), r"^stat must be real numbers of shape \(3,\)"),
    (lambda: orientation.complete_signs(np.eye(3), [1.0, 2.0, 3.0], completed=5), "^completed must be an axis, 0, 1 or 2"),
    (lambda: orientation.complete_signs(np.eye(3), [1.0, 2.0, 3.0], to_world=np.eye(2)), r"^to_world must be .* \(3, 3\)"),
    (lambda: orientation.region_frame(np.eye(2), np.zeros(3), np.ones((4, 3)), None, np.eye(3)),
     r"^second_moment must have shape \(3, 3\), got \(2, 2\)"),  # JAX's dot_general error
    (lambda: orientation.region_frame(np.eye(3), np.zeros(3), np.ones(3), None, np.eye(3)), r"^y must have shape \(m, 3\)"),
])
def test_frame_pieces_refuse_other_shapes_by_name(call, message):
    with pytest.raises(jaxpose.InvalidInputError, match=message):
        call()
    # what they take is unchanged: three eigenvalues, two gaps (closed forms)
    np.testing.assert_allclose(orientation.relative_gaps([9.0, 4.0, 1.0]), [5.0 / 9.0, 3.0 / 4.0], rtol=1e-15)
    assert orientation.ambiguity([0.05, 0.5], 3.0) == pytest.approx(0.5)


def test_a_nan_cue_is_no_cue():
    """ambiguity took a NaN cue for one that clears its threshold: 0.0 ("well determined") where the
    gaps came first, NaN where a NaN gap did (Python's min skips NaN but after the first). A cue that
    could not be measured determines nothing: ambiguity 1 (flagged); finite cues keep the closed form."""
    for gaps, sign, contrast in (([0.5, 0.5], np.nan, None), ([np.nan, 0.5], 2.0, None), ([0.5, 0.5], 2.0, np.nan)):
        assert orientation.ambiguity(gaps, sign, contrast) == 1.0
    assert orientation.ambiguity([0.5, 0.5], 2.0, 0.5 * orientation.SYMMETRY_MIN) == pytest.approx(0.5)


def test_sign_cues_are_scale_free():
    """The PCA frames (and core's) fed ambiguity a NaN or inf sign cue for float64 points at 1e-120
    or 1e105: their cubed coordinates under- or overflow, the third moments were 0 / 0 or inf, the
    signs unread, and the frame was reported determined (ambiguity 0.0) where the same points at
    unit scale have a sign cue at 0.21 of its threshold (ambiguity 0.79, flagged). orientation.third_moments
    scales such coordinates by a power of 2 first (exact): the frame of a scaled copy is the frame."""
    from jaxpose.rotation.rotation import frame_of

    rng = np.random.default_rng(0)
    pts = rng.normal(size=(300, 3)) * [3.0, 2.0, 1.0]
    pts[:, 0] = np.abs(pts[:, 0]) ** 1.5  # skewed along its long axis
    unit = frame_of(pts, "pca_vertices")
    assert 0 < unit.ambiguity < 1 and np.all(unit.gaps > orientation.GAP_MIN)  # the weak cue is a sign
    for scale in (1e-120, 1e105):
        scaled = frame_of(pts * scale, "pca_vertices")
        np.testing.assert_allclose(scaled.rotation, unit.rotation, atol=1e-12)
        np.testing.assert_allclose(scaled.margins, unit.margins, rtol=1e-12)
        assert scaled.ambiguity == pytest.approx(unit.ambiguity, rel=1e-12)  # was 0.0
    z = np.array([[-1.0, 3.0], [-1.0, -1.0], [2.0, -2.0]])  # closed form: E[z^3] / E[|z|^2]^(3/2)
    want = np.mean(z ** 3, axis=0) / np.mean(np.sum(z * z, axis=1)) ** 1.5
    for scale in (1.0, 1e-150, 1e150):
        np.testing.assert_allclose(orientation.third_moments(z * scale), want, rtol=1e-14)
    with pytest.raises(jaxpose.InvalidInputError, match=r"^z must be real numbers of shape \(n, k\)"):
        orientation.third_moments(np.zeros((0, 3)))
    with pytest.raises(jaxpose.InvalidInputError, match="^r must be finite"):  # was a NaN rotation and a RuntimeWarning
        orientation.proper(np.full((3, 3), np.nan))
