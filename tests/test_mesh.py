"""Mesh I/O, surface sampling, normalize_mesh and atomic export."""
import hashlib
import json
import os
import re

import numpy as np
import pytest
import trimesh

from jaxpose import baselines, mesh
from jaxpose.io import formats
from jaxpose._validate import InvalidInputError


# --------------------------------------------------------------------------- helpers
def digest(path):
    with open(path, "rb") as handle:
        return hashlib.sha256(handle.read()).hexdigest()


def lumpy():
    body = trimesh.creation.capsule(height=1.0, radius=0.5)
    arm = trimesh.creation.box(extents=(1.5, 0.2, 0.2))
    arm.apply_translation([1.2, 0.0, 0.3])
    return trimesh.util.concatenate([body, arm])


# --------------------------------------------------------------------------- load
@pytest.mark.parametrize("ext", ["obj", "ply", "off", "stl", "glb"])
def test_load_round_trip(tmp_path, ext):
    original = lumpy()
    path = tmp_path / f"shape.{ext}"
    original.export(path)
    before = digest(path)
    loaded = mesh.load(path)
    assert isinstance(loaded, trimesh.Trimesh)
    assert len(loaded.faces) == len(original.faces)
    assert loaded.area == pytest.approx(original.area, rel=1e-5)
    np.testing.assert_allclose(baselines.surface_centroid(loaded), baselines.surface_centroid(original), atol=1e-5)
    assert digest(path) == before  # reading never touches the file
    assert isinstance(mesh.load(str(path)), trimesh.Trimesh)  # str paths too


def test_scene_is_concatenated(tmp_path):
    a = trimesh.creation.box()
    b = trimesh.creation.icosphere()
    b.apply_translation([3.0, 0.0, 0.0])
    scene = trimesh.Scene([a, b])
    path = tmp_path / "scene.glb"
    scene.export(path)
    for source in (scene, path):
        loaded = mesh.load(source)
        assert isinstance(loaded, trimesh.Trimesh)
        assert len(loaded.faces) == len(a.faces) + len(b.faces)
        assert loaded.bounds[1, 0] == pytest.approx(4.0)


def test_a_gltf_reads_its_buffer_files_from_its_folder(tmp_path):
    """A .gltf beside its .bin buffers (trimesh's and most tools' layout): read from the path's
    folder, the same mesh as the buffers embedded; a buffer file missing is named."""
    shape = lumpy()
    files = trimesh.Scene(shape).export(file_type="gltf")
    assert any(name.endswith(".bin") for name in files)  # buffers as files of their own
    for name, data in files.items():
        (tmp_path / name).write_bytes(data)
    embedded = tmp_path / "embedded" / "model.gltf"
    embedded.parent.mkdir()
    embedded.write_bytes(trimesh.exchange.gltf.export_gltf(trimesh.Scene(shape), embed_buffers=True)["model.gltf"])
    loaded = mesh.load(tmp_path / "model.gltf")
    np.testing.assert_array_equal(loaded.vertices, mesh.load(embedded).vertices)
    np.testing.assert_array_equal(loaded.faces, mesh.load(embedded).faces)
    alone = tmp_path / "alone" / "model.gltf"
    alone.parent.mkdir()
    alone.write_bytes(files["model.gltf"])
    with pytest.raises(InvalidInputError, match=r"model.gltf: cannot read GLTF file: it refers to gltf_buffer_0.bin, "
                                                r"which is not in its folder .*alone"):
        mesh.load(alone)


def test_a_gltf_buffer_named_out_of_its_folder_is_never_opened(tmp_path, monkeypatch):
    """A .gltf naming ``../pipe.bin`` (a FIFO beside its folder) as a buffer: refused as not in its
    folder, on every trimesh: the reader resolves and reads the names itself, trimesh's own
    ``FilePathResolver.get`` is never called (trimesh 4's opened ``../pipe.bin`` and waited for a
    writer, for ever; 5's refused it in its own words); buffers in the folder read as before."""
    import threading

    folder = tmp_path / "d"
    folder.mkdir()
    files = trimesh.creation.box().export(file_type="gltf")
    for name, data in files.items():
        (folder / name).write_bytes(data)
    tree = json.loads(files["model.gltf"])
    tree["buffers"][0]["uri"] = "../pipe.bin"
    (folder / "out.gltf").write_text(json.dumps(tree))
    os.mkfifo(tmp_path / "pipe.bin")
    asked = []

    def trimesh_get(self, name):  # trimesh's rule, whichever version is installed: not to be used
        asked.append(name)
        raise RuntimeError(f"trimesh's resolver asked for {name!r}")

    monkeypatch.setattr(trimesh.resolvers.FilePathResolver, "get", trimesh_get)
    assert len(mesh.load(folder / "model.gltf").vertices) == 8  # the buffers beside it
    errors = []

    def load():
        try:
            mesh.load(folder / "out.gltf")
        except Exception as exc:
            errors.append(exc)

    thread = threading.Thread(target=load, daemon=True)
    thread.start()
    thread.join(30)
    blocked = thread.is_alive()
    while thread.is_alive():  # let it go: a writer that closes at once
        try:
            os.close(os.open(tmp_path / "pipe.bin", os.O_WRONLY | os.O_NONBLOCK))
        except OSError:
            pass
        thread.join(1)
    assert not blocked, "the reader waited on ../pipe.bin"
    assert asked == []
    assert len(errors) == 1 and isinstance(errors[0], InvalidInputError), errors
    assert re.search(r"out.gltf: cannot read GLTF file: it refers to \.\./pipe.bin, which is not in its folder .*d ",
                     str(errors[0])), errors[0]


