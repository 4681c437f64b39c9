"""The fast readers against trimesh's loaders on the same files: equal vertices, faces and extras."""
from __future__ import annotations

import io
import re
from pathlib import Path

import numpy as np
import pytest
import trimesh

from jaxpose.io import readers
from jaxpose.io.readers import Unsupported

SHARED = Path(__file__).resolve().parents[2] / "shared" / "data"


def trimesh_load(data, file_type):
    """What jaxpose read before the fast readers: trimesh.load(..., process=False), a scene as one mesh."""
    loaded = trimesh.load(io.BytesIO(data), file_type=file_type, process=False)
    if isinstance(loaded, trimesh.Scene):
        meshes = loaded.dump()
        assert len(meshes) == 1
        loaded = meshes[0]
    return loaded


def check_same(data, file_type):
    """The reader's mesh equals trimesh's: vertices, faces, and the Trimesh made from its arguments."""
    if isinstance(data, str):
        data = data.encode()
    expected = trimesh_load(data, file_type)
    got = readers.read(data, file_type)
    assert got.vertices.dtype == np.float64 and got.faces.dtype == np.int64
    np.testing.assert_array_equal(got.vertices, np.asarray(expected.vertices))
    np.testing.assert_array_equal(got.faces, np.asarray(expected.faces))
    made = trimesh.Trimesh(**got.kwargs(), process=False)
    np.testing.assert_array_equal(made.vertices, expected.vertices)
    np.testing.assert_array_equal(made.faces, expected.faces)
    for name in ("vertex_normals", "face_normals"):
        if name in expected._cache.cache:
            np.testing.assert_array_equal(made._cache[name], expected._cache[name])
    assert made.visual.kind == expected.visual.kind
    if expected.visual.kind == "vertex":
        np.testing.assert_array_equal(made.visual.vertex_colors, expected.visual.vertex_colors)
    elif expected.visual.kind == "face":
        np.testing.assert_array_equal(made.visual.face_colors, expected.visual.face_colors)
    elif expected.visual.kind == "texture":
        np.testing.assert_array_equal(made.visual.uv, expected.visual.uv)
    assert set(made.face_attributes) == set(expected.face_attributes)
    for key, value in expected.face_attributes.items():
        np.testing.assert_array_equal(made.face_attributes[key], value)
    return got


@pytest.fixture(scope="module")
def mesh():
    """A closed mesh with coordinates that need every digit (no round numbers)."""
    m = trimesh.creation.icosphere(subdivisions=2)
    rng = np.random.default_rng(0)
    m.vertices = m.vertices * [1.3, 0.7, 2.1] + rng.normal(scale=0.01, size=m.vertices.shape) + [10.0, -3.0, 0.5]
    return m


def exported(mesh, file_type, **kwargs):
    data = mesh.export(file_type=file_type, **kwargs)
    return data.encode() if isinstance(data, str) else data


# --------------------------------------------------------------------------- OFF
def test_off_exported(mesh):
    check_same(exported(mesh, "off"), "off")


OFF_VARIANTS = {
    "comments_blank_crlf": "# made by hand\r\nOFF\r\n# counts\r\n\r\n4 2 0\r\n0 0 0 # first\r\n1 0 0\r\n\r\n"
                           "1 1 0\r\n0 1 0.5\r\n# faces\r\n3 0 1 2\r\n3 0 2 3\r\n",
    "counts_on_header_line": "OFF 4 2 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n3 0 1 2\n3 0 2 3\n",
    "coff_colors": "COFF\n4 2 0\n0 0 0 255 0 0 255\n1 0 0 0 255 0 255\n1 1 0 0 0 255 255\n0 1 0 9 9 9 255\n"
                   "3 0 1 2 0.5 0.5 0.5\n3 0 2 3 0.1 0.2 0.3\n",
    "quads": "OFF\n6 2 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n2 0 0\n2 1 0\n4 0 1 2 3\n4 1 4 5 2\n",
    "mixed_triangles_quads": "OFF\n6 3 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n2 0 0\n2 1 0\n4 1 4 5 2\n3 0 1 2\n4 0 1 2 3\n",
    "indented_trailing_spaces": "  OFF\n  3 1 0  \n\t0 0 0\n 1e-3 0 0 \n0 1.5E+2 -0\n  3   0 1 2   \n\n\n",
    "more_faces_than_lines_hold_extra_lines": "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 2 1 0\n",
}


@pytest.mark.parametrize("name", sorted(OFF_VARIANTS))
def test_off_by_hand(name):
    check_same(OFF_VARIANTS[name], "off")


OFF_POLYGONS = {
    "mixed": ("OFF\n8 4 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n2 0 0\n2 1 0\n3 0.5 0\n3 1.5 1\n",
              "5 1 4 6 5 2\n3 0 1 2\n4 0 1 2 3\n6 4 6 7 5 2 1\n"),
    "pentagons": ("OFF\n6 2 0\n0 0 0\n1 0 0\n1.5 1 0\n0.5 1.5 0\n-0.5 1 0\n2 2 2\n", "5 0 1 2 3 4\n5 5 4 3 2 1\n"),
}


@pytest.mark.parametrize("name", sorted(OFF_POLYGONS))
def test_off_polygons(name):
    """trimesh's OFF loader fails on polygons of more than 4 corners (it fans the index strings);
    the reader gives what trimesh.geometry.triangulate_quads gives for the integer lists."""
    head, faces = OFF_POLYGONS[name]
    got = readers.read((head + faces).encode(), "off")
    polygons = [[int(i) for i in line.split()[1:]] for line in faces.splitlines()]
    np.testing.assert_array_equal(got.faces, trimesh.geometry.triangulate_quads(polygons))
    first = head.replace(head.splitlines()[1], head.splitlines()[1].split()[0] + " 1 0") + "3 0 1 2\n"
    np.testing.assert_array_equal(got.vertices, trimesh_load(first.encode(), "off").vertices)


@pytest.mark.parametrize("text", [
    "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 5\n",      # index out of range: trimesh raises
    "OFF\n3 0 0\n0 0 0\n1 0 0\n0 1 0\n",               # no faces: a point cloud
    "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0x1\n3 0 1 2\n",    # a number float() and strtod read differently
    "PLY\n",
])
def test_off_refused(text):
    with pytest.raises(Unsupported):
        readers.read(text.encode(), "off")


@pytest.mark.parametrize("head", ["OFF\n4 2 b0\n", "OFF\n4 2 99999999999999999999\n",
                                  "# made by hand\nOFF\n4 2 99999999999999999999\n"])
def test_off_counts_line_that_trimesh_refuses_is_refused(tmp_path, head):
    """A counts line whose third count is no int64 (a corrupted byte, an overflow): trimesh refuses
    the file, and so does jaxpose (the reader read it, ignoring that count; found by fuzzing)."""
    from jaxpose import mesh as jmesh
    from jaxpose.errors import InvalidInputError

    data = (head + "0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 1 2\n3 0 2 3\n").encode()
    with pytest.raises((ValueError, OverflowError)):
        trimesh_load(data, "off")
    with pytest.raises(InvalidInputError, match="its counts line '4 2 .*' (is not|holds a count beyond)"):
        readers.read(data, "off")
    path = tmp_path / "counts.off"
    path.write_bytes(data)
    with pytest.raises(InvalidInputError, match="counts.off: cannot read OFF file: its counts line"):
        jmesh.load(path)


# OFF files in the layout most writers produce: read on the bytes (readers.off._off_plain)
TRIANGLES = "0 0 0\n1 0 0\n1 1 0\n0 1 0.5\n3 0 1 2\n3 0 2 3\n"
OFF_PLAIN = {
    "lf": "OFF\n4 2 0\n" + TRIANGLES,
    "crlf": ("OFF\n4 2 0\n" + TRIANGLES).replace("\n", "\r\n"),
    "no_final_newline": "OFF\n4 2 0\n" + TRIANGLES.rstrip("\n"),
    "two_counts_blank_head": "\n \nOFF \n4 2\n" + TRIANGLES,
    "coff_vertex_colors": "COFF\n4 2 0\n0 0 0 255 0 0 255\n1 0 0 0 255 0 255\n1 1 0 0 0 255 255\n0 1 0 9 9 9 255\n"
                          "3 0 1 2\n3 0 2 3\n",
    "face_colors": "OFF\n4 2 0\n" + TRIANGLES.replace("2\n", "2 255 0 0\n").replace(" 3\n", " 3 0 255 0\n"),
    "signs_exponents": "OFF\n4 2 0\n-0 +1e-3 .5\n1. -2.5E+2 0.1234567890123456789\n1e300 1 0\n0 1 -7\n"
                       "3 0 1 2\n3 00 2 3\n",
    "lines_after_the_faces": "OFF\n4 2 0\n" + TRIANGLES + "3 1 2 3\nanything at all\n",
}
# the same meshes in layouts read line by line (the careful path), and files that are broken
OFF_NOT_PLAIN = {
    "comment": "# made by hand\nOFF\n4 2 0\n" + TRIANGLES,  # (trimesh garbles comments after data)
    "two_spaces": "OFF\n4 2 0\n" + TRIANGLES.replace("1 1 0", "1  1 0"),
    "tab": "OFF\n4 2 0\n" + TRIANGLES.replace("1 1 0", "1\t1 0"),
    "leading_space": "OFF\n4 2 0\n" + TRIANGLES.replace("1 1 0", " 1 1 0"),
    "trailing_space": "OFF\n4 2 0\n" + TRIANGLES.replace("3 0 1 2", "3 0 1 2 "),
    "blank_line": "OFF\n4 2 0\n" + TRIANGLES.replace("1 1 0\n", "1 1 0\n\n"),
    "lone_cr": "OFF\r4 2 0\r" + TRIANGLES.replace("\n", "\r"),
    "counts_on_header_line": "OFF 4 2 0\n" + TRIANGLES,
    "vertex_lines_of_several_lengths": "OFF\n4 2 0\n" + TRIANGLES.replace("1 0 0", "1 0 0 7"),
    "quads": "OFF\n4 1 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n",
    "non_ascii_comment": "# caf\u00e9\nOFF\n4 2 0\n" + TRIANGLES,
}


