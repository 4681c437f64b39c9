"""The fast OFF and PLY writers against trimesh's exporters: the same bytes."""
from __future__ import annotations

import numpy as np
import pytest
import trimesh

from jaxpose.io import writers
from jaxpose.io.readers import Unsupported

# values whose 10th decimal is a tie, or close to one, signed zeros, sub-1e-10 magnitudes
AWKWARD = [[0.00048828125, -0.00048828125, 0.0], [-0.0, 1e-13, -1e-13], [0.5, 1.5, 2.5],
           [3 * 2.0**-11, 123456.00000000005, -0.99999999995], [1e-10, 5e-11, 1.5e-10],
           [449999.9999999999, -449999.0, 2.0**-30]]


@pytest.mark.parametrize("exponent", [-12, -8, -3, 0, 2, 5])
def test_off_bytes_equal_trimesh(exponent):
    rng = np.random.default_rng(exponent + 20)
    vertices = np.concatenate([AWKWARD, rng.normal(size=(3000, 3)) * 10.0**exponent,
                               np.round(rng.normal(size=(500, 3)) * 2**20) / 2**30])
    vertices = vertices[np.all(np.abs(vertices) < 4.5e5, axis=1)]
    faces = rng.integers(0, len(vertices), size=(4000, 3))
    expected = trimesh.Trimesh(vertices, faces, process=False).export(file_type="off").encode()
    assert writers.off_bytes(vertices, faces) == expected


@pytest.mark.parametrize("top", [0, 9, 10, 99999, 100000, 999999])
def test_off_face_lines_every_index_width(top):
    """Face lines as Python formats them, for indices of 1 to 6 digits."""
    rng = np.random.default_rng(top)
    faces = rng.integers(0, top + 1, size=(300, 3))
    faces[0] = [top, 0, top]
    expected = "".join(f"3 {a} {b} {c}\n" for a, b, c in faces.tolist()).encode()
    assert writers._triangles(faces) == expected


def test_off_bytes_refuses_what_it_cannot_format():
    faces = np.array([[0, 1, 2]])
    with pytest.raises(Unsupported):
        writers.off_bytes(np.array([[0.0, 0, 0], [1, 0, 0], [5e5, 1, 0]]), faces)
    with pytest.raises(Unsupported):
        writers.off_bytes(np.array([[0.0, 0, 0], [1, 0, 0], [np.nan, 1, 0]]), faces)
    with pytest.raises(Unsupported):
        writers.off_bytes(np.zeros((3, 3)), np.array([[0, 1, 3]]))  # no vertex 3
    with pytest.raises(Unsupported):
        writers._triangles(np.array([[0, 1, 10**7]]))  # 8 digits: trimesh writes it


def test_library_encode_uses_it(tmp_path):
    from jaxpose import mesh

    shape = mesh.example_shape()
    assert mesh.encode(shape, "off") == shape.export(file_type="off").encode()
    far = shape.copy()
    far.vertices += 1e6  # beyond the fast writer: trimesh writes it
    assert mesh.encode(far, "off") == far.export(file_type="off").encode()


@pytest.mark.parametrize("exponent", [-8, 0, 5, 30])
def test_ply_bytes_equal_trimesh(exponent):
    rng = np.random.default_rng(exponent + 50)
    vertices = np.concatenate([AWKWARD, rng.normal(size=(2000, 3)) * 10.0**exponent])
    faces = rng.integers(0, len(vertices), size=(3000, 3))
    expected = trimesh.Trimesh(vertices, faces, process=False).export(file_type="ply")
    assert writers.ply_bytes(vertices, faces) == expected


def test_ply_bytes_refuses_what_it_cannot_write():
    with pytest.raises(Unsupported):
        writers.ply_bytes(np.zeros((3, 3)), np.array([[0, 1, 3]]))  # no vertex 3
    with pytest.raises(Unsupported):
        writers.ply_bytes(np.zeros((3, 2)), np.array([[0, 1, 2]]))