def test_faceless_geometry_is_a_point_cloud(tmp_path):
    points = np.random.default_rng(0).normal(size=(50, 3))
    path = tmp_path / "cloud.ply"
    trimesh.PointCloud(points).export(path)
    loaded = mesh.load(path)
    assert isinstance(loaded, trimesh.PointCloud)
    np.testing.assert_allclose(loaded.vertices, points, atol=1e-6)
    obj = tmp_path / "cloud.obj"
    obj.write_text("".join(f"v {x} {y} {z}\n" for x, y, z in points))
    assert isinstance(mesh.load(obj), trimesh.PointCloud)
    assert isinstance(mesh.load(points), trimesh.PointCloud)
    assert isinstance(mesh.load(trimesh.Trimesh(points, np.zeros((0, 3), int))), trimesh.PointCloud)


@pytest.mark.parametrize(
    "name, content, message",
    [
        ("missing.obj", None, "no such file"),
        ("shape.xyzw", b"1 2 3\n", "unsupported format"),
        ("noext", b"1 2 3\n", "unsupported format"),
        ("corrupt.ply", b"garbage\x00\x01\x02", "cannot read"),
        ("corrupt.off", b"OFF\n3 1 0\n0 0\n", "cannot read"),
        ("empty.obj", b"", "empty geometry"),
        # one message for a file with nothing in it, whatever its format (were trimesh's words: 'not enough
        # columns in xyz file!', 'not enough values to unpack', 'Not a ply file!', 'index 0 is out of bounds')
        ("empty.xyz", b"", "empty.xyz: empty geometry: no vertices read as XYZ"),
        ("comments.xyz", b"# a\n// b\n\n", "empty geometry: no vertices read as XYZ"),
        ("empty.off", b"", "empty geometry: no vertices read as OFF"),
        ("comments.off", b"# a\n", "empty geometry: no vertices read as OFF"),
        ("empty.ply", b"", "empty geometry: no vertices read as PLY"),
        ("empty.glb", b"", "empty geometry: no vertices read as GLB"),
        ("nan.obj", b"v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "NaN"),
    ],
)
def test_load_errors(tmp_path, name, content, message):
    path = tmp_path / name
    if content is not None:
        path.write_bytes(content)
    with pytest.raises(InvalidInputError, match=message):
        mesh.load(path)
    if content is not None:
        assert path.read_bytes() == content


def test_load_directory_raises(tmp_path):
    with pytest.raises(InvalidInputError, match="not a file"):
        mesh.load(tmp_path)


# --------------------------------------------------------------------------- sample
def test_sample_surface_reads_paths_and_matches_loaded_geometry(tmp_path):
    """mesh.sample_surface of a file is sample.sample_surface of the loaded mesh, bit for bit."""
    from jaxpose import sample

    shape = lumpy()
    path = tmp_path / "lumpy.ply"
    shape.export(path)
    loaded = mesh.load(path)
    np.testing.assert_array_equal(mesh.sample_surface(path, 500, seed=3), sample.sample_surface(loaded, 500, seed=3))
    np.testing.assert_array_equal(mesh.sample_surface(shape, 500, seed=3), sample.sample_surface(shape, 500, seed=3))
    with pytest.raises(InvalidInputError, match="no such file"):
        mesh.sample_surface(tmp_path / "missing.ply", 10)


# --------------------------------------------------------------------------- normalize_mesh
def test_normalize_mesh_surface_centroid(tmp_path):
    shape = lumpy()
    shape.apply_translation([3.0, -1.0, 2.0])
    shape.apply_scale(2.0)
    original = shape.vertices.copy()
    normalized, pose = mesh.normalize_mesh(shape, method="surface_centroid")
    np.testing.assert_array_equal(shape.vertices, original)  # input untouched
    # Pose holds JAX arrays: float32 unless x64 is enabled
    np.testing.assert_allclose(baselines.surface_centroid(normalized), 0.0, atol=1e-6)
    assert baselines.mean_distance(normalized, np.zeros(3)) == pytest.approx(1.0, rel=1e-6)
    np.testing.assert_allclose(np.asarray(pose.center), baselines.surface_centroid(shape), rtol=1e-6)
    matrix = mesh.pose_matrix(pose)
    np.testing.assert_allclose(normalized.vertices, shape.vertices @ matrix[:3, :3].T + matrix[:3, 3], atol=1e-12)
    # a path works the same
    path = tmp_path / "shape.ply"
    shape.export(path)
    before = digest(path)
    from_file, pose2 = mesh.normalize_mesh(path, method="surface_centroid")
    np.testing.assert_allclose(np.asarray(pose2.center), np.asarray(pose.center), atol=1e-6)
    assert digest(path) == before


@pytest.mark.parametrize(
    "method, check",
    [
        ("vertex_mean", lambda m: np.linalg.norm(baselines.vertex_mean(m))),
        ("bbox", lambda m: abs(baselines.unit_cube(m) - 1.0) + np.linalg.norm(baselines.bbox_center(m))),
        ("min_ball", lambda m: abs(baselines.min_ball(m)[1] - 1.0) + np.linalg.norm(baselines.min_ball(m)[0])),
    ],
)
def test_normalize_mesh_baselines(method, check):
    shape = lumpy()
    shape.apply_translation([0.5, 0.25, -4.0])
    normalized, _ = mesh.normalize_mesh(shape, method=method)
    assert check(normalized) < 1e-6  # float32 poses unless JAX x64 is on


def test_normalize_point_cloud():
    points = np.random.default_rng(0).normal(size=(300, 3)) + 5.0
    normalized, _ = mesh.normalize_mesh(trimesh.PointCloud(points), method="surface_centroid")
    assert isinstance(normalized, trimesh.PointCloud)
    np.testing.assert_allclose(normalized.vertices.mean(axis=0), 0.0, atol=1e-6)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"method": "centroid"}, "unknown method"),
        ({"center": "middle"}, "unknown center"),
        ({"method": "surface_centroid", "power": 2}, "power applies"),
        ({"gamma": -1.0}, "gamma"),
        ({"nu": 1.5}, "nu"),
        ({"method": "bbox", "resolution": 32}, "resolution applies"),
    ],
)
def test_normalize_mesh_validation(kwargs, message):
    with pytest.raises(InvalidInputError, match=message):
        mesh.normalize_mesh(lumpy(), **kwargs)