OFF_LATE_COMMENTS = {  # a comment after the first line end: trimesh's comment_strip repeats lines before it
    "after_counts": "OFF\n4 2 0\n# the vertices\n" + TRIANGLES,
    "between_blocks": "OFF\n4 2 0\n" + TRIANGLES.replace("3 0 1 2", "# the faces\n3 0 1 2"),
    "end_of_lines": "OFF\n4 2 0\n" + TRIANGLES.replace("\n", " # note\n"),
    "header_line": "OFF # made by hand\n4 2 0\n" + TRIANGLES,
    "crlf": ("OFF\n4 2 0\n# the vertices\n" + TRIANGLES).replace("\n", "\r\n"),
}


@pytest.mark.parametrize("name", sorted(OFF_LATE_COMMENTS))
def test_off_comments_anywhere_are_cut_to_their_line_end(name):
    """Read as the file without its comments: trimesh (and the reader, which copied it) read
    'OFF\\n4 2 0\\n# the vertices\\n...' with '4 2 0' a second time as the first vertex, every vertex
    one line late and a face lost, without a word."""
    data = OFF_LATE_COMMENTS[name].encode()
    plain = b"\n".join(line.split(b"#")[0].rstrip() for line in data.split(b"\n"))
    got, expected = readers.read(data, "off"), readers.read(plain, "off")
    np.testing.assert_array_equal(got.vertices, expected.vertices)
    np.testing.assert_array_equal(got.faces, expected.faces)
    np.testing.assert_array_equal(got.vertices, trimesh_load(OFF_PLAIN["lf"].encode(), "off").vertices)
    assert readers.off.without_comments(data).count(b"\n") == data.count(b"\n") and b"#" not in \
        readers.off.without_comments(data)


@pytest.mark.parametrize("name", sorted(OFF_PLAIN))
def test_off_plain_layouts(name):
    """Read on the bytes, and equal to trimesh's mesh."""
    data = OFF_PLAIN[name].encode()
    assert readers.off._off_plain(data) is not None
    check_same(data, "off")


@pytest.mark.parametrize("name", sorted(OFF_NOT_PLAIN))
def test_off_other_layouts_read_line_by_line(name):
    data = OFF_NOT_PLAIN[name].encode()
    assert readers.off._off_plain(data) is None
    check_same(data, "off")


@pytest.mark.parametrize("text", [
    "OFF\n4 2 0\n0 0 0\n1 0\n1 1 0 5\n0 1 0\n3 0 1 2\n3 0 2 3\n",  # 2 and 4 values: 6 in all
    "OFF\n4 2 0\n0 0 0\n1 0 0\n1.2.3 1 0\n0 1 0\n3 0 1 2\n3 0 2 3\n",  # not one number
    "OFF\n4 2 0\n0 0 0\n1 0 0\n1-2 1 0\n0 1 0\n3 0 1 2\n3 0 2 3\n",
    "OFF\n4 2 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n3 0 1 2\n3 0 2 3 4\n",  # a longer face line
    "OFF\n4 2 0\n0 0 0\n1 0 0\n1 1 0\n0 1 e\n3 0 1 2\n3 0 2 3\n",
])
def test_off_plain_refuses_what_is_not_plain(text):
    """Values that are not one number each, or lines of several lengths: not read on the bytes."""
    assert readers.off._off_plain(text.encode()) is None


def _token_positions(block):
    chars = np.frombuffer(block, np.uint8)
    ends = np.flatnonzero((chars == 32) | (chars == 10))
    starts = np.concatenate([[0], ends[:-1] + 1])
    return chars, starts, ends


@pytest.mark.parametrize("decimals", [0, 1, 3, 6, 10, 13])
@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e4])
def test_off_fixed_decimals_are_floats(decimals, scale):
    """Fixed-decimal values read as integers over 10^F: bit for bit Python's float of each token
    (signs, -0, no digit before the point, no digit after it, up to 15 digits)."""
    rng = np.random.default_rng(decimals)
    tokens = [f"{v:.{decimals}f}" for v in rng.normal(size=3000) * scale]
    tokens = [t if sum(c.isdigit() for c in t) <= 15 else "1." + "0" * decimals for t in tokens]
    tokens[::7] = [t.replace("0.", ".", 1) if t.startswith(("0.", "-0.")) and decimals else t for t in tokens[::7]]
    if decimals == 0:
        tokens = [t + "." for t in tokens]  # "12."
    tokens[1::11] = ["-0." + "0" * decimals] * len(tokens[1::11])
    block = "".join(f"{a} {b} {c}\n" for a, b, c in zip(*[iter(tokens)] * 3)).encode()
    got = readers.off._decimals(*_token_positions(block))
    assert got is not None
    np.testing.assert_array_equal(got.view(np.int64), np.array([float(t) for t in tokens]).view(np.int64))


@pytest.mark.parametrize("tokens", [
    "1.5 2.25 3.5",    # several decimal counts
    "1 2 3",           # no point
    "1.5 -2.5 3.5e1",  # an exponent
    "1.5 +2.5 3.5",    # a plus sign
    "1.5 2-5 3.5",
    "1.5 2.5.5 3.5",
    "1.5 . 3.5",       # no digit
    "1.5 -.5 1234567890123.45",  # 16 digits: not exact as an integer here
])
def test_off_fixed_decimals_refuse_other_tokens(tokens):
    assert readers.off._decimals(*_token_positions(tokens.encode() + b"\n")) is None


@pytest.mark.parametrize("cut", ["vertex", "face_line", "mid_face", "all_faces"])
def test_off_truncated_is_an_error(tmp_path, mesh, cut):
    """A truncated OFF file is an error naming it, where trimesh reads part of it: fewer vertex or
    face lines than the counts line says, or a last face cut short."""
    from jaxpose import mesh as jmesh
    from jaxpose.errors import InvalidInputError

    data = exported(mesh, "off")
    lines = data.splitlines(keepends=True)
    nv = len(mesh.vertices)
    kept = {"vertex": lines[:nv], "face_line": lines[:-1], "mid_face": lines[:-1] + [lines[-1][:4]],
            "all_faces": lines[:nv + 2]}[cut]
    path = tmp_path / "cut.off"
    path.write_bytes(b"".join(kept))
    with pytest.raises(InvalidInputError, match="cut.off: .*(truncated|fewer indices than its count.*truncated)"):
        jmesh.load(path)


@pytest.mark.parametrize("newline", ["\n", "\r\n"])
@pytest.mark.parametrize("bad, what", [("1 0", "vertex 2"), ("3 0 1", "face 2")])
def test_off_short_lines_are_named_by_their_line_in_the_file(tmp_path, newline, bad, what):
    """A short OFF vertex or face line is named by its place among the vertices (faces) and its
    line number in the file, as the PLY reader names a short vertex line (comments, blank lines
    and the header counted: the number an editor shows; it said 'vertex line 2' before)."""
    from jaxpose import mesh as jmesh
    from jaxpose.errors import InvalidInputError

    lines = ["# a tetrahedron", "", "OFF", "# counts", "4 2 0", "", "0 0 0", "1 0 0  # two", "0 1 0", "0 0 1", "",
             "3 0 1 2", "3 0 1 3"]
    at = 7 if what.startswith("vertex") else 12  # (0-based) the second vertex line, the second face line
    lines[at] = bad
    path = tmp_path / "short.off"
    path.write_bytes(newline.join(lines).encode() + newline.encode())
    line = path.read_bytes().decode().splitlines().index(bad) + 1  # the oracle: the line an editor shows
    with pytest.raises(InvalidInputError, match=f"short.off: cannot read OFF file: {what} \\(line {line} of the file\\) "
                       "holds .*truncated or malformed"):
        jmesh.load(path)


@pytest.mark.parametrize("cut", ["face_line", "mid_face", "counts", "negative"])
def test_ply_truncated_is_an_error(tmp_path, mesh, cut):
    """A truncated ASCII PLY file is an error naming it, where trimesh reads part of it without a
    word (a mesh short of faces, or a point cloud of the face lines): fewer lines than the header's
    counts, a last face cut short, a negative count."""
    from jaxpose import mesh as jmesh
    from jaxpose.errors import InvalidInputError

    data = exported(mesh, "ply", encoding="ascii")
    lines = data.splitlines(keepends=True)
    nv = len(mesh.vertices)
    header = data[:data.index(b"end_header")]
    kept = {"face_line": data[:-len(lines[-1])], "mid_face": data[:-len(lines[-1])] + lines[-1][:5],
            "counts": data.replace(f"element vertex {nv}".encode(), f"element vertex {nv + 50}".encode()),
            "negative": data.replace(f"element vertex {nv}".encode(), f"element vertex -{nv}".encode())}[cut]
    assert header and kept != data
    path = tmp_path / "cut.ply"
    path.write_bytes(kept)
    with pytest.raises(InvalidInputError, match="cut.ply: .*(truncated|negative count)"):
        jmesh.load(path)