@pytest.mark.parametrize("name", ["out.ply", "out.off", "out.obj", "out.stl", "out.xyz"])
def test_non_finite_coordinates_are_not_written(tmp_path, name):
    """A mesh or point cloud with NaN or inf coordinates is refused, and nothing is written (it
    was written: a file that jaxpose's readers refuse)."""
    from jaxpose import mesh
    from jaxpose.errors import InvalidInputError

    box = trimesh.creation.box()
    box.vertices[3] = [np.nan, 0.0, np.inf]
    geometry = trimesh.PointCloud(box.vertices) if name.endswith(".xyz") else box
    with pytest.raises(InvalidInputError, match="NaN or inf"):
        mesh.export(geometry, tmp_path / name)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("name", ["out.ply", "out.stl", "out.glb", "points.ply", "points.glb", "surface.ply"])
def test_coordinates_beyond_float32_are_not_written_as_float32(tmp_path, name):
    """PLY, STL and GLB hold float32 coordinates: one of 1e39 (finite in float64) was cast to inf
    with a RuntimeWarning, and the file written held inf (which jaxpose's readers refuse). Refused
    by name, nothing written; the text formats (float64 digits) write it."""
    from jaxpose import mesh
    from jaxpose.errors import InvalidInputError
    from jaxpose.geometry import Surface

    box = trimesh.creation.box()
    box.vertices[3] = [1e39, 0.0, -2.0]
    geometry = {"out": box, "points": trimesh.PointCloud(box.vertices),
                "surface": Surface(box.vertices, box.faces)}[name.split(".")[0]]
    with pytest.raises(InvalidInputError, match=r"beyond float32's range \(3\.4e\+38\).* largest \|coordinate\| 1e\+39"):
        mesh.export(geometry, tmp_path / name)
    assert list(tmp_path.iterdir()) == []
    for text in ("out.obj", "out.off", "out.xyz"):
        kept = trimesh.PointCloud(box.vertices) if text.endswith(".xyz") else box
        assert mesh.load(mesh.export(kept, tmp_path / text)).vertices.max() == 1e39
    box.vertices[3] = [3.4e38, 0.0, -2.0]  # float32's largest is 3.40282e38: written, as float32
    written = mesh.load(mesh.export(box, tmp_path / "edge.ply")).vertices
    np.testing.assert_array_equal(written, box.vertices.astype(np.float32))


def test_encode_takes_a_format_name_in_any_case():
    """encode(m, "PLY") is encode(m, "ply"): the float32-range check compared the name as given and
    wrote inf into an upper-case "PLY", "STL", "GLB"."""
    from jaxpose import mesh
    from jaxpose.errors import InvalidInputError

    box = trimesh.creation.box()
    assert mesh.encode(box, "OFF") == mesh.encode(box, "off") and mesh.encode(box, "Ply") == mesh.encode(box, "ply")
    box.vertices[3] = [1e39, 0.0, -2.0]
    for name in ("PLY", "Stl", "GLB"):
        with pytest.raises(InvalidInputError, match=rf"beyond float32's range .* as {name.upper()}, which"):
            mesh.encode(box, name)


def test_export_refuses_what_is_not_a_geometry_or_a_path(tmp_path):
    """export("abc", path) was an AttributeError ('str' object has no attribute 'vertices') and
    export(mesh, None) Path()'s TypeError: refused by name, nothing written."""
    from jaxpose import mesh
    from jaxpose.errors import InvalidInputError

    for geometry in ("abc", np.zeros((4, 3)), None):
        with pytest.raises(InvalidInputError, match=r"^cannot write a (str|ndarray|NoneType): give a Trimesh, PointCloud"):
            mesh.export(geometry, tmp_path / "out.ply")
    with pytest.raises(InvalidInputError, match=r"^path must be a str or Path, got None"):
        mesh.export(trimesh.creation.box(), None)
    assert list(tmp_path.iterdir()) == []