def test_normalize_mesh_ocsvm():
    shape = mesh.example_shape()
    shape.apply_translation([1.0, 2.0, 3.0])
    # 400 samples (incidental): the float32 default-grid program at 448 rows of test_pinned.py (its
    # normalize calls on 400 points), not one of its own at 512 rows
    normalized, pose = mesh.normalize_mesh(shape, count=400, method="ocsvm")
    matrix = mesh.pose_matrix(pose)
    center = np.asarray(pose.center, float)
    np.testing.assert_allclose(matrix[:3, :3] @ center + matrix[:3, 3], 0.0, atol=1e-12)
    np.testing.assert_allclose(np.asarray(pose.matrix, float), matrix, rtol=1e-5, atol=1e-6)
    expected = shape.vertices @ matrix[:3, :3].T + matrix[:3, 3]
    np.testing.assert_allclose(normalized.vertices, expected, atol=1e-9)
    assert float(np.asarray(pose.scale)) > 0


# --------------------------------------------------------------------------- export
@pytest.mark.parametrize("ext", ["obj", "ply", "off", "stl"])
def test_export_round_trip(tmp_path, ext):
    shape = lumpy()
    path = tmp_path / f"out.{ext}"
    assert mesh.export(shape, path) == path
    assert mesh.load(path).area == pytest.approx(shape.area, rel=1e-5)
    assert sorted(p.name for p in tmp_path.iterdir()) == [path.name]  # no temporary left


def test_export_refuses_existing_unless_forced(tmp_path):
    path = tmp_path / "out.ply"
    path.write_bytes(b"keep me")
    with pytest.raises(InvalidInputError, match="exists"):
        mesh.export(lumpy(), path)
    assert path.read_bytes() == b"keep me"
    mesh.export(lumpy(), path, force=True)
    assert isinstance(mesh.load(path), trimesh.Trimesh)


def test_export_point_cloud(tmp_path):
    cloud = trimesh.PointCloud(np.random.default_rng(0).normal(size=(20, 3)))
    mesh.export(cloud, tmp_path / "cloud.ply")
    assert isinstance(mesh.load(tmp_path / "cloud.ply"), trimesh.PointCloud)


@pytest.mark.parametrize("name", ["out.unknownext", "out", "missing_dir/out.ply"])
def test_export_errors_leave_nothing(tmp_path, name):
    with pytest.raises(InvalidInputError):
        mesh.export(lumpy(), tmp_path / name)
    assert list(tmp_path.iterdir()) == []


def test_write_atomic_failure_leaves_no_temporary(tmp_path, monkeypatch):
    import os

    def broken_replace(src, dst):
        raise OSError("disk full")

    monkeypatch.setattr(os, "replace", broken_replace)
    with pytest.raises(OSError, match="disk full"):
        mesh.write_atomic(tmp_path / "x.json", "{}")
    assert list(tmp_path.iterdir()) == []


def test_example_shape_is_a_clean_mesh():
    shape = mesh.example_shape()
    assert isinstance(shape, trimesh.Trimesh) and shape.area > 0
    # the outlying arm pulls the surface centroid away from the body at the origin
    assert baselines.surface_centroid(shape)[0] > 0.1


try:
    from hypothesis import given, settings
    from hypothesis import strategies as st
except ImportError:  # pragma: no cover
    given = None

if given is not None:

    @settings(max_examples=30, deadline=None)
    @given(count=st.integers(4, 3000), seed=st.integers(0, 2**32 - 1), method=st.sampled_from(mesh.SAMPLING))
    def test_sampling_count_property(count, seed, method):
        points = mesh.sample_surface(_LUMPY, count, seed=seed, method=method)
        assert points.shape == (count, 3) and np.all(np.isfinite(points))
        lo, hi = _LUMPY.bounds
        assert np.all(points >= lo - 1e-9) and np.all(points <= hi + 1e-9)

    _LUMPY = lumpy()


# --------------------------------------------------------------------------- encodings, content
TETRA = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"