def test_a_blank_line_inside_an_ascii_ply_data_is_named(tmp_path):
    """ASCII PLY holds one element a line (trimesh's reader, plyfile's): a blank line among the
    vertex or face lines shifts every later one, and trimesh failed with "setting an array element
    with a sequence." or "index 0 is out of bounds for axis 0 with size 0". The error names the
    line (a point cloud's, another element's too); blank lines after the last element's, which
    nothing reads, are read as before."""
    from jaxpose import mesh as jmesh
    from jaxpose.errors import InvalidInputError

    head = ("ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
            "element face 4\nproperty list uchar int vertex_indices\n")
    vertices = ["0 0 0", "1 0 0", "0 1 0", "0 0 1"]
    faces = ["3 0 2 1", "3 0 1 3", "3 0 3 2", "3 1 2 3"]
    cases = {"vertex": (vertices[:2] + [""] + vertices[2:] + faces, 12, "vertex"),
             "between": (vertices + ["  \t"] + faces, 14, "face"),
             "face": (vertices + faces[:3] + [""] + faces[3:], 17, "face"),
             "first": ([""] + vertices + faces, 10, "vertex")}
    for name, (lines, number, element) in cases.items():
        for end in ("\n", "\r\n"):
            path = tmp_path / f"{name}.ply"
            path.write_bytes((head + "end_header\n" + "\n".join(lines) + "\n").replace("\n", end).encode())
            with pytest.raises(InvalidInputError, match=rf"{name}.ply: cannot read PLY file: line {number} is blank, "
                                                        rf"inside its {element} data \(ASCII PLY holds one element a line"):
                jmesh.load(path)
    cloud = tmp_path / "cloud.ply"
    cloud.write_text(head.split("element face")[0] + "end_header\n" + "\n".join(vertices[:3] + [""] + vertices[3:]) + "\n")
    with pytest.raises(InvalidInputError, match=r"cloud.ply: cannot read PLY file: line 11 is blank, inside its vertex"):
        jmesh.load(cloud)
    edges = head + "element edge 2\nproperty int vertex1\nproperty int vertex2\nend_header\n"
    (tmp_path / "edges.ply").write_text(edges + "\n".join(vertices + faces + ["0 1", "", "1 2"]) + "\n")
    with pytest.raises(InvalidInputError, match=r"edges.ply: cannot read PLY file: line 22 is blank, inside its edge"):
        jmesh.load(tmp_path / "edges.ply")  # (trimesh reads every element: it failed too)
    blank_first = ply_bytes("ascii", ([("float", "x"), ("float", "y"), ("float", "z")], SQUARE),
                            (["list uchar int vertex_indices"], [((0, 1, 2),)])).replace(b"end_header\n", b"end_header\n\n")
    with pytest.raises(InvalidInputError, match=r"^cannot read PLY file: line 11 is blank, inside its vertex data"):
        readers.read(blank_first, "ply")  # (test_ply_refused's before: Unsupported, for trimesh, which failed)
    (tmp_path / "after.ply").write_text(head + "end_header\n" + "\n".join(vertices + faces) + "\n\n \n")
    loaded = jmesh.load(tmp_path / "after.ply")
    np.testing.assert_array_equal(loaded.vertices, [[float(v) for v in line.split()] for line in vertices])
    np.testing.assert_array_equal(loaded.faces, [[int(v) for v in line.split()[1:]] for line in faces])


@pytest.mark.parametrize("cut, fragment", [
    (-30, "truncated binary STL: its header counts 12 triangles (684 bytes), the file has 654 bytes"),
    (-50 * 12, "truncated binary STL: its header counts 12 triangles (684 bytes), the file has 84 bytes"),
    (-620, "truncated binary STL: 64 bytes, fewer than its 84-byte header"),
    (+7, "size does not match its header: 12 triangles take 684 bytes, the file has 691"),
])
def test_a_truncated_binary_stl_says_so(tmp_path, cut, fragment):
    """A binary STL cut short (or with bytes after its triangles) read as "empty geometry ... not
    STL" or as text needing trimesh's optional module; the message says what is wrong with its size."""
    from jaxpose import mesh as jmesh
    from jaxpose.errors import InvalidInputError

    data = exported(trimesh.creation.box(), "stl")
    assert len(data) == 84 + 50 * 12  # the oracle: the format's size rule for the box's 12 triangles
    for header in (b"", b"solid box"):  # some exporters begin a binary header with "solid"
        path = tmp_path / "cut.stl"
        whole = header + data[len(header):]
        path.write_bytes(whole[:cut] if cut < 0 else whole + b"\x01" * cut)
        with pytest.raises(InvalidInputError, match="cut.stl: a ") as info:
            jmesh.load(path)
        assert fragment in str(info.value), info.value


@pytest.mark.parametrize("name", ["noise.stl", "noise.ply", "noise.off", "noise.obj"])
def test_binary_noise_is_an_error_about_the_file(tmp_path, name):
    """Random bytes under a mesh suffix: an error naming the file and its format, never about
    the reader's machinery (a garbage STL read 'No module named charset_normalizer': trimesh's
    optional module for text it could not parse)."""
    from jaxpose import mesh as jmesh
    from jaxpose.errors import InvalidInputError

    path = tmp_path / name
    path.write_bytes(np.random.default_rng(0).integers(0, 256, 3000, dtype=np.uint8).tobytes())
    with pytest.raises(InvalidInputError, match=f"{name}: ") as info:
        jmesh.load(path)
    assert "No module named" not in str(info.value), info.value


@pytest.mark.parametrize("name, data, match", [
    # a truncated .gltf said "it refers to model.gltf, which is not in its folder" (trimesh, the JSON
    # unread, asked for a file of its own name); not JSON at all alike
    ("cut.gltf", b'{"asset": {"version": "2.0"}, "meshes": [', "cut.gltf: cannot read GLTF file: not a JSON text "),
    ("text.gltf", b"hello\n", "text.gltf: cannot read GLTF file: not a JSON text "),
    # it said trimesh's "not enough values to unpack (expected 3, got 1)"
    ("plain.off", b"4 1 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 1 2\n", "plain.off: cannot read OFF file: no OFF header "),
])
def test_a_file_not_of_its_format_is_named_so(tmp_path, name, data, match):
    from jaxpose import mesh as jmesh
    from jaxpose.errors import InvalidInputError

    path = tmp_path / name
    path.write_bytes(data)
    with pytest.raises(InvalidInputError, match=match) as info:
        jmesh.load(path)
    assert "model.gltf" not in str(info.value) and "unpack" not in str(info.value), info.value


OBJ_TET = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n"
PLY_TET_HEAD = ("ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
                "element face 4\nproperty list uchar int vertex_indices\nend_header\n")


@pytest.mark.parametrize("name, text, match", [
    ("index.ply", PLY_TET_HEAD + "0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 7\n",
     "index.ply: faces must be .* indices of its vertices .*vertex 7 of 4"),
    ("zero.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 0 3 4\n",
     "zero.obj: .*index 0 .*count from 1"),
    # in OBJ's own numbering (it read 'index 8 is out of bounds for axis 0 with size 4', trimesh's IndexError)
    ("index.obj", OBJ_TET + "f 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 9\n", "index.obj: .*a face references vertex 9 of the 4 "),
    ("back.obj", OBJ_TET + "f 1 3 2\nf 1 2 4\nf 1 4 3\nf -1 -2 -5\n", "back.obj: .*a face references vertex -5 of the 4 "),
    ("flat.obj", "v 0 0\nv 1 0\nv 0 1\nf 1 2 3\n", "flat.obj: .*vertex 1 has fewer than 3 coordinates"),
    # the same where trimesh reads the file (materials, faces of several forms): it read them without a word
    ("zero_forms.obj", OBJ_TET + "f 1 3 2\nf 1 2 4\nf 0/1 3/1 4/1\n", "zero_forms.obj: .*index 0 "),
    # (they read trimesh's 'index 8 is out of bounds for axis 0 with size 4')
    ("index_material.obj", OBJ_TET + "usemtl a\nf 1 3 2\nf 2 3 9\n", "index_material.obj: .*a face references vertex 9 of the 4 "),
    ("index_forms.obj", OBJ_TET + "f 1 3 2\nf 1/1 2/1 4/1\nf -1//1 -2//1 -5//1\n", "index_forms.obj: .*references vertex -5 of the 4 "),
    ("cut_material.obj", OBJ_TET + "usemtl a\nf 1 3 2\nf 1 2 4\nf 1 4", "cut_material.obj: .*last line 'f 1 4' .*fewer"),
    ("bare_material.obj", OBJ_TET + "usemtl a\nf 1 3 2\nf 1 2 4\nf\n", "bare_material.obj: .*last line 'f' is a face"),
    ("vertex_material.obj", OBJ_TET + "usemtl a\nf 1 3 2\nf 1 2 4\nv 1 2\n", "vertex_material.obj: .*last line 'v 1 2'"),
    # a texture coordinate that is not there: trimesh dropped all of the file's UV without a word
    ("uv.obj", OBJ_TET + "vt 0 0\nvt 1 0\nf 1/1 3/2 2/1\nf 1/1 2/3 4/1\n",
     "uv.obj: .*a face references texture coordinate 3 of the 2 it has .*UV coordinates would be dropped"),
    ("uv_back.obj", OBJ_TET + "vt 0 0\nf 1/-2 3/1 2/1\n", "uv_back.obj: .*texture coordinate -2 of the 1 "),
    ("uv_normals.obj", OBJ_TET + "vt 0 0\nvn 0 0 1\nf 1/1/1 3/1/1 2/9/1\n", "uv_normals.obj: .*texture coordinate 9 of the 1 "),
    ("uv_material.obj", OBJ_TET + "vt 0 0\nusemtl a\nf 1/1 3/1 2/1\nf 1/1 2/5 4/1\n",
     "uv_material.obj: .*texture coordinate 5 of the 1 "),
    ("uv_forms.obj", OBJ_TET + "vt 0 0\nf 1 3 2\nf 1/1 2/1 4/1\nf 1/4 4/1 3/1\n", "uv_forms.obj: .*texture coordinate 4 of the 1 "),
    # (fuzzed) a face line cut by "usemtl": trimesh's scene of it raised a raw ValueError when flattened
    ("scene.obj", "v 3 0 2 6 9 6\nv 7 6 6 6 3 2\nv 7 3 9 9 2 4\nv 5 1 6 0 5 3\nv 4 1 6 7 1 4\nf 5usemtl \nf 1 1 2",
     "scene.obj: cannot flatten its scene into one mesh: face colors incorrect shape"),
])
def test_broken_references_are_errors(tmp_path, name, text, match):
    """Faces that reference a vertex that is not there (trimesh's loader left a raw IndexError for
    the merge), OBJ's index 0 (trimesh reads the last vertex) and 2-coordinate vertices are errors
    naming the file; faces of several forms too, and in a file with materials (read by trimesh) a
    last line cut to a face of fewer than 3 corners or a vertex of fewer than 3 values (trimesh drops
    it without a word; found by fuzzing)."""
    from jaxpose import mesh as jmesh
    from jaxpose.errors import InvalidInputError

    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(InvalidInputError, match=match):
        jmesh.load(path)


