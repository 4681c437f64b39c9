"""Reference frames: invariances of the size, equivariance of the axes, float64 host frames."""
import jax.numpy as jnp
import numpy as np
import pytest

from conftest import box_surface
from jaxpose import InvalidInputError
from jaxpose.pose.frame import REFERENCE_RMS, host_frame, prescale, principal_axes, reference_frame


def _rotation(seed):
    q, _ = np.linalg.qr(np.random.default_rng(seed).normal(size=(3, 3)))
    return q * np.sign(np.linalg.det(q))


def test_unit_cube_surface_has_reference_size_one(x64):
    pts = box_surface(20000, seed=0, extents=(1.0, 1.0, 1.0))
    mean, size = reference_frame(jnp.asarray(pts))
    assert np.allclose(np.asarray(mean), 0.0, atol=0.01)
    assert float(size) == pytest.approx(1.0, rel=0.01)  # sqrt(5/12) is the cube surface's RMS radius
    assert REFERENCE_RMS == pytest.approx(np.sqrt(5 / 12))


def test_size_is_similarity_invariant_and_prescale_equivariant(x64):
    pts = box_surface(500, seed=1)
    r, t, s = _rotation(2), np.array([3.0, -1.0, 7.0]), 2.5
    moved = s * pts @ r.T + t
    m0, s0 = reference_frame(jnp.asarray(pts))
    m1, s1 = reference_frame(jnp.asarray(moved))
    assert float(s1) == pytest.approx(s * float(s0), rel=1e-12)
    np.testing.assert_allclose(np.asarray(m1), s * np.asarray(m0) @ r.T + t, atol=1e-12)
    y0, to_world0, _ = prescale(jnp.asarray(pts))
    y1, to_world1, _ = prescale(jnp.asarray(moved))
    # the same points up to the sign of each principal axis
    signs = np.sign(np.sum(np.asarray(y0) * np.asarray(y1), axis=0))
    np.testing.assert_allclose(np.asarray(y1), np.asarray(y0) * signs, atol=1e-10)
    c = jnp.asarray([0.1, -0.2, 0.3])
    np.testing.assert_allclose(np.asarray(to_world1(c * signs)), s * np.asarray(to_world0(c)) @ r.T + t, atol=1e-10)


def test_masked_rows_are_left_out(x64):
    pts = box_surface(300, seed=3)
    padded = np.concatenate([pts, np.full((50, 3), 100.0)])
    mask = np.arange(350) < 300
    a, b = reference_frame(jnp.asarray(pts)), reference_frame(jnp.asarray(padded), jnp.asarray(mask))
    np.testing.assert_allclose(np.asarray(a[0]), np.asarray(b[0]), atol=1e-12)
    assert float(a[1]) == pytest.approx(float(b[1]), rel=1e-12)
    axes = np.asarray(principal_axes(jnp.asarray(pts - pts.mean(0))))
    np.testing.assert_allclose(axes.T @ axes, np.eye(3), atol=1e-12)


@pytest.mark.parametrize("offset", [0.0, 1e6, 1e12])
def test_host_frame_keeps_digits_far_from_the_origin(offset):
    pts = box_surface(200, seed=4)
    mean, rms = host_frame(pts + offset)
    mean0, rms0 = host_frame(pts)
    represented = 4 * offset * np.finfo(np.float64).eps  # what pts + offset can hold of pts
    assert abs(rms - rms0) <= 1e-12 * rms0 + represented
    # the shift is only a translation: the centered points keep their shape to what the input holds
    d = (pts + offset - mean) - (pts - mean0)
    np.testing.assert_allclose(d - d.mean(axis=0), 0.0, atol=1e-12 + represented)
    summed = len(pts) * np.finfo(np.float64).eps * (offset + 1.0)  # rounding bound of a float64 mean
    np.testing.assert_allclose(mean - offset, mean0, rtol=0, atol=summed)


def test_host_frame_refuses_what_the_dtype_cannot_hold():
    with pytest.raises(InvalidInputError, match="outside the range"):
        host_frame(np.full((4, 3), 1e300) * np.arange(4)[:, None])


def test_frames_refuse_empty_and_misshapen_points_by_name():
    """prescale of one point (3,) or a batch (2, 2, 3) was einsum's 'subscript ... does not contain
    the correct number of indices'; reference_frame of no points a NaN mean and size; host_frame of
    none NumPy's 'zero-size array to reduction operation maximum'. Refused by name
    (_validate.check_array, the library's rule; the mask's shape by check_mask) before anything is
    traced; a single point is what it is (its own mean, size 0)."""
    for call, message in (
            (lambda: prescale(np.ones(3)), r"^points must have shape \(m, 3\), got \(3,\)"),
            (lambda: prescale(np.ones((2, 2, 3))), r"^points must have shape \(m, 3\), got \(2, 2, 3\)"),
            (lambda: prescale(np.ones((4, 3)), np.ones(3, bool)), r"^mask must have shape \(4,\), one flag per point"),
            (lambda: reference_frame(np.zeros((0, 3))), r"^points needs at least 1 point, got 0$"),
            (lambda: principal_axes(np.ones((4, 2))), r"^y must have shape \(m, 3\), got \(4, 2\)"),
            (lambda: host_frame(np.zeros((0, 3))), r"^points needs at least 1 point, got 0$"),
            (lambda: host_frame(np.zeros((0, 3)), name="the model's points"), "^the model's points needs at least 1 point")):
        with pytest.raises(InvalidInputError, match=message):
            call()
    one = np.array([[1.0, 2.0, 3.0]])
    # one point, or one repeated, read "span 0 ...: outside the range of float32 (rescale the input, or
    # enable jax_enable_x64)": no rescaling or x64 gives them a spread
    for same, what in ((one, "one point"), (np.repeat(one, 5, axis=0), "all 5 identical")):
        with pytest.raises(InvalidInputError, match=rf"^points have no spread to scale by \({what}\)"):
            host_frame(same)
    mean, size = host_frame(np.r_[one, one + [0.0, 0.0, 2.0]])
    np.testing.assert_allclose(mean, [1.0, 2.0, 4.0])
    assert size == pytest.approx(1.0)  # each point 1 from their mean