def test_text_files_in_any_encoding_load(tmp_path):
    """An OBJ with a Latin-1 comment, an OFF with cp1252 bytes, an ASCII STL whose name is Latin-1:
    the same geometry as their UTF-8 versions (mesh data is ASCII; other bytes are comments)."""
    (tmp_path / "utf8.obj").write_text("# café modèle\n" + TETRA, encoding="utf-8")
    (tmp_path / "latin1.obj").write_bytes(("# café modèle\n" + TETRA).encode("latin-1"))
    sphere = trimesh.creation.icosphere(subdivisions=1)
    (tmp_path / "cp1252.off").write_bytes(sphere.export(file_type="off").replace("OFF\n", "OFF\n# \u201cquoted\u201d\n", 1)
                                          .encode("cp1252"))
    stl = sphere.export(file_type="stl_ascii")
    (tmp_path / "latin1.stl").write_bytes(stl.replace("solid", "solid crème", 1).encode("latin-1"))
    reference = mesh.load(tmp_path / "utf8.obj")
    np.testing.assert_array_equal(mesh.load(tmp_path / "latin1.obj").vertices, reference.vertices)
    assert len(mesh.load(tmp_path / "cp1252.off").faces) == len(sphere.faces)
    assert len(mesh.load(tmp_path / "latin1.stl").faces) == len(sphere.faces)
    assert formats.sniff_format(stl.encode()) == "stl" and formats.sniff_format(b"ply\n") == "ply"


def test_a_byte_order_mark_is_not_part_of_the_first_line(tmp_path):
    """Text files that start with a byte-order mark (Windows editors, .NET writers; UTF-16 from
    Windows PowerShell) read as without it. An OBJ lost its first vertex to trimesh's and the fast
    reader's first line, every face then one vertex off: silently another mesh where the last vertex
    is unused ("TETRA + v 0 0 -1"), else an error about a vertex the file has; an XYZ failed
    ("could not convert string to float: '\ufeff0'")."""
    bom = b"\xef\xbb\xbf"
    spare = TETRA.replace("f 1 3 2", "v 0 0 -1\nf 1 3 2", 1)  # a fifth vertex no face uses
    cloud = "".join(f"{x} {y} {z}\n" for x, y, z in np.random.default_rng(0).normal(size=(40, 3)))
    for name, text in (("tetra.obj", TETRA), ("spare.obj", spare), ("cloud.xyz", cloud),
                       ("sphere.off", trimesh.creation.icosphere(subdivisions=1).export(file_type="off"))):
        (tmp_path / name).write_text(text)
        reference = mesh.load(tmp_path / name)
        for encoded in (bom + text.encode(), text.encode("utf-16"), text.encode("utf-16-be").join([b"\xfe\xff", b""])):
            (tmp_path / f"marked_{name}").write_bytes(encoded)
            loaded = mesh.load(tmp_path / f"marked_{name}")
            np.testing.assert_array_equal(loaded.vertices, reference.vertices)
            if hasattr(reference, "faces"):
                np.testing.assert_array_equal(loaded.faces, reference.faces)
    off = trimesh.creation.icosphere(subdivisions=1).export(file_type="off")
    (tmp_path / "off_as.obj").write_bytes(bom + off.encode())
    with pytest.raises(InvalidInputError, match="the content is OFF, not OBJ"):  # sniffed past the mark
        mesh.load(tmp_path / "off_as.obj")


def test_an_off_comment_after_the_counts_line_is_a_comment(tmp_path):
    """'OFF\\n4 5 0\\n# the vertices\\n...' reads as without the comment, through the fast reader and
    through trimesh (a face of 2 corners: the fast reader declines): trimesh read the counts line
    a second time as the first vertex, every vertex one line late, the last face lost, silently."""
    vertices = "0 0 0\n1 0 0\n0 1 0\n0 0 1\n"
    faces = "3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n"
    for name, counts, more in (("fast", "4 4 0", ""), ("trimesh", "4 5 0", "2 0 1\n")):
        (tmp_path / f"{name}.off").write_text(f"OFF\n{counts}\n# the vertices\n{vertices}# faces\n{more}{faces}")
        (tmp_path / f"{name}_plain.off").write_text(f"OFF\n{counts}\n{vertices}{more}{faces}")
        loaded, plain = mesh.load(tmp_path / f"{name}.off"), mesh.load(tmp_path / f"{name}_plain.off")
        np.testing.assert_array_equal(loaded.vertices, plain.vertices)
        np.testing.assert_array_equal(loaded.faces, plain.faces)
        assert len(loaded.faces) == 4 and loaded.vertices.min() == 0.0 and loaded.vertices.max() == 1.0


def test_tabs_separate_an_obj_lines_values_as_spaces_do(tmp_path):
    """'v\\t0 0 1' is a vertex (OBJ's values are separated by white space): trimesh's loader and the
    fast reader know 'v ' only and dropped it, every later vertex one number off (silently another
    mesh where the last vertex is unused); a file of tabs only was 'empty geometry'. Fast reader
    and trimesh's path (a material line) alike."""
    spare = TETRA.replace("f 1 3 2", "v 0 0 -1\nf 1 3 2", 1)  # a fifth vertex no face uses
    cases = {"one_tab": spare.replace("v 0 0 1", "v\t0 0 1"), "all_tabs": TETRA.replace(" ", "\t"),
             "material": spare.replace("v 0 0 1", "v\t0 0 1").replace("f 1 3 2", "usemtl skin\nf 1 3 2")}
    for name, text in cases.items():
        (tmp_path / f"{name}.obj").write_text(text)
        (tmp_path / f"{name}_spaces.obj").write_text(text.replace("\t", " "))
        loaded, plain = mesh.load(tmp_path / f"{name}.obj"), mesh.load(tmp_path / f"{name}_spaces.obj")
        np.testing.assert_array_equal(loaded.vertices, plain.vertices)
        np.testing.assert_array_equal(loaded.faces, plain.faces)
        assert loaded.vertices.min() == 0.0 and len(loaded.faces) == 4, name