@pytest.mark.parametrize("faces, whole", [
    ("f 1 3 2\nf 1 2 -", "-1"), ("f 1 3 2\nf 1 2 4 -", "-2"), ("f 1 3 2\nf 1 2 4/", "4"),
    ("vt 0 0\nf 1/1 3/1 2/1\nf 1/1 2/1 4/", "4/1"), ("vt 0 0\nf 1/1 3/1 2/1\nf 1/1 2/1 4/-", "4/-1"),
    ("vt 0 0\nvn 0 0 1\nf 1/1/1 3/1/1 2/1/1\nf 1/1/1 2/1/1 4/1", "4/1/1"),
    ("vn 0 0 1\nf 1//1 3//1 2//1\nf -1//1 -2//1 -3//", "-3//1")])
@pytest.mark.parametrize("material", ["", "usemtl a\n"])
def test_an_obj_cut_within_its_last_face_is_an_error(tmp_path, faces, whole, material):
    """An OBJ file cut within its last face line's last corner ('f 1 2 -', 'f 1 2 4/', 'f 1/1/1
    2/1/1 4/1'): trimesh read '-' as vertex 0 and '4/' as 4 (a wrong face, or a wrong mesh, without
    a word) or failed with Python's "invalid literal for int()"; refused as a cut vertex line is, on
    the fast reader's path and trimesh's (materials). The line with its last corner whole reads as
    trimesh reads it."""
    from jaxpose import mesh as jmesh
    from jaxpose.errors import InvalidInputError

    path = tmp_path / "cut.obj"
    path.write_text(OBJ_TET + material + faces)
    last = faces.rsplit("\n", 1)[1]
    with pytest.raises(InvalidInputError, match=f"cut.obj: cannot read OBJ file: its last line '{re.escape(last)}' "
                       f"ends in '{re.escape(last.split()[-1])}', which is not a reference of the form of its first "
                       "corner .*truncated"):
        jmesh.load(path)
    path.write_text(OBJ_TET + material + faces.rsplit(" ", 1)[0] + f" {whole}\n")
    expected = trimesh.load(path, process=False)
    got = jmesh.read(path)
    np.testing.assert_array_equal(np.asarray(got.vertices)[np.asarray(got.faces)],
                                  np.asarray(expected.vertices)[np.asarray(expected.faces)])


@pytest.mark.parametrize("last", ["f 1 2 +3", "f 1/1 2/1 +3/+1", "f +1 2 3"])
def test_an_obj_last_face_with_explicit_plus_signs_reads_as_trimesh_reads_it(tmp_path, last):
    """A last face whose corners carry a '+' sign on some of them only ('f 1 2 +3') is a whole face:
    the cut-face rule took '+3' for another form than '1' and refused the file (review); read as
    trimesh reads it."""
    from jaxpose import mesh as jmesh

    path = tmp_path / "plus.obj"
    path.write_text(OBJ_TET + "vt 0 0\n" + last + "\n")
    expected = trimesh.load(path, process=False)
    got = jmesh.read(path)
    np.testing.assert_array_equal(np.asarray(got.vertices)[np.asarray(got.faces)],
                                  np.asarray(expected.vertices)[np.asarray(expected.faces)])


def test_normal_references_and_uv_references_without_uv_are_not_checked(tmp_path):
    """Out-of-range normal references, and texture references in a file without 'vt' lines, read
    as the file without them on both paths (the fast reader's and trimesh's, with materials): the
    file's normals are never used (read drops them) and a file without UV has none to lose."""
    from jaxpose import mesh as jmesh

    faces = ["f 1{0} 3{0} 2{0}", "f 1{0} 2{1} 4{0}", "f 1{0} 4{0} 3{0}", "f 2{0} 3{0} 4{0}"]
    plain = tmp_path / "plain.obj"
    plain.write_text(OBJ_TET + "\n".join(f.format("", "") for f in faces) + "\n")
    expected = jmesh.read(plain)
    for name, head, forms in (("normals.obj", "vn 0 0 1\n", ("//1", "//7")), ("no_uv.obj", "", ("/1", "/5")),
                              ("normals_uv.obj", "vt 0 0\nvn 0 0 1\n", ("/1/1", "/1/-4"))):
        for material in ("", "usemtl a\n"):
            path = tmp_path / f"{material[:1]}{name}"
            path.write_text(OBJ_TET + head + material + "\n".join(f.format(*forms) for f in faces) + "\n")
            got = jmesh.read(path)
            np.testing.assert_array_equal(np.asarray(got.vertices), np.asarray(expected.vertices))
            np.testing.assert_array_equal(np.asarray(got.faces), np.asarray(expected.faces))


def test_a_valid_textured_obj_read_by_trimesh_is_not_scanned_for_texture_references(tmp_path, monkeypatch):
    """An OBJ with materials and UV that trimesh keeps is not scanned again for its texture
    references (the scan cost 5.2 s and ~650 MB on a 1e6-vertex, 2e6-face file): only a file with
    'vt' lines whose mesh lost its UV is (then named as before, test_broken_references_are_errors)."""
    from jaxpose import mesh as jmesh

    def scan(data):
        raise AssertionError("scanned")

    monkeypatch.setattr(readers.obj, "check_texture_references", scan)
    path = tmp_path / "textured.obj"
    path.write_text(OBJ_TET + "vt 0 0\nvt 1 0\nvt 0 1\nusemtl a\nf 1/1 3/3 2/2\nf 1/1 2/2 4/3\nf 1/1 4/3 3/3\n"
                    "f 2/2 3/3 4/3\n")
    loaded = jmesh.load(path)
    assert loaded.visual.uv is not None and len(loaded.faces) == 4
    path.write_text(OBJ_TET + "vt 0 0\nusemtl a\nf 1/1 3/1 2/1\nf 1/1 2/5 4/1\n")  # UV lost: scanned
    with pytest.raises(AssertionError, match="scanned"):
        jmesh.load(path)


PLY_TET_TEXT = ("ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
                "element face 2\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n"
                "3 0 1 2\n3 0 2 3\n")


# --------------------------------------------------------------------------- PLY
@pytest.mark.parametrize("encoding", ["binary", "ascii"])
def test_ply_exported(mesh, encoding):
    check_same(exported(mesh, "ply", encoding=encoding), "ply")
    colored = mesh.copy()
    colored.visual.vertex_colors = np.random.default_rng(1).integers(0, 255, (len(mesh.vertices), 4))
    check_same(exported(colored, "ply", encoding=encoding), "ply")
    colored = mesh.copy()
    colored.visual.face_colors = np.random.default_rng(2).integers(0, 255, (len(mesh.faces), 4))
    check_same(exported(colored, "ply", encoding=encoding), "ply")


def ply_bytes(encoding, vertex, face, comments=("made by hand",), newline="\n"):
    """A PLY file from structured arrays: vertex (n,) with fields; face as (properties, rows) where
    rows are tuples whose list is a tuple of indices."""
    (vprops, vrows), (fprops, frows) = vertex, face
    lines = ["ply", f"format {encoding} 1.0", *(f"comment {c}" for c in comments),
             f"element vertex {len(vrows)}", *(f"property {t} {n}" for t, n in vprops),
             f"element face {len(frows)}", *(f"property {p}" for p in fprops), "end_header"]
    header = (newline.join(lines) + newline).encode()
    if encoding == "ascii":
        def text(row):
            return " ".join(" ".join(map(str, (len(v), *v))) if isinstance(v, tuple) else str(v) for v in row)
        return header + newline.join(text(r) for r in list(vrows) + list(frows)).encode() + newline.encode()
    endian = ">" if "big" in encoding else "<"
    types = {"float": "f4", "double": "f8", "uchar": "u1", "int": "i4", "uint": "u4", "short": "i2", "ushort": "u2"}
    body = b"".join(np.array(row, [(n, endian + types[t]) for t, n in vprops]).tobytes() for row in vrows)
    for row in frows:
        for prop, value in zip(fprops, row):
            words = prop.split()
            if words[0] == "list":
                body += np.array(len(value), endian + types[words[1]]).tobytes()
                body += np.array(value, endian + types[words[2]]).tobytes()
            else:
                body += np.array(value, endian + types[words[0]]).tobytes()
    return header + body


SQUARE = [(0.0, 0.0, 0.0), (1.0, 0.0, 0.25), (1.0, 1.0, 0.5), (0.0, 1.0, 0.125), (2.0, 0.5, 0.1)]


def extra_vertex(n=len(SQUARE)):
    props = [("float", "x"), ("float", "y"), ("float", "z"), ("float", "quality"), ("float", "nx"), ("float", "ny"),
             ("float", "nz"), ("uchar", "red"), ("uchar", "green"), ("uchar", "blue"), ("int", "flags")]
    rows = [(*SQUARE[i], 0.1 * i, 0.0, 0.6, 0.8, 10 * i, 20, 30 + i, i - 2) for i in range(n)]
    return props, rows


@pytest.mark.parametrize("encoding", ["ascii", "binary_little_endian", "binary_big_endian"])
@pytest.mark.parametrize("counts", ["uchar int", "int uint", "uchar ushort"])
def test_ply_extra_properties(encoding, counts):
    vertex = extra_vertex()
    face = (["int before", f"list {counts} vertex_indices", "float after", "uchar red", "uchar green", "uchar blue"],
            [(7, (0, 1, 2), 0.5, 1, 2, 3), (8, (0, 2, 3), 0.25, 4, 5, 6), (9, (1, 4, 2), 1.5, 7, 8, 9)])
    got = check_same(ply_bytes(encoding, vertex, face), "ply")
    assert set(got.extras) == {"vertex_normals", "vertex_colors", "face_colors"}


@pytest.mark.parametrize("encoding", ["ascii", "binary_little_endian", "binary_big_endian"])
def test_ply_quads_and_double(encoding):
    vertex = ([("double", "x"), ("double", "y"), ("double", "z")], SQUARE + [(2.0, 1.5, 0.3)])
    face = (["list uchar int vertex_index"], [((0, 1, 2, 3),), ((1, 4, 5, 2),)])
    check_same(ply_bytes(encoding, vertex, face), "ply")


