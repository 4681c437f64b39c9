"""Vertices and faces of any input, triangle areas, closed surfaces."""
import numpy as np
import pytest
import trimesh

from jaxpose import geometry
from jaxpose._validate import InvalidInputError


def test_split_geometry_of_meshes_clouds_and_arrays():
    box = trimesh.creation.box()
    v, f = geometry.split_geometry(box)
    assert v.dtype == np.float64 and f.dtype == np.int64 and f.shape == (12, 3)
    points = np.random.default_rng(0).normal(size=(10, 3)).astype(np.float32)
    for source in (points, trimesh.PointCloud(points), trimesh.Trimesh(points, np.zeros((0, 3), int), process=False)):
        v, f = geometry.split_geometry(source)
        assert f is None and v.dtype == np.float64
        np.testing.assert_array_equal(v, points.astype(np.float64))


@pytest.mark.parametrize("faces, message", [
    (np.array([[0, 1, 7]]), "do not exist"),
    (np.array([[0, 1]]), r"shape \(f, 3\)"),
    (np.array([[0, 1, 1]]), "no area"),
])
def test_split_geometry_refuses_bad_faces(faces, message):
    vertices = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0.0]])
    mesh = type("M", (), {"vertices": vertices, "faces": faces})()
    with pytest.raises(InvalidInputError, match=message):
        geometry.split_geometry(mesh)


def test_triangle_areas_and_closedness():
    tri = np.array([[[0, 0, 0], [2, 0, 0], [0, 3, 0.0]], [[0, 0, 0], [1, 0, 0], [0, 0, 1.0]]])
    np.testing.assert_allclose(geometry.triangle_areas(tri), [3.0, 0.5])
    box = trimesh.creation.box()
    assert geometry.is_closed(box.faces)
    assert not geometry.is_closed(box.faces[:-1])  # one triangle off: a hole
    assert not geometry.is_closed(np.concatenate([box.faces, box.faces[:1]]))  # an edge shared three times