def test_comments_that_end_an_obj_data_line_are_cut(tmp_path):
    """'v 0 0 1 # a' and 'f 1 2 3 # tri' read as the file says (a comment to the end of the line):
    trimesh's loader, and the fast reader that copied it, failed 'could not be read to its end due
    to unmatched data', naming no line. Fast reader and trimesh's path (a material line) alike; a
    name's '#' (usemtl) is kept."""
    cases = {"fast": (TETRA.replace("v 0 0 1", "v 0 0 1 # apex").replace("f 1 3 2", "f 1 3 2\t# base"),
                      TETRA),
             "tight": (TETRA.replace("v 0 0 1", "v 0 0 1#apex").replace("f 1 3 2", "f 1 3 2#"), TETRA),
             "material": (TETRA.replace("v 0 0 1", "v 0 0 1 # apex").replace("f 1 3 2", "usemtl s#2\nf 1 3 2 # b"),
                          TETRA.replace("f 1 3 2", "usemtl s#2\nf 1 3 2"))}
    for name, (text, plain) in cases.items():
        (tmp_path / f"{name}.obj").write_text(text)
        (tmp_path / f"{name}_plain.obj").write_text(plain)
        loaded, expected = mesh.load(tmp_path / f"{name}.obj"), mesh.load(tmp_path / f"{name}_plain.obj")
        np.testing.assert_array_equal(loaded.vertices, expected.vertices)
        np.testing.assert_array_equal(loaded.faces, expected.faces)
        assert loaded.vertices.max() == 1.0 and len(loaded.faces) == 4, name


def test_a_comment_on_a_continued_obj_line_is_cut(tmp_path):
    """A '#' comment on the second line of a data line continued by a backslash ('f 1 3 \\' then
    '2 # base') is cut as the file says, by the fast reader and on trimesh's path (a material line)
    alike: only a line that began with its keyword was seen as data, so the comment stayed and was
    read as values ("invalid literal for int() with base 10: '#'"; a vertex's: "could not be read
    to its end due to unmatched data"). CRLF line ends too."""
    continued = {"face": ("f 1 3 2", "f 1 3 \\\n2 # base"), "vertex": ("v 0 0 1", "v 0 \\\n 0 \\\n1#apex"),
                 "comment_line": ("f 1 2 4", "f 1 2 4 \\\n# side")}
    for name, plain in {"fast": TETRA, "material": TETRA.replace("f 1 3 2", "usemtl s\nf 1 3 2")}.items():
        for tag, (line, text) in continued.items():
            for end in ("\n", "\r\n"):
                (tmp_path / f"{name}_{tag}.obj").write_bytes(plain.replace(line, text).replace("\n", end).encode())
                (tmp_path / f"{name}_plain.obj").write_text(plain)
                loaded = mesh.load(tmp_path / f"{name}_{tag}.obj")
                expected = mesh.load(tmp_path / f"{name}_plain.obj")
                np.testing.assert_array_equal(loaded.vertices, expected.vertices)
                np.testing.assert_array_equal(loaded.faces, expected.faces)
                assert len(loaded.faces) == 4, (name, tag)


def test_an_obj_comment_line_ending_in_a_backslash_continues_into_the_next_line(tmp_path):
    """A comment line that ends in a backslash ('# side \\' then 'f 1 2 4') joins the next line, as
    any OBJ line does: the OBJ specification joins lines that end in '\\' and exempts no line, and
    trimesh's loader and three.js's OBJLoader join before they look for comments, so the face is
    part of the comment. Pinned (docs/api.md, "Reading OBJ files"): the fast reader and trimesh's
    path (a material line) alike, LF and CRLF; a comment line without it keeps the face."""
    for name, plain in {"fast": TETRA, "material": TETRA.replace("f 1 3 2", "usemtl s\nf 1 3 2")}.items():
        for end in ("\n", "\r\n"):
            joined = plain.replace("f 1 2 4", "# side \\\nf 1 2 4").replace("\n", end)
            (tmp_path / f"{name}.obj").write_bytes(joined.encode())
            (tmp_path / f"{name}_without.obj").write_text(plain.replace("f 1 2 4\n", ""))
            (tmp_path / f"{name}_apart.obj").write_text(plain.replace("f 1 2 4", "# side\nf 1 2 4"))
            loaded, expected = mesh.load(tmp_path / f"{name}.obj"), mesh.load(tmp_path / f"{name}_without.obj")
            np.testing.assert_array_equal(loaded.vertices, expected.vertices)
            np.testing.assert_array_equal(loaded.faces, expected.faces)
            assert len(loaded.faces) == 3 and len(mesh.load(tmp_path / f"{name}_apart.obj").faces) == 4, (name, end)


def test_indented_obj_lines_are_read(tmp_path):
    """Lines that start with white space read as the file says, by the fast reader and on trimesh's
    path (a material line) alike: an indented vertex was dropped (a face then 'references vertex 4
    of the 3 it has') and a file whose faces were all indented loaded as a point cloud, silently."""
    for name, plain in {"fast": TETRA, "material": TETRA.replace("f 1 3 2", "usemtl s\nf 1 3 2")}.items():
        for tag, text in {"some": plain.replace("v 0 0 1", "  v 0 0 1"),
                          "all": "\n".join("\t " + line for line in plain.split("\n"))}.items():
            (tmp_path / f"{name}_{tag}.obj").write_text(text)
            (tmp_path / f"{name}_plain.obj").write_text(plain)
            loaded, expected = mesh.load(tmp_path / f"{name}_{tag}.obj"), mesh.load(tmp_path / f"{name}_plain.obj")
            np.testing.assert_array_equal(loaded.vertices, expected.vertices)
            np.testing.assert_array_equal(loaded.faces, expected.faces)
            assert len(loaded.faces) == 4, (name, tag)