def test_ply_ascii_mixed_polygons_crlf():
    vertex = ([("float", "x"), ("float", "y"), ("float", "z")], SQUARE + [(2.0, 1.5, 0.3), (3.0, 1.0, 0.0)])
    face = (["list uchar int vertex_indices", "int flags"],
            [((0, 1, 2, 3), 1), ((1, 4, 2), 2), ((4, 6, 5, 2, 1), 3), ((0, 1, 2), 4)])
    check_same(ply_bytes("ascii", vertex, face, newline="\r\n"), "ply")


PLY_FIVE_HEAD = ("ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nproperty float y\nproperty float z\n"
                 "property uchar red\nproperty uchar green\nproperty uchar blue\nelement face 2\n"
                 "property list uchar {kind} vertex_indices\nend_header\n0 0 0 1 2 3\n1 0 0.25 1 2 3\n1 1 0.5 1 2 3\n"
                 "0 1 0.125 1 2 3\n2 0.5 0.1 1 2 3\n")


@pytest.mark.parametrize("kind, faces", [
    ("uint", "3 0 1 2\n3 0 2 4294967296\n"),  # beyond uint32: trimesh reads vertex 0
    ("uint", "3 0 1 2\n3 0 2 1e300\n"),
    ("uint", "3 0 1 2\n3 0 2 nan\n"),
    ("uchar", "3 0 1 2\n3 0 2 256\n"),
    ("ushort", "3 0 1 2\n3 0 2 65538\n"),   # trimesh reads vertex 2
    ("int", "3 0 1 2\n3 0 2 1.5\n"),        # trimesh reads vertex 1
    ("uint", "3 4 0 1\n5 2 0 4 3 123456789012345678\n"),  # (fuzzed: trimesh and the reader cast it apart)
])
def test_ply_ascii_index_not_of_its_type_is_an_error(tmp_path, kind, faces):
    """An ASCII PLY face index that is no integer of its declared type: trimesh casts it to some index
    of the type without a word (which one: the machine's float-to-integer conversion, and NumPy's
    loops differ), the reader did the same; the file is refused, naming the line (found by fuzzing)."""
    from jaxpose import mesh as jmesh
    from jaxpose.errors import InvalidInputError

    data = (PLY_FIVE_HEAD.format(kind=kind) + faces).encode()
    with pytest.raises(InvalidInputError, match="face line 2 holds an index that is not an integer of its type"):
        readers.read(data, "ply")
    path = tmp_path / "index.ply"
    path.write_bytes(data)
    with pytest.raises(InvalidInputError, match="index.ply: cannot read PLY file: face line 2"):
        jmesh.load(path)


