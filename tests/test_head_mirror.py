"""jaxpose.rotation.rotation.left_right with ``beyond`` (the head frame of a point cloud) reads the head's
mirror plane from the head, not from the neck that carries it: a synthetic head surface
(mirror-symmetric about y = 0 only: an ellipsoid with a muzzle ahead) above a neck that leans to one
side, given as the geometry of the ``head`` frame."""
import numpy as np

from jaxpose.rotation import parts, rotation


def _on_ellipsoid(center, radii, n, rng):
    d = rng.normal(size=(n, 3))
    return np.asarray(center) + np.asarray(radii) * d / np.linalg.norm(d, axis=1, keepdims=True)


def _on_tube(a, b, r, n, rng):
    a, b = np.asarray(a, float), np.asarray(b, float)
    axis = (b - a) / np.linalg.norm(b - a)
    d = rng.normal(size=(n, 3))
    d -= (d @ axis)[:, None] * axis
    return a + rng.uniform(0, 1, (n, 1)) * (b - a) + r * d / np.linalg.norm(d, axis=1, keepdims=True)


def _geometry(surface, head_depth):
    """The geometry left_right reads: up z, the neck at the origin, the chest's thinner axis x."""
    found = parts.Parts(None, None, np.zeros(3), head_depth, 0.2, 2.0, 1.0)
    z = np.zeros(3)
    return rotation.HeadChest(found, np.zeros((1, 3)), np.ones(1), np.zeros((1, 3), int), np.zeros(1, bool), z,
                              np.eye(3), z, np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0]), np.ones(2), z,
                              surface, 0.0, z)


def test_the_head_mirror_is_read_beyond_the_neck():
    """Head: an ellipsoid (0.5, 0.4, 0.6) centered 1.2 above the neck, head depth 0.4, with a
    muzzle (a ball, 0.2) ahead (+x): mirror-symmetric about y = 0 only. Neck: a tube (0.25) from
    the neck leaning 0.45 to +y, all of it within MIRROR_BEYOND head depths of the neck. Read
    from the whole surface the mirror plane tilts away from y (the neck's lean); read beyond the
    neck (left_right with beyond = MIRROR_BEYOND, as for a point cloud) its normal is y within 3 degrees, the head's clear plane (contrast > 0.5),
    and the head took part (True)."""
    rng = np.random.default_rng(0)
    head = np.concatenate([_on_ellipsoid((0, 0, 1.2), (0.5, 0.4, 0.6), 3000, rng),
                           _on_ellipsoid((0.55, 0, 1.0), (0.2, 0.2, 0.2), 600, rng)])
    head = head[head[:, 2] > 0.0]
    neck = _on_tube((0, 0.45, -0.2), (0, 0.1, rotation.MIRROR_BEYOND * 0.4), 0.25, 3000, rng)
    surface = np.concatenate([head, neck])
    x, y = np.eye(3)[0], np.eye(3)[1]
    whole, _ = rotation.head_mirror(surface, x, y)
    assert np.degrees(np.arccos(abs(whole @ y))) > 10.0  # the neck's lean turns the whole surface's plane
    lr, contrast, chosen = rotation.left_right(None, _geometry(surface, 0.4), rotation.MIRROR_BEYOND)
    assert np.degrees(np.arccos(abs(lr @ y))) < 3.0 and contrast > 0.5 and chosen is True
    alone, c_alone = rotation.head_mirror(surface[surface[:, 2] > rotation.MIRROR_BEYOND * 0.4], x, y)
    assert abs(alone @ y) > np.cos(np.radians(3.0)) and abs(contrast - c_alone) < 1e-12