def test_xyz_files_with_commas_comments_or_uneven_lines(tmp_path):
    """Commas as separators and comment lines ('#', CloudCompare's '//X Y Z' header) read as the
    plain file: trimesh counted the first line's columns before it took commas as spaces ('not
    enough columns in xyz file!' for every 'x,y,z' file) and failed on comments. A line of another
    length than the first is refused naming it: trimesh read the values in rows of the first line's
    count (where the total divides, silently other points)."""
    points = np.random.default_rng(0).normal(size=(40, 3))
    (tmp_path / "plain.xyz").write_text("".join(f"{x} {y} {z}\n" for x, y, z in points))
    plain = mesh.load(tmp_path / "plain.xyz").vertices
    variants = {"commas": "".join(f"{x},{y},{z}\n" for x, y, z in points),
                "comma_space": "".join(f"{x}, {y}, {z}\n" for x, y, z in points),
                "cloudcompare": "//X,Y,Z\n" + "".join(f"{x},{y},{z}\n" for x, y, z in points),
                "comments": "# scan 1\n" + "".join(f"{x} {y} {z}\n" for x, y, z in points[:20]) + "  # half\n"
                            + "".join(f"{x} {y} {z}\n" for x, y, z in points[20:]),
                # '#' at a line's end, as OFF's (it was 'line 2 holds 5 values ... truncated or malformed')
                "end_comments": "".join(f"{x} {y} {z} # c{i}\n" for i, (x, y, z) in enumerate(points)),
                "end_comments_commas": "".join(f"{x},{y},{z}#c\n" for x, y, z in points)}
    for name, text in variants.items():
        (tmp_path / f"{name}.xyz").write_text(text)
        np.testing.assert_array_equal(mesh.load(tmp_path / f"{name}.xyz").vertices, plain)
    lines = [f"{x} {y} {z}" for x, y, z in points]
    lines[6] += " 7"
    lines[9] = lines[9].rpartition(" ")[0]  # 4 and 2 values: 120 in all, 40 rows of 3 to trimesh
    (tmp_path / "uneven.xyz").write_text("\n".join(lines) + "\n")
    with pytest.raises(InvalidInputError, match=r"uneven.xyz: cannot read XYZ file: line 7 holds 4 values, line 1 "
                                                r"\(the first\) 3: a truncated or malformed file"):
        mesh.load(tmp_path / "uneven.xyz")
    (tmp_path / "slashes.xyz").write_text("\n".join(f"{x} {y} {z} // c" for x, y, z in points) + "\n")
    with pytest.raises(InvalidInputError, match=r"slashes.xyz: cannot read XYZ file"):  # "//" a whole line only
        mesh.load(tmp_path / "slashes.xyz")


def test_a_one_line_xyz_file_is_one_point(tmp_path):
    """An XYZ file of one line of values is a point cloud of that point, as a one-vertex OBJ or PLY
    is: trimesh's loader counted the columns of a file without a line end after its values (its
    text stripped) without the last character, 'not enough columns in xyz file!' for '1 2 3'
    (and '1 2 3 255 0 0' a reshape error) though '10 20 30' read. Normalizing it says why not."""
    texts = {"plain": "1 2 3\n", "bare": "1 2 3", "comment": "# one\n1 2 3  # c\n\n", "commas": "1,2,3\r\n",
             "wide": "10 20 30\n"}
    for name, text in texts.items():
        (tmp_path / f"{name}.xyz").write_text(text)
        loaded = mesh.load(tmp_path / f"{name}.xyz")
        assert isinstance(loaded, trimesh.PointCloud), name
        np.testing.assert_array_equal(loaded.vertices, [[10.0, 20, 30] if name == "wide" else [1.0, 2, 3]])
    (tmp_path / "color.xyz").write_text("1 2 3 255 0 7\n")
    colored = mesh.load(tmp_path / "color.xyz")
    np.testing.assert_array_equal(colored.vertices, [[1.0, 2, 3]])
    np.testing.assert_array_equal(colored.colors, [[255, 0, 7, 255]])
    (tmp_path / "two.xyz").write_text("1 2\n")
    with pytest.raises(InvalidInputError, match=r"two.xyz: cannot read XYZ file: not enough columns"):
        mesh.load(tmp_path / "two.xyz")
    with pytest.raises(InvalidInputError, match=r"all 1 vertices are identical: no shape to normalize"):
        mesh.normalize_mesh(tmp_path / "plain.xyz", method="bbox")