PLY_SHORT_HEAD = ("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                  "{extra}element face 1\nproperty list uchar int vertex_indices\nend_header\n")
PLY_RGB = "property uchar red\nproperty uchar green\nproperty uchar blue\n"


@pytest.mark.parametrize("extra, body, line", [
    ("", "0 0 0\n1 0\n0 1 0\n3 0 1 2\n", 11),
    (PLY_RGB, "0 0 0 255 0 0\n1 0\n0 1 0 0 0 255\n3 0 1 2\n", 14),
    (PLY_RGB, "0 0\n1 0\n0 1\n3 0 1 2\n", 13),  # every line (trimesh: KeyError 'z')
])
def test_ply_ascii_vertex_line_without_its_coordinates_is_an_error(tmp_path, extra, body, line):
    """An ASCII PLY vertex line with fewer values than its x, y, z: refused, naming the vertex and
    the file's line; trimesh's error named neither ('setting an array element with a sequence.').
    Also through trimesh's path (a point cloud: no faces)."""
    from jaxpose import mesh as jmesh
    from jaxpose.errors import InvalidInputError

    data = (PLY_SHORT_HEAD.format(extra=extra) + body).encode()
    vertex = 1 if body.startswith("0 0\n") else 2
    with pytest.raises(InvalidInputError, match=f"vertex {vertex} \\(line {line} of the file\\) holds 2 values, fewer "
                                                "than the 3 its properties need up to x, y, z"):
        readers.read(data, "ply")
    cloud = data.replace(b"element face 1\nproperty list uchar int vertex_indices\n", b"").replace(b"3 0 1 2\n", b"")
    for name, text, at in (("mesh.ply", data, line), ("cloud.ply", cloud, line - 2)):  # (2 header lines fewer)
        (tmp_path / name).write_bytes(text)
        with pytest.raises(InvalidInputError, match=f"{name}: cannot read PLY file: vertex {vertex} \\(line {at} of"):
            jmesh.load(tmp_path / name)


def test_ply_ascii_vertex_line_without_its_color_is_read_as_trimesh_does(tmp_path):
    """A vertex line that lacks only its color columns: trimesh reads the file (its colors
    dropped); so does mesh.load (trimesh's path), no error."""
    from jaxpose import mesh as jmesh

    data = (PLY_SHORT_HEAD.format(extra=PLY_RGB) + "0 0 0 255 0 0\n1 0 0\n0 1 0 0 0 255\n3 0 1 2\n").encode()
    expected = trimesh_load(data, "ply")
    with pytest.raises(Unsupported):
        readers.read(data, "ply")
    (tmp_path / "rgb.ply").write_bytes(data)
    loaded = jmesh.load(tmp_path / "rgb.ply")
    np.testing.assert_array_equal(loaded.vertices, expected.vertices)
    np.testing.assert_array_equal(loaded.faces, [[0, 1, 2]])


def test_ply_ascii_value_beyond_its_type_is_left_to_trimesh():
    """A vertex color beyond its uchar (300): the cast is the machine's choice, so the reader does
    not guess trimesh's value; trimesh reads the file. With a face index beyond its type too, the
    file is refused (not left to trimesh's silent cast)."""
    from jaxpose.errors import InvalidInputError

    data = (PLY_FIVE_HEAD.format(kind="int").replace("1 1 0.5 1 2 3", "1 1 0.5 300 2 3") + "3 0 1 2\n3 0 2 3\n").encode()
    assert len(trimesh_load(data, "ply").faces) == 2
    with pytest.raises(Unsupported):
        readers.read(data, "ply")
    with pytest.raises(InvalidInputError, match="face line 2 holds an index that is not an integer of its type int32"):
        readers.read(data.replace(b"3 0 2 3\n", b"3 0 2 4294967296\n"), "ply")


MIXED_VERTEX = ([("float", "x"), ("float", "y"), ("float", "z")], SQUARE + [(2.0, 1.5, 0.3), (3.0, 1.0, 0.0)])
MIXED_FACE = (["int before", "list uchar int vertex_indices", "float after", "uchar red", "uchar green", "uchar blue"],
              [(7, (0, 1, 2, 3), 0.5, 1, 2, 3), (8, (1, 4, 2), 0.25, 4, 5, 6), (9, (4, 6, 5, 2, 1), 1.5, 7, 8, 9),
               (1, (0, 1, 2), 2.5, 9, 9, 9)])


@pytest.mark.parametrize("encoding", ["binary_little_endian", "binary_big_endian"])
def test_ply_binary_faces_of_several_sizes_read_as_their_ascii_file(tmp_path, encoding):
    """A binary PLY of triangles, quads and a pentagon (Blender and MeshLab write such files):
    trimesh refuses it ("PLY is unexpected length!": it reads every list as long as the first), and
    so did jaxpose, calling the file truncated. Read now, as trimesh reads the same faces written
    as ASCII PLY (vertices, the triangulated faces, the face colors)."""
    from jaxpose import mesh as jmesh

    data = ply_bytes(encoding, MIXED_VERTEX, MIXED_FACE)
    with pytest.raises(ValueError):
        trimesh_load(data, "ply")
    expected = trimesh_load(ply_bytes("ascii", MIXED_VERTEX, MIXED_FACE), "ply")
    got = readers.read(data, "ply")
    np.testing.assert_array_equal(got.vertices, expected.vertices)
    np.testing.assert_array_equal(got.faces, expected.faces)
    np.testing.assert_array_equal(got.extras["face_colors"], expected.visual.face_colors[:, :3])
    (tmp_path / "mixed.ply").write_bytes(data)
    np.testing.assert_array_equal(jmesh.load(tmp_path / "mixed.ply").faces, expected.faces)


def test_ply_binary_faces_of_several_sizes_cut_or_beside_other_elements():
    """Such a file cut short, or with bytes after its last face, is named so, with the face where it
    ends; beside an element this reader does not read (which trimesh cannot read either), the file
    is refused saying what it holds and what to do, not called truncated."""
    from jaxpose.errors import InvalidInputError

    data = ply_bytes("binary_little_endian", MIXED_VERTEX, MIXED_FACE)
    with pytest.raises(InvalidInputError, match="truncated, 185 bytes after the header end inside its face 4 of 4"):
        readers.read(data[:-7], "ply")
    with pytest.raises(InvalidInputError, match="2 bytes after its last element .*take 192, every list as long as"):
        readers.read(data + b"xx", "ply")
    empty = ply_bytes("binary_little_endian", (MIXED_VERTEX[0], []), MIXED_FACE)
    with pytest.raises(InvalidInputError, match=r"lists have several lengths \(3, 4, 5\) and no vertices or no faces: "
                                                r"jaxpose does not read it \(nor does trimesh\)"):
        readers.read(empty, "ply")
    far = ply_bytes("binary_little_endian", MIXED_VERTEX, (MIXED_FACE[0], [MIXED_FACE[1][0], (8, (1, 99, 2), 0.25, 4, 5, 6)]))
    with pytest.raises(InvalidInputError, match="a face references vertex 99 of 7: a malformed file"):
        readers.read(far, "ply")  # (the fallback to trimesh said "PLY is unexpected length!": review)


def test_ply_binary_faces_of_several_sizes_also_where_their_bytes_fit_the_first_rule():
    """Faces of several sizes that take as many bytes as if all were as long as the first (a quad, a
    triangle, a pentagon, a quad: 4 corners a face on average): trimesh's length rule holds, so the
    file went to trimesh, which read wrong faces without a word (uchar indices) or failed ("a face
    references vertex 1797"; review). Read as the ASCII file is; beside other elements (an edge
    list, which trimesh would skip) and with texture coordinates on the vertices (Blender's s, t:
    dropped), the same."""
    vertex = ([("float", "x"), ("float", "y"), ("float", "z")], [(float(k), float(k * k % 7), 0.5 * k) for k in range(16)])
    faces = [((0, 1, 2, 3),), ((4, 5, 6),), ((7, 8, 9, 10, 11),), ((12, 13, 14, 15),)]
    for counts in ("uchar uchar", "uchar int"):
        face = ([f"list {counts} vertex_indices"], faces)
        expected = trimesh_load(ply_bytes("ascii", vertex, face), "ply")
        got = readers.read(ply_bytes("binary_little_endian", vertex, face), "ply")
        np.testing.assert_array_equal(got.faces, expected.faces)
        np.testing.assert_array_equal(got.vertices, expected.vertices)
    uv = ([*vertex[0], ("float", "s"), ("float", "t")], [(*v, 0.25, 0.75) for v in vertex[1]])
    data = ply_bytes("binary_big_endian", uv, ([f"list uchar int vertex_indices"], faces))
    data = data.replace(b"end_header\n", b"element edge 1\nproperty int vertex1\nproperty int vertex2\nend_header\n")
    got = readers.read(data + np.array([0, 1], ">i4").tobytes(), "ply")
    np.testing.assert_array_equal(got.faces, expected.faces)
    np.testing.assert_array_equal(got.vertices, expected.vertices)


@pytest.mark.parametrize("data", [
    ply_bytes("ascii", ([("float", "x"), ("float", "y"), ("float", "z"), ("float", "u"), ("float", "v")],
                        [(*p, 0.5, 0.5) for p in SQUARE]),
              (["list uchar int vertex_indices"], [((0, 1, 2),)])),  # texture coordinates
    ply_bytes("ascii", ([("float", "x"), ("float", "y"), ("float", "z")], SQUARE),
              (["list uchar int vertex_indices"], [((0, 1, 9),)])),  # an index out of range
    ply_bytes("ascii", ([("float", "x"), ("float", "y"), ("float", "z")], SQUARE), (["list uchar int vertex_indices"], [])),
    b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nelement edge 1\nend_header\n1\n1\n",
])
def test_ply_refused(data):
    with pytest.raises(Unsupported):
        readers.read(data, "ply")


# --------------------------------------------------------------------------- OBJ
def test_obj_exported(mesh):
    check_same(exported(mesh, "obj"), "obj")
    check_same(exported(mesh, "obj", include_normals=True), "obj")
    textured = mesh.copy()
    uv = np.random.default_rng(3).uniform(size=(len(mesh.vertices), 2))
    textured.visual = trimesh.visual.TextureVisuals(uv=uv)
    data = exported(textured, "obj", include_texture=True, write_texture=False)
    check_same(data.replace(b"usemtl material_0\n", b"").replace(b"mtllib material.mtl\n", b""), "obj")


OBJ_HEAD = "v 0 0 0\nv 1 0 0.25\nv 1 1 0.5\nv 0 1 0.125\nv 2 0.5 0.1\nv 2 1.5 0.3\nv 3 1 0\nv 9 9 9\n"
OBJ_UV = "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvt 0.5 0.5\n"
OBJ_NORMALS = "vn 0 0 1\nvn 0 1 0\nvn 1 0 0\n"
OBJ_VARIANTS = {
    "triangles": OBJ_HEAD + "f 1 2 3\nf 1 3 4\nf 2 5 3\n",
    "quads": OBJ_HEAD + "f 1 2 3 4\nf 2 5 6 3\n",
    "mixed_polygons": OBJ_HEAD + "f 1 2 3 4\nf 2 5 3\nf 5 7 6 3 2\nf 1 2 3\n",
    "negative": OBJ_HEAD + "f -8 -7 -6\nf -8 -6 -5\nf 2 -4 3\n",
    "comments_groups_blank_crlf": ("# a comment\r\nmtllib none.mtl\r\no body\r\n\r\n" + OBJ_HEAD.replace("\n", "\r\n")
                                   + "g part\r\ns 1\r\n# faces\r\nf 1 2 3\r\n\r\nf 1 3 4\r\ns off\r\nf 2 5 3\r\n"),
    "continuation": OBJ_HEAD + "f 1 2 \\\n3\nf 1 3 4\n",
    "w_coordinate": OBJ_HEAD.replace("\n", " 1.0\n") + "f 1 2 3\nf 1 3 4\n",
    "vertex_colors": OBJ_HEAD.replace("\n", " 0.5 0.25 1\n") + "f 1 2 3\nf 1 3 4\n",
    "v_vt": OBJ_HEAD + OBJ_UV + "f 1/1 2/2 3/3\nf 1/1 3/3 4/4\nf 2/5 5/2 3/3\n",
    "v_vn": OBJ_HEAD + OBJ_NORMALS + "f 1//1 2//1 3//2\nf 1//1 3//2 4//3\nf 2//3 5//3 3//3\n",
    "v_vt_vn": OBJ_HEAD + OBJ_UV + OBJ_NORMALS + "f 1/1/1 2/2/1 3/3/2\nf 1/1/1 3/3/2 4/4/3\nf 2/5/3 5/2/3 3/3/1\n",
    "v_vt_vn_quads": OBJ_HEAD + OBJ_UV + OBJ_NORMALS + "f 1/1/1 2/2/1 3/3/2 4/4/3\nf 2/5/3 5/2/3 6/3/1 3/1/1\n",
    "v_vt_mixed": OBJ_HEAD + OBJ_UV + "f 1/1 2/2 3/3 4/4\nf 2/5 5/2 3/3\nf 5/1 7/2 6/3 3/4 2/5\n",
    "v_vt_negative": OBJ_HEAD + OBJ_UV + "f -8/-5 -7/-4 -6/-3\nf 1/1 3/3 4/4\n",
    "v_vn_without_normals": OBJ_HEAD + "f 1//1 2//1 3//1\n",
    "v_vt_without_uv": OBJ_HEAD + "f 1/1 2/1 3/1\n",
    "unreferenced_first": "v 5 5 5\n" + OBJ_HEAD + "f 2 3 4\n",
}


@pytest.mark.parametrize("name", sorted(OBJ_VARIANTS))
def test_obj_by_hand(name):
    check_same(OBJ_VARIANTS[name], "obj")


@pytest.mark.parametrize("name", ["triangles", "negative", "v_vt_vn", "mixed_polygons"])
def test_obj_tabs_are_white_space(name):
    """Values (and keywords) separated by tabs: the mesh of the same file with spaces (trimesh,
    which the reader copied, knows 'v ' and 'f ' only: 'v\\t' lines were dropped, every later
    vertex one number off)."""
    spaces = OBJ_VARIANTS[name]
    tabs = spaces.replace(" ", "\t")
    got, expected = readers.read(tabs.encode(), "obj"), check_same(spaces, "obj")
    np.testing.assert_array_equal(got.vertices, expected.vertices)
    np.testing.assert_array_equal(got.faces, expected.faces)
    mixed = spaces.replace("v 1 0", "v\t1 0", 1)
    np.testing.assert_array_equal(readers.read(mixed.encode(), "obj").vertices, expected.vertices)


@pytest.mark.parametrize("name", ["triangles", "v_vt_vn", "mixed_polygons"])
def test_obj_comments_that_end_a_data_line_are_cut(name):
    """'v 1 0 0 # a', 'f 1 2 3 # tri': the mesh of the file without them (the reader, as trimesh's
    loader it copied, read the comment as values: Unsupported, then trimesh's 'could not be read to
    its end due to unmatched data')."""
    plain = OBJ_VARIANTS[name]
    commented = "\n".join(line + (" # c" if line[:1] in "vf" else "") for line in plain.split("\n"))
    got, expected = readers.read(commented.encode(), "obj"), check_same(plain, "obj")
    np.testing.assert_array_equal(got.vertices, expected.vertices)
    np.testing.assert_array_equal(got.faces, expected.faces)


@pytest.mark.parametrize("name", ["triangles", "v_vt_vn", "mixed_polygons"])
def test_obj_lines_that_start_with_white_space_are_read(name):
    """'  v 1 0 0', '\tf 1 2 3': the mesh of the file without the indent (the reader, as trimesh's
    loader it copied, knew a line by its first characters: an indented vertex was dropped, every
    later face one vertex off, and a file of indented faces read as a point cloud); a line continued
    by a backslash keeps its leading space (there it separates values)."""
    plain = OBJ_VARIANTS[name]
    expected = check_same(plain, "obj")
    for indent in ("  ", "\t", " \t"):
        indented = "\n".join(indent + line if line else line for line in plain.split("\n"))
        got = readers.read(indented.encode(), "obj")
        np.testing.assert_array_equal(got.vertices, expected.vertices)
        np.testing.assert_array_equal(got.faces, expected.faces)
    if "f 1 2 3" in plain:  # (a backslash at a line's end continues it: its next line's indent separates)
        continued = plain.replace("f 1 2 3", "f 1 2\\\n  3", 1)
        np.testing.assert_array_equal(readers.read(continued.encode(), "obj").faces, expected.faces)


@pytest.mark.parametrize("text", [
    OBJ_HEAD + "usemtl a\nf 1 2 3\nusemtl b\nf 1 3 4\n",   # materials split the mesh
    OBJ_HEAD + "f 1 2 3\nf 1/1 3/1 4/1\n",                 # several kinds of references
    OBJ_HEAD,                                              # a point cloud
])  # (a face of 2 corners, which trimesh drops: an error, tests/test_input_boundary.py; a vertex that
#     is not there: an error, test_broken_references_are_errors)
def test_obj_refused(text):
    with pytest.raises(Unsupported):
        readers.read(text.encode(), "obj")


# --------------------------------------------------------------------------- STL
@pytest.mark.parametrize("file_type", ["stl", "stl_ascii"])
def test_stl_exported(mesh, file_type):
    got = check_same(exported(mesh, file_type), "stl")
    assert len(got.vertices) == 3 * len(mesh.faces)  # duplicates are kept, as trimesh keeps them


def test_stl_ascii_by_hand():
    text = ("solid Part 1\r\n  facet normal 0 0 1\r\n    outer loop\r\n      vertex 0 0 0\r\n      vertex 1 0 0\r\n"
            "      vertex 1 1 0\r\n    endloop\r\n  endfacet\r\n  facet normal 0 0 1\r\n    outer loop\r\n"
            "      vertex 0 0 0\r\n      vertex 1 1 0\r\n      vertex 0 1 1.5e-1\r\n    endloop\r\n  endfacet\r\n"
            "endsolid Part 1\r\n")
    check_same(text, "stl")


def test_stl_refused():
    two = "solid a\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 1 1 0\nendloop\nendfacet\nendsolid a\n"
    with pytest.raises(Unsupported):
        readers.read((two + two.replace(" a", " b")).encode(), "stl")
    with pytest.raises(Unsupported):
        readers.read(b"\0" * 84, "stl")  # binary, no triangles


@pytest.mark.parametrize("file_type, data", [
    ("obj", "v 0 0 0\nv 1 0 0\nv 0 \u0663 0\nv 0 0 1\nf 1 2 3\nf 1 3 4\n"),  # an Arabic-Indic 3
    ("obj", "v 0 0 0\nv 1\u00a00 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 3 4\n"),  # a no-break space
    ("obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 3\u00a04\n"),  # one among the faces
    ("ply", PLY_TET_TEXT.replace("1 0 0\n", "1\x1f0 0\n")),                     # a unit separator
    ("ply", PLY_TET_TEXT.replace("3 0 1 2\n", "3 0 1 \uff12\n")),                 # a full-width 2
    ("stl", "solid a\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 1 \u0661 0\n"
            "endloop\nendfacet\nendsolid a\n"),
    ("stl", "solid a\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1\u20280 0\nvertex 1 1 0\n"
            "endloop\nendfacet\nendsolid a\n"),
])
def test_numbers_that_trimesh_does_not_read_are_refused(file_type, data):
    """trimesh reads OBJ, PLY and ASCII STL numbers with numpy.fromstring (ASCII digits and white
    space) and refuses other digits and Unicode spaces, which float and str.split read: the readers
    read such a file (found by fuzzing); they refuse it now."""
    data = data.encode()
    with pytest.raises(ValueError):
        trimesh_load(data, file_type)
    with pytest.raises(Unsupported):
        readers.read(data, file_type)


def test_registry():
    assert set(readers.READERS) == {"off", "ply", "obj", "stl"}
    with pytest.raises(Unsupported):
        readers.read(b"glTF", "glb")


# --------------------------------------------------------------------------- the dev data
def dev_meshes():
    """The first mesh of each dev dataset (faust-dev, kids-dev/kid_0001, tosca-dev/dog). The classes
    of one dataset are stored alike (kid_0001 and kid_0002: the same PLY header, 59,727 vertices and
    119,344 faces; dog and horse: the same header, units and exporter): a second class of a dataset
    takes the same reader paths in every format."""
    if not SHARED.is_dir():
        return []
    found = []
    for dataset in sorted(SHARED.glob("*/")):
        folders = [dataset] + sorted(dataset.glob("*/"))
        found += [next(iter(sorted(d.glob("*.ply")))) for d in folders if any(d.glob("*.ply"))][:1]
    return found


@pytest.mark.shared
@pytest.mark.skipif(not SHARED.is_dir(), reason="needs ../shared/data")
@pytest.mark.parametrize("path", dev_meshes(), ids=lambda p: f"{p.parent.name}/{p.name}")
def test_dev_data_in_every_format(path):
    """One mesh of each dev dataset, written by trimesh's exporters in every format, read alike."""
    mesh = trimesh.load(path, process=False)
    check_same(path.read_bytes(), "ply")
    for file_type, kwargs in [("off", {}), ("obj", {}), ("stl", {}), ("stl_ascii", {}),
                              ("ply", {"encoding": "ascii"}), ("ply", {"encoding": "binary"})]:
        check_same(exported(mesh, file_type, **kwargs), file_type.split("_")[0])


# --------------------------------------------------------------------------- the library's loading path
def without_fast_readers(monkeypatch):
    def refuse(data, file_type):
        raise Unsupported("disabled")

    monkeypatch.setattr(readers, "read", refuse)


LIBRARY_FILES = {
    "off": lambda m: exported(m, "off"),
    "ply": lambda m: exported(m, "ply"),
    "ply_ascii_colors": lambda m: exported(colored(m), "ply", encoding="ascii"),
    "obj": lambda m: exported(m, "obj", include_normals=True),
    "obj_uv": lambda m: OBJ_VARIANTS["v_vt_vn"].encode(),
    "obj_quads": lambda m: OBJ_VARIANTS["quads"].encode(),
    "stl": lambda m: exported(m, "stl"),
    "stl_ascii": lambda m: exported(m, "stl_ascii"),
    "ply_normals_extras": lambda m: ply_bytes("binary_little_endian", extra_vertex(),
                                              (["list uchar int vertex_indices"], [((0, 1, 2, 3),), ((1, 4, 2),)])[:1] +
                                              ([((0, 1, 2),), ((1, 4, 2),), ((0, 2, 3),)],)),
}


def colored(m):
    out = m.copy()
    out.visual.vertex_colors = np.random.default_rng(4).integers(0, 255, (len(m.vertices), 4))
    return out


@pytest.mark.parametrize("name", sorted(LIBRARY_FILES))
def test_library_load_is_unchanged(tmp_path, monkeypatch, mesh, name):
    """jaxpose.mesh.load through the fast readers equals load through trimesh alone: the merged
    mesh, its colors and UV, and the bytes of its normalized copy in every output format."""
    from jaxpose import mesh as jmesh

    path = tmp_path / f"input.{name.split('_')[0]}"
    path.write_bytes(LIBRARY_FILES[name](mesh))
    fast = jmesh.load(path)
    with monkeypatch.context() as patch:
        without_fast_readers(patch)
        slow = jmesh.load(path)
    assert type(fast) is type(slow)
    assert {k: v for k, v in fast.metadata.items() if not k.startswith("_")} == \
        {k: v for k, v in slow.metadata.items() if not k.startswith("_")}
    np.testing.assert_array_equal(fast.vertices, slow.vertices)
    np.testing.assert_array_equal(fast.faces, slow.faces)
    assert fast.visual.kind == slow.visual.kind
    if slow.visual.kind == "texture":
        np.testing.assert_array_equal(fast.visual.uv, slow.visual.uv)
    elif slow.visual.kind is not None:
        np.testing.assert_array_equal(fast.visual.vertex_colors, slow.visual.vertex_colors)
        np.testing.assert_array_equal(fast.visual.face_colors, slow.visual.face_colors)
    np.testing.assert_array_equal(fast.vertex_normals, slow.vertex_normals)
    np.testing.assert_array_equal(fast.face_normals, slow.face_normals)
    if name.startswith("stl"):
        assert len(fast.vertices) < 3 * len(fast.faces)  # the corners were merged
    method = "surface_centroid"  # defined on the open sheets too (the robust default refuses them)
    pose_fast, pose_slow = jmesh.normalize_mesh(fast, method=method)[1], jmesh.normalize_mesh(slow, method=method)[1]
    np.testing.assert_array_equal(np.asarray(pose_fast.center), np.asarray(pose_slow.center))
    np.testing.assert_array_equal(np.asarray(pose_fast.scale), np.asarray(pose_slow.scale))
    for file_type in jmesh.MESH_FORMATS:
        a = jmesh.encode(jmesh._transformed(fast, pose_fast), file_type)
        b = jmesh.encode(jmesh._transformed(slow, pose_slow), file_type)
        assert a == b, file_type


@pytest.mark.parametrize("shift", [0.0, 0.5])
def test_library_merge_ignores_the_files_normals_at_the_origin(tmp_path, shift):
    """A file read by trimesh (materials) whose vertices, split by their normals, hold one position
    twice: merged into one vertex per position, also where the anchor vertex is the origin (moving
    the vertices by it kept trimesh's cached normals, and they kept the vertices apart; found by
    fuzzing)."""
    from jaxpose import mesh as jmesh

    positions = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, -1, 0]]) + shift
    triangles = np.array([[0, 1, 2], [0, 2, 3], [0, 3, 4], [0, 4, 1]])
    normal = [1, 1, 2, 2]  # the first two faces' normal is 1, the others' 2: vertices 0, 1 and 3 split
    text = "".join(f"v {x} {y} {z}\n" for x, y, z in positions) + "vn 0 0 1\nvn 0 0 -1\nusemtl a\n"
    text += "".join("f " + " ".join(f"{i + 1}//{n}" for i in t) + "\n" for t, n in zip(triangles, normal))
    path = tmp_path / "split.obj"
    path.write_text(text)
    loaded = jmesh.load(path)
    assert len(loaded.vertices) == len(positions)
    np.testing.assert_array_equal(np.asarray(loaded.vertices)[loaded.faces], positions[triangles])


