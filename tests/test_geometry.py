"""Vertices and faces of any input, triangle areas, closed surfaces."""
import re

import numpy as np
import pytest
import trimesh

from jaxpose import geometry
from jaxpose.errors import InvalidInputError, OpenMeshWarning


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


def test_a_vertices_faces_pair_is_refused_with_the_fix():
    """A (vertices, faces) tuple where a geometry goes (``rotation.frame_of``, the baselines, every
    reader of ``split_geometry``) was NumPy's 'inhomogeneous shape' ValueError; sample_surface and
    normalize_mesh already named jaxpose.geometry.Surface. Surface(vertices, faces) is read as the mesh."""
    from jaxpose.rotation.rotation import frame_of

    box = trimesh.creation.box()
    for call in (lambda g: geometry.split_geometry(g), lambda g: frame_of(g, "pca_vertices")):
        with pytest.raises(InvalidInputError, match=r"^a \(vertices, faces\) pair: pass jaxpose.geometry.Surface"):
            call((box.vertices, box.faces))
    v, f = geometry.split_geometry(geometry.Surface(box.vertices, box.faces))
    np.testing.assert_array_equal(f, box.faces)


def test_faces_are_whole_numbers_one_rule_everywhere():
    """split_geometry (frame_of, the baselines, estimate) cast float faces to int64: [0, 1, 2.5] was
    truncated into another face without a word, while sample.lattice_points and robust_solid refused
    every float and jaxpose.mesh.load took whole ones. One rule (_validate.check_faces): whole-number
    floats are the integers' indices, fractions refused."""
    box = trimesh.creation.box()
    v, f = geometry.split_geometry(geometry.Surface(box.vertices, box.faces.astype(float)))
    np.testing.assert_array_equal(f, box.faces)
    assert f.dtype == np.int64
    with pytest.raises(InvalidInputError, match=r"^faces must be \(f, 3\) integer indices .* with fractions"):
        geometry.split_geometry(geometry.Surface(box.vertices, box.faces + 0.5))
    bad = box.faces.astype(float)
    bad[0, 0] = np.inf  # (NumPy's "invalid value in remainder" RuntimeWarning, an error under the suite's filters)
    with pytest.raises(InvalidInputError, match=r"^faces must be \(f, 3\) integer indices"):
        geometry.split_geometry(geometry.Surface(box.vertices, bad))
    with pytest.raises(InvalidInputError, match=r"^faces index vertices that do not exist \(indices 0 \.\.\. 1234567, 8 "):
        geometry.split_geometry(geometry.Surface(box.vertices, np.where(box.faces == 7, 1234567, box.faces)))


def test_meshes_whose_areas_float64_cannot_hold_are_refused_by_their_extent():
    """A mesh spanning 1e100 got inf - inf = NaN areas: NumPy's 'repeats may not contain negative
    values' from the sampler, a NaN surface centroid, an OverflowError traceback from the robust
    default at 1e150; one spanning 1e-100 got areas of 0 and 'all its faces are degenerate'."""
    import jaxpose

    box = trimesh.creation.box()  # extent 1: areas 1 and 0.5
    for factor, message in ((1e100, "its face areas overflow float64"), (1e-100, "its face areas underflow float64")):
        scaled = trimesh.Trimesh(box.vertices * factor, box.faces, process=False)
        for call in (lambda: geometry.split_geometry(scaled), lambda: jaxpose.sample_surface(scaled, 10),
                     lambda: jaxpose.normalize_mesh(scaled, method="surface_centroid")):
            with pytest.raises(InvalidInputError, match=message):
                call()
    for factor, offset in ((1e70, 0.0), (1e-70, 0.0), (1e70, 1e80)):  # within the range (far too): areas factor^2
        scaled = trimesh.Trimesh(box.vertices * factor + [offset, 0.0, 0.0], box.faces, process=False)
        v, f = geometry.split_geometry(scaled)
        np.testing.assert_allclose(geometry.triangle_areas(v[f]), factor**2 * geometry.triangle_areas(box.vertices[f]),
                                   rtol=1e-5)  # at 1e80 the corners round by 1.5e64 (3e-6 of 5e69)


def test_triangle_areas_and_closedness():
    tri = np.array([[[0, 0, 0], [2, 0, 0], [0, 3, 0.0]], [[0, 0, 0], [1, 0, 0], [0, 0, 1.0]]])
    np.testing.assert_allclose(geometry.triangle_areas(tri), [3.0, 0.5])
    box = trimesh.creation.box()
    assert geometry.is_closed(box.faces)
    assert not geometry.is_closed(box.faces[:-1])  # one triangle off: a hole
    assert not geometry.is_closed(np.concatenate([box.faces, box.faces[:1]]))  # an edge shared three times


def test_triangle_areas_refuses_what_is_no_set_of_triangles():
    """One triangle (3, 3) was an IndexError ('too many indices'), (f, 4, 3) and (f, 3) arrays
    areas of something else or NumPy's errors: InvalidInputError naming the shape (f, 3, 3)."""
    tri = [[0, 0, 0], [2, 0, 0], [0, 3, 0.0]]
    with pytest.raises(InvalidInputError, match=r"triangles must have shape \(f, 3, 3\).*got \(3, 3\) \(one "
                                                r"triangle: pass triangles\[None\]\)"):
        geometry.triangle_areas(np.array(tri))
    for bad in (np.zeros((2, 4, 3)), np.zeros((2, 3, 2)), np.zeros(3)):
        with pytest.raises(InvalidInputError, match=r"triangles must have shape \(f, 3, 3\).*got " + re.escape(str(bad.shape))):
            geometry.triangle_areas(bad)
    np.testing.assert_allclose(geometry.triangle_areas([tri]), [3.0])  # a list of triangles reads as its array
    assert geometry.triangle_areas(np.zeros((0, 3, 3))).shape == (0,)