def test_content_that_does_not_match_its_suffix_is_named(tmp_path):
    sphere = trimesh.creation.icosphere(subdivisions=1)
    cases = {
        "ply_as.obj": (sphere.export(file_type="ply"), "the content is PLY, not OBJ: rename it to .ply"),
        "stl_as.ply": (sphere.export(file_type="stl"), "the content is STL, not PLY"),
        "off_as.obj": (sphere.export(file_type="off").encode(), "the content is OFF, not OBJ"),
        "binary.obj": (b"\x00\x01\x02junk" * 10, "binary data, not a text OBJ file"),
        "words.stl": (b"hello, this is not a mesh\n", "no vertices read as STL"),
    }
    for name, (data, message) in cases.items():
        (tmp_path / name).write_bytes(data)
        before = digest(tmp_path / name)
        with pytest.raises(InvalidInputError, match=message):
            mesh.load(tmp_path / name)
        assert digest(tmp_path / name) == before


# --------------------------------------------------------------------------- early refusal
@pytest.mark.parametrize("kwargs, message", [
    (dict(foo=1), "unknown argument foo"),
    (dict(method="ocsvm", foo=1, bar=2), "unknown arguments bar, foo"),
    (dict(seed=-1), "seed must be >= 0"),
    (dict(sampling="bogus"), "unknown sampling"),
    (dict(strict="yes"), "strict must be True or False"),
    # strict=True where it does nothing (robust, bbox, ...): refused, as the command line's --strict (it was taken)
    (dict(strict=True), r"strict applies to the closed-surface estimators .* \(center robust_depth, scale robust_volume\) "
                        "do not use"),
    (dict(method="bbox", strict=True), r"\(center bbox_center, scale unit_cube\) do not use"),
    (dict(power=-1.0), "power must be a finite number >= 0"),
    (dict(resolution=1000), r"resolution=1000 needs up to .* GiB .* use a resolution in \[8, 291\]"),
    (dict(method="ocsvm", resolution=1000), r"resolution=1000 .* needs about .* GiB .* use a resolution in \[8, 281\]"),
    (dict(method="ocsvm", tol=-1.0), "tol must be a finite number > 0"),
    (dict(count=3), "count must be >= 4"),
])
def test_every_argument_is_checked_before_the_file_is_read(kwargs, message):
    """A bad argument is named (with its range) even when the file does not exist: nothing is read first."""
    with pytest.raises(InvalidInputError, match=message):
        mesh.normalize_mesh("/nonexistent/shape.ply", **kwargs)


def test_the_ocsvm_frame_takes_the_ocsvm_options(monkeypatch):
    """rotation='ocsvm' runs the OCSVM (its gamma, nu, ... were taken): its solver and grid options
    reach the frame too, and are checked; they were refused ('options ['tol'] apply to the ocsvm
    estimator only') where the center and scale were not the OCSVM's."""
    seen = []

    def frame_of(geometry, name, resolution=None, ocsvm=None):
        seen.append((name, ocsvm["options"], ocsvm["gamma"]))
        return type("Found", (), {"rotation": np.eye(3), "ambiguity": 0.0})()

    monkeypatch.setattr(mesh, "frame_of", frame_of)
    box = trimesh.creation.box((1.0, 2.0, 3.0))
    _, pose = mesh.normalize_mesh(box, method="vertex_mean", rotation="ocsvm", gamma=20.0, tol=1e-4, refine=4)
    assert seen == [("ocsvm", {"tol": 1e-4, "refine": 4}, 20.0)] and pose.rotation.shape == (3, 3)
    # resolution too, an OCSVM option as refine is (refine=4 was taken, resolution=32 refused:
    # 'resolution applies to the robust and ocsvm estimators (options), not vertex_mean / ...')
    mesh.normalize_mesh(box, method="vertex_mean", rotation="ocsvm", resolution=32, refine=4)
    assert seen[-1] == ("ocsvm", {"resolution": 32, "refine": 4}, 47.0)
    with pytest.raises(InvalidInputError, match="resolution"):
        mesh.check_arguments(method="vertex_mean", rotation="ocsvm", resolution=4)
    with pytest.raises(InvalidInputError, match="tol must be a finite number > 0"):
        mesh.check_arguments(method="vertex_mean", rotation="ocsvm", tol=-1.0)
    with pytest.raises(InvalidInputError, match=r"options \['tol'\] apply to the ocsvm estimator only \(pass"):
        mesh.check_arguments(method="vertex_mean", rotation="pca_vertices", tol=1e-4)


def test_each_estimator_gets_the_options_it_reads():
    """normalize_mesh passes estimate and frame_of only what they read (they refuse an option they do
    not read): the OCSVM's filled-in defaults reach neither a vertex mean nor a PCA frame, a robust
    resolution not the PCA frame; the same pose as without the frame."""
    box = trimesh.creation.box((1.0, 2.0, 3.0))
    _, pose = mesh.normalize_mesh(box, method="vertex_mean", rotation="pca_vertices")
    np.testing.assert_allclose(pose.center, box.vertices.mean(0), atol=1e-12)
    _, robust = mesh.normalize_mesh(box, resolution=32, rotation="pca_vertices")
    _, plain = mesh.normalize_mesh(box, resolution=32)
    np.testing.assert_array_equal(robust.center, plain.center)
    assert robust.rotation.shape == (3, 3)


def test_vertices_far_from_the_origin_are_not_merged(tmp_path):
    """trimesh's merge_vertices rounds coordinates to 1e-8 as int64, which overflows at 1e12 and
    merges every vertex into one; load merges near the origin, exactly."""
    body = trimesh.creation.icosphere(subdivisions=1)
    o = np.array([1e12, -7e11, 3e11])
    corners = body.triangles.reshape(-1, 3) + o  # each triangle's corners apart, as STL stores them
    soup = trimesh.Trimesh(corners, np.arange(len(corners)).reshape(-1, 3), process=False)
    soup.export(tmp_path / "far.obj")  # text, float64
    loaded = mesh.load(tmp_path / "far.obj")
    assert len(loaded.vertices) == len(body.vertices) and len(loaded.faces) == len(body.faces)
    assert np.isclose(loaded.area, body.area, rtol=1e-3)  # the coordinates themselves are rounded to 1.2e-4