def test_library_merge_hashes_mirrored_vertices_apart():
    """Vertices mirrored through the anchor, (a, b, c) and (-a, -b, c), as a symmetric shape has:
    distinct hashes, so the array merge decides (no fall back to trimesh)."""
    from jaxpose.io import mesh as jmesh

    rng = np.random.default_rng(3)
    half = rng.integers(-10**9, 10**9, size=(5000, 3))
    keys = np.concatenate([half, half * [-1, -1, 1], half * [1, -1, -1], half * [-1, 1, -1], [[0, 0, 0]]])
    keys = np.unique(keys, axis=0)
    assert len(np.unique(jmesh._hash_keys(keys))) == len(keys)
    shape = trimesh.creation.icosphere(subdivisions=3)
    assert jmesh._merged(shape.vertices, shape.faces) is not None


def test_library_merge_hash_collision_falls_back(monkeypatch):
    """Two different keys with one hash: the array merge says it cannot tell (trimesh merges)."""
    from jaxpose.io import mesh as jmesh

    vertices = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 1, 0]])
    faces = np.array([[0, 1, 2], [0, 1, 3]])
    keep, inverse = jmesh._merged(vertices, faces)
    np.testing.assert_array_equal(keep, [0, 1, 2])
    np.testing.assert_array_equal(inverse[faces], [[0, 1, 2], [0, 1, 2]])
    monkeypatch.setattr(jmesh, "_hash_keys", lambda keys: np.zeros(len(keys), np.uint64))  # every key: 0
    assert jmesh._merged(vertices, faces) is None
    assert jmesh._merged(vertices[:3], faces[:1]) is None