def _solid_of(mesh, strict=False):
    """A function that needs a closed mesh, as the baselines use the checks."""
    vertices, faces = geometry.require_faces(mesh, "solid_of")
    geometry.warn_if_open(faces, "solid_of", strict)
    return len(vertices)


def test_require_faces_and_warn_if_open():
    box = trimesh.creation.box()
    assert _solid_of(box) == 8  # closed: no warning (warnings are errors in this suite)
    with pytest.raises(InvalidInputError, match="solid_of needs a mesh with faces"):
        _solid_of(box.vertices)
    holed = trimesh.Trimesh(box.vertices, box.faces[:-1], process=False)
    with pytest.warns(OpenMeshWarning, match="solid_of: the mesh is not closed") as record:
        _solid_of(holed)
    assert record[0].filename == __file__  # reported at the caller's line, not inside jaxpose
    with pytest.raises(InvalidInputError, match=r"not closed.*strict=True"):
        _solid_of(holed, strict=True)


def test_host_functions_refuse_traced_geometry_by_name():
    """The NumPy functions of a geometry under jit / vmap / grad: an InvalidInputError naming the
    argument and the fix (trace jaxpose.normalize), not JAX's TracerArrayConversionError from
    np.asarray (it named no argument). Refused while tracing: nothing compiles."""
    import jax

    import jaxpose
    from jaxpose import baselines, sample
    from jaxpose.geometry import Surface
    from jaxpose.occupancy.solid import near_solid, robust_solid
    from jaxpose.occupancy.voxels import weighted_centroid
    from jaxpose.rotation.core import pre_frame
    from jaxpose.pose.estimators import estimate
    from jaxpose.rotation.rotation import frame_of

    box = trimesh.creation.box()
    points = np.asarray(box.vertices, np.float32)
    calls = {
        "the geometry": [lambda p: baselines.center(p, "bbox_center"), lambda p: baselines.frame(p, "pca_vertices"),
                         lambda p: estimate(p, "vertex_mean").scale, lambda p: frame_of(p, "pca_vertices").rotation,
                         lambda p: geometry.split_geometry(Surface(p, box.faces))[0],
                         lambda p: sample.sample_surface(Surface(p, box.faces), 8)],
        "center": [lambda p: baselines.scale(points, "mean_distance", center=p[0])],
        "input": [lambda p: jaxpose.sample_surface(Surface(p, box.faces), 8)],
        "vertices and faces": [lambda p: robust_solid(p, box.faces, resolution=16),
                               lambda p: sample.lattice_points(p, box.faces, 0.5), lambda p: pre_frame(p, box.faces)],
        "triangles": [lambda p: geometry.triangle_areas(p[box.faces])],
        "x, kept, origin and pitch": [lambda p: near_solid(p, np.ones((2, 2, 2), bool), np.zeros(3), 1.0)],
        "x and w": [lambda p: weighted_centroid(p, np.ones(len(points)))],
    }
    for name, fns in calls.items():
        for fn in fns:
            with pytest.raises(InvalidInputError, match=f"^{name}.*: a traced array .*trace jaxpose.normalize"):
                jax.jit(fn)(points)


def test_surface_labels_match_trimesh_split():
    """geometry.surface_labels: the face-connected surfaces, as trimesh's own split finds them."""
    import trimesh

    from jaxpose.geometry import surface_labels

    parts = [trimesh.creation.box(), trimesh.creation.icosphere(subdivisions=1), trimesh.creation.cylinder(0.2, 1.0)]
    for k, part in enumerate(parts):
        part.apply_translation([3.0 * k, 0.0, 0.0])
    mesh = trimesh.util.concatenate(parts)
    count, labels = surface_labels(len(mesh.vertices) + 1, mesh.faces)  # one vertex in no face
    assert count == len(mesh.split(only_watertight=False)) + 1 == 4
    offsets = np.cumsum([0] + [len(p.vertices) for p in parts])
    for a, b in zip(offsets[:-1], offsets[1:]):
        assert len(np.unique(labels[a:b])) == 1
    assert len(np.unique(labels[offsets[:-1]])) == 3 and labels[-1] not in labels[:-1]


def test_a_path_where_a_loaded_geometry_is_needed_says_how_to_load_it():
    """sample.sample_surface('some/path.obj') (and every host function of a geometry) said
    'vertices must have shape (m, 3), got ()'; now what it takes and how to load a file."""
    import pathlib

    from jaxpose import baselines, sample

    for path in ("some/path.obj", pathlib.Path("some/path.obj"), b"some/path.obj"):
        for call in (lambda: sample.sample_surface(path, 100), lambda: baselines.center(path),
                     lambda: geometry.split_geometry(path)):
            with pytest.raises(InvalidInputError, match=r"^expected a loaded geometry \(a Trimesh, PointCloud, "
                               r"jaxpose.geometry.Surface or \(n, 3\) points\), got the path 'some/path.obj': load "
                               r"it first with jaxpose.mesh.load\(path\)"):
                call()