def test_vertices_of_a_mesh_larger_than_the_merge_keys_reach_are_not_merged(tmp_path):
    """A mesh spanning 2e12 (beyond 9.2e10 from its middle vertex the 1e-8 keys overflow int64):
    the fast readers merged distinct vertices (the example body at 1e12 lost 578 of its 774 vertices
    and half its scale, silently); they now merge it exactly, and trimesh's merge (formats the fast
    readers leave to trimesh) refuses it by name instead of merging wrongly."""
    body = trimesh.creation.icosphere(subdivisions=1)
    corners = body.triangles.reshape(-1, 3) * 1e12  # each triangle's corners apart, as STL stores them
    soup = trimesh.Trimesh(corners, np.arange(len(corners)).reshape(-1, 3), process=False)
    soup.export(tmp_path / "big.obj")  # text, float64: the fast reader
    loaded = mesh.load(tmp_path / "big.obj")
    assert len(loaded.vertices) == len(body.vertices) and len(loaded.faces) == len(body.faces)
    np.testing.assert_allclose(trimesh.Trimesh(loaded.vertices, loaded.faces, process=False).area, body.area * 1e24, rtol=1e-12)
    soup.export(tmp_path / "big.glb")  # trimesh's format
    with pytest.raises(InvalidInputError, match=r"big.glb: the mesh reaches .* trimesh's vertex merge"):
        mesh.load(tmp_path / "big.glb")


def test_jax_arrays_of_points_are_points():
    """normalize_mesh and sample_surface took NumPy arrays and lists of points but refused a JAX
    array ('input: cannot use a ArrayImpl as a mesh'); a traced one (under jit) is named as such
    (it was JAX's TracerArrayConversionError once arrays were read)."""
    import jax
    import jax.numpy as jnp

    points = trimesh.creation.icosphere(subdivisions=1).vertices * [1.0, 2.0, 3.0]
    as_jax = jnp.asarray(points, jnp.float32)
    _, pose = mesh.normalize_mesh(as_jax, method="vertex_mean")
    _, expected = mesh.normalize_mesh(np.asarray(as_jax), method="vertex_mean")
    np.testing.assert_array_equal(pose.center, expected.center)
    np.testing.assert_array_equal(pose.scale, expected.scale)
    np.testing.assert_array_equal(mesh.sample_surface(as_jax, 8, seed=1), mesh.sample_surface(np.asarray(as_jax), 8, seed=1))
    with pytest.raises(InvalidInputError, match="a traced array"):
        jax.jit(lambda x: mesh.normalize_mesh(x, method="vertex_mean")[1].scale)(as_jax)



def test_a_surfaces_faces_are_integer_indices():
    """A Surface's faces are indices: fractional ones (7.5 was read as vertex 7) and bools (read as
    vertices 0 and 1) are refused, whole floats taken; a (vertices, faces) pair is named as one
    (it was NumPy's 'inhomogeneous shape' about points)."""
    from jaxpose.geometry import Surface

    box = trimesh.creation.box()
    v, f = np.asarray(box.vertices), np.asarray(box.faces)
    _, want = mesh.normalize_mesh(Surface(v, f), method="surface_centroid")
    _, pose = mesh.normalize_mesh(Surface(v, f.astype(np.float32)), method="surface_centroid")
    np.testing.assert_array_equal(pose.center, want.center)
    for faces, got in ((f + 0.5, "float64 with fractions"), (f > 3, "bool")):
        with pytest.raises(InvalidInputError, match=f"^input: faces must be .* indices of its vertices .*got {got}"):
            mesh.normalize_mesh(Surface(v, faces), method="surface_centroid")
    with pytest.raises(InvalidInputError, match=r"a \(vertices, faces\) pair: pass jaxpose.geometry.Surface"):
        mesh.normalize_mesh((v, f), method="surface_centroid")


def test_unknown_keywords_are_named():
    box = trimesh.creation.box()
    for kwargs in (dict(foo=1), dict(method="ocsvm", foo=1), dict(method="surface_centroid", foo=1)):
        with pytest.raises(InvalidInputError, match="unknown argument foo"):
            mesh.normalize_mesh(box, **kwargs)


def test_strict_is_refused_where_no_estimator_reads_it_by_every_entry_point():
    """strict=True with estimators that are not closed-surface ones does nothing: the command line
    refused --strict so, normalize_mesh, estimate and the batch's NormalizeOptions took it (one
    rule now, estimators.check_strict); with a closed-surface center or scale it is taken."""
    from jaxpose.batch.task import NormalizeOptions

    for call in (lambda: NormalizeOptions(strict=True), lambda: NormalizeOptions(method="ocsvm", strict=True),
                 lambda: mesh.normalize_mesh("/nonexistent/shape.ply", center="bbox_center", strict=True)):
        with pytest.raises(InvalidInputError, match="strict applies to the closed-surface estimators"):
            call()
    for fields in (dict(method="solid"), dict(method="solid_sqrt_area"), dict(center="depth_weighted_solid"),
                   dict(scale="gyration_radius")):
        assert NormalizeOptions(**fields, strict=True).strict is True