@pytest.mark.parametrize("name", ["off", "ply", "ply_ascii_colors", "obj", "obj_uv", "stl", "stl_ascii"])
def test_dataset_folders_load_as_trimesh_does(tmp_path, monkeypatch, mesh, name):
    """datasets.load_folder through the fast readers: trimesh.load(path, force="mesh",
    process=False)'s mesh (vertices as stored, none merged) and names."""
    from jaxpose.datasets import folder

    path = tmp_path / "class" / f"input.{name.split('_')[0]}"
    path.parent.mkdir()
    path.write_bytes(LIBRARY_FILES[name](mesh))
    fast = folder.load_folder(tmp_path)["class"][0]
    with monkeypatch.context() as patch:
        without_fast_readers(patch)
        slow = folder.load_folder(tmp_path)["class"][0]
    np.testing.assert_array_equal(fast.vertices, slow.vertices)
    np.testing.assert_array_equal(fast.faces, slow.faces)
    assert {k: v for k, v in fast.metadata.items() if not k.startswith("_")} == \
        {k: v for k, v in slow.metadata.items() if not k.startswith("_")}
    assert fast.visual.kind == slow.visual.kind


def test_readers_refuse_what_is_not_bytes_at_their_boundary():
    """The readers take a file's bytes; a str (a path, or the text) was an AttributeError ('str' object
    has no attribute 'decode') or TypeError from deep inside, and read() turned it into Unsupported
    (trimesh's turn). A TypeError at the boundary, naming the fix; bytearray and memoryview read as bytes."""
    off = b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"
    cases = {"read_off": off, "read_obj": b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
             "read_ply": trimesh.creation.box().export(file_type="ply"),
             "read_stl": trimesh.creation.box().export(file_type="stl")}
    for name, data in cases.items():
        reader = getattr(readers, name)
        for wrong, hint in ((data.decode("latin-1"), "got str: pass the file's bytes"), (None, "got NoneType"), (3, "got int")):
            with pytest.raises(TypeError, match=f"^{name} reads a file's bytes .*{hint}"):
                reader(wrong)
        for alike in (bytearray(data), memoryview(data)):
            np.testing.assert_array_equal(reader(alike).faces, reader(data).faces)
    with pytest.raises(TypeError, match="^read reads a file's bytes .*got str: pass the file's bytes, Path"):
        readers.read(off.decode(), "off")
    with pytest.raises(TypeError, match="^check_vertex_references reads a file's bytes .*got str"):
        readers.obj.check_vertex_references("f 1 2 3\n")


# --------------------------------------------------------------------------- broken files, at the boundary
TRIMESH_WORDS = ("unexpected length", "invalid literal", "C int", "C long", "inhomogeneous", "list index",
                 "unpack", "float16q'", "sequence")


def _broken_files():
    """{name: (bytes, what the message says)}: real files of a tiny mesh, cut at several byte offsets
    or with a header that claims absurd or malformed counts."""
    m = trimesh.creation.icosphere(subdivisions=0)  # 12 vertices, 20 faces
    ply = m.export(file_type="ply")
    ascii_ply = trimesh.exchange.ply.export_ply(m, encoding="ascii")
    off = m.export(file_type="off").encode()
    stl_text = trimesh.exchange.stl.export_stl_ascii(m).encode()
    header_end = ply.index(b"end_header\n") + len(b"end_header\n")
    body = off.split(b"\n", 2)[2]  # OFF without its first two lines
    files = {}
    # a binary PLY cut past its minimum length (every list empty), or one byte long (trimesh: "PLY is unexpected length!")
    for cut in (header_end + 300, len(ply) - 7, len(ply) - 1):
        files[f"cut{cut}.ply"] = (ply[:cut], "truncated or malformed")
    files["longer.ply"] = (ply + b"\0", "truncated or malformed")
    files["texture_cut.ply"] = (ply.replace(b"end_header", b"comment TextureFile a.png\nend_header")[:-5],
                                "truncated or malformed")
    # cut right after "end_header", before its line end (trimesh: "PLY is unexpected length!")
    files["no_body.ply"] = (ply[:header_end - 1], "truncated, 0 bytes after the header, fewer than the 164")
    # an OBJ cut within its last vertex's number (trimesh: NumPy's "could not be read to its end due to unmatched data")
    obj = m.export(file_type="obj").encode()
    line = next(line for line in obj.split(b"\n") if line.startswith(b"v ") and line.split()[3].startswith(b"-"))
    files["cut_number.obj"] = (obj[:obj.index(line) + line.rindex(b"-") + 1],  # "v 0.0 -0.52573111 -"
                               "ends in '-', which is not a number: a truncated or malformed file")
    # ... within a normal's or a texture coordinate's last number (the same NumPy words; review)
    files["cut_normal.obj"] = (b"v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 -", "'vn 0 0 -' ends in '-', which is not a number")
    files["cut_uv.obj"] = (b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nvt 1 -", "'vt 1 -' ends in '-', which is not a number")
    # classic Mac OS line ends (the same NumPy words; before the review's fix, the whole file quoted as its last line)
    files["lone_cr.obj"] = (b"v 0 0 0\rv 1 0 0\rv 0 1 0\rvt 0 0\rvt 1 0\rvt 0 1\rf 1/1 2/2 3/3\r",
                            "its lines end in a lone carriage return")
    # a header cut before its end_header ("list index out of range", "not enough values to unpack")
    for cut in (40, header_end - 20):
        files[f"head{cut}.ply"] = (ply[:cut], "truncated inside its header")
        files[f"head{cut}_ascii.ply"] = (ascii_ply[:cut], "truncated inside its header")
    # absurd counts (a C int overflow, gigabytes): told without allocating them
    for count in (b"4000000000", b"99999999999999999999"):
        for tag, data in (("bin", ply), ("ascii", ascii_ply)):
            files[f"faces{count.decode()}_{tag}.ply"] = (data.replace(b"element face 20", b"element face " + count),
                                                         "truncated")
        files[f"faces{count.decode()}.off"] = (b"OFF\n12 " + count + b" 0\n" + body, "truncated|beyond any file")
    files["edges_beyond_int64.off"] = (b"OFF\n12 20 99999999999999999999\n" + body, "beyond any file")
    # the first face's list claims 4e9 indices (a uint count)
    huge_list = bytearray(ply.replace(b"list uchar int", b"list uint int"))
    at = huge_list.index(b"end_header\n") + len(b"end_header\n") + 12 * 12
    huge_list[at:at + 1] = np.uint32(4_000_000_000).tobytes()  # the count, 4 bytes now
    files["huge_list.ply"] = (bytes(huge_list), "truncated or malformed")
    # malformed counts ("invalid literal for int()")
    files["counts_x.off"] = (b"OFF\n3 x 0\n" + body, "is not 'vertices faces \\[edges\\]' as whole numbers")
    files["counts_float.off"] = (b"OFF\n12.0 20 0\n" + body, "is not 'vertices faces")
    files["counts_one.off"] = (b"OFF\n12\n" + body, "is not 'vertices faces")
    files["counts_negative.off"] = (b"OFF\n-3 1 0\n" + body, "negative count")
    files["count_4e9.ply"] = (ply.replace(b"element face 20", b"element face 4e9"), "whole number count")
    # a vertex line cut short ("setting an array element with a sequence")
    cut = off.index(b"\n", off.index(b"\n", off.index(b"\n") + 1) + 1) + 6  # inside the second vertex line (line 4)
    files["vertex_cut.off"] = (off[:cut] + b"\n" + body[body.index(b"\n") + 1:], r"vertex 2 \(line 4 of the file\) holds 1 value, fewer than its 3 coordinates")
    # an ASCII STL cut before its endsolid ("empty geometry ... not STL")
    for cut in (len(stl_text) // 3, len(stl_text) - 20):
        files[f"cut{cut}_ascii.stl"] = (stl_text[:cut], "without the 'endsolid' line")
    return files


BROKEN = _broken_files()


@pytest.mark.parametrize("name", sorted(BROKEN))
def test_broken_files_are_named_in_jaxposes_words(tmp_path, name):
    """A truncated file, or one whose header claims an absurd or malformed count: jaxpose.mesh.load
    names the file, says it is truncated or malformed and what was expected, in jaxpose's words
    (trimesh's own were "PLY is unexpected length!", "invalid literal for int()", a NumPy "C int"
    overflow, ...), without allocating what the header claims."""
    import tracemalloc

    from jaxpose import mesh as jmesh
    from jaxpose.errors import InvalidInputError

    data, fragment = BROKEN[name]
    path = tmp_path / name
    path.write_bytes(data)
    tracemalloc.start()
    try:
        with pytest.raises(InvalidInputError) as info:
            jmesh.load(path)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    message = str(info.value)
    assert message.startswith(f"{path}: cannot read {path.suffix[1:].upper()} file: "), message
    assert re.search(fragment, message), message
    assert not any(words in message for words in TRIMESH_WORDS), message
    assert peak < 64 * 2**20, peak  # the file's size, not the header's claim


def test_broken_files_that_trimesh_refuses_too():
    """The oracle that the files above are broken: trimesh's loader fails on each, but those it
    reads a part of without a word (an ASCII PLY or an OFF file shorter than its counts say; an
    ASCII STL without endsolid, read as no vertices)."""
    silent = [name for name in BROKEN if name.endswith(("_ascii.ply", "_ascii.stl")) or name == "faces4000000000.off"]
    for name, (data, _) in BROKEN.items():
        if name not in silent:
            with pytest.raises(Exception):
                trimesh.load(io.BytesIO(data), file_type=name.rsplit(".", 1)[1], process=False)
