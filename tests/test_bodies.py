"""benchmarks/bodies.py (issue 34's research record): its measures against closed forms."""
import numpy as np
import pytest
import trimesh
from scipy import ndimage

from benchmarks import bodies


def test_capped_volume_is_the_closed_form_and_caps_a_planar_hole():
    closed = trimesh.creation.icosphere(subdivisions=3, radius=2.0)
    assert bodies.capped_volume(closed.vertices, closed.faces) == pytest.approx(closed.volume, rel=1e-12)
    box = trimesh.creation.box(extents=(1.0, 2.0, 3.0))
    top = np.flatnonzero(np.isclose(box.triangles_center[:, 2], 1.5))
    assert len(top) == 2  # the square face z = 1.5, two triangles
    opened = np.delete(box.faces, top, axis=0)
    assert bodies.capped_volume(box.vertices, opened) == pytest.approx(6.0, rel=1e-12)  # a flat cap is exact


def test_local_thickness_of_two_balls():
    """Two separate balls of radius 9 and 4 voxels: every voxel's thickness is about its ball's
    radius (within the lattice's 1-2 voxels), whatever its depth; its depth is not."""
    grid = np.indices((60, 30, 30)).transpose(1, 2, 3, 0) + 0.5
    big = np.sum((grid - (15, 15, 15)) ** 2, axis=-1) < 9 ** 2
    small = np.sum((grid - (45, 15, 15)) ** 2, axis=-1) < 4 ** 2
    inside = big | small
    depth = ndimage.distance_transform_edt(inside)
    t = bodies.local_thickness(inside, depth)
    assert np.all(t[~inside] == 0)
    assert 6.5 <= t[big].min() and t[big].max() <= 9 and 2 <= t[small].min() and t[small].max() <= 4
    rim = big & (depth < 2)
    assert rim.sum() > 0.4 * big.sum() and t[rim].min() >= 6.5  # the rim of the big ball is thick, not shallow


def test_spreads_by_hand():
    sigma, cv = bodies.spreads([[0, 0, 0], [2, 0, 0]], [1.0, 3.0])
    assert sigma == pytest.approx(1.0) and cv == pytest.approx(0.5)
