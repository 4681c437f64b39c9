"""Fast readers for OFF, PLY, OBJ and STL: what trimesh's loaders give, parsed with NumPy.

Each reader takes a file's bytes and returns :class:`Loaded`: the vertices and faces that
``trimesh.load(file, process=False)`` gives for it (equal arrays: the same values, order and
triangulation), and the other arguments trimesh's loader hands to ``trimesh.Trimesh`` (vertex
normals and colors, face colors, an STL's face normals and attributes, an OBJ's UV coordinates), so
that ``trimesh.Trimesh(**loaded.kwargs(), process=False)`` is the mesh trimesh would have made.

What they read (anything else raises :class:`Unsupported`, and the caller reads the file with
trimesh: never a silently different mesh):

* OFF (text): ``OFF`` / ``COFF`` headers, ``#`` comments, blank lines, any line endings, extra
  values on a line (colors), triangles, quads and polygons.
* PLY: ``ascii``, ``binary_little_endian`` and ``binary_big_endian``; a ``vertex`` element with
  ``x``, ``y``, ``z`` and any other scalar properties (``nx ny nz`` become vertex normals,
  ``red green blue [alpha]`` colors, as trimesh does); a ``face`` element with a
  ``vertex_indices`` (or ``vertex_index``) list of any count and index types and any other scalar
  properties. Binary lists all of the length of the first (trimesh's own rule).
* OBJ: ``v`` (3, 4 or 6 values: ``x y z [w]`` or ``x y z r g b``), ``vt``, ``vn``, faces of
  ``v``, ``v/vt``, ``v//vn`` and ``v/vt/vn`` references (negative ones count from the end of the
  file's vertices, as in trimesh), triangles, quads and polygons, ``o`` / ``g`` / ``s`` lines,
  comments, ``\\`` line continuations. No ``usemtl`` (materials split the mesh).
* STL: binary, and ASCII with one solid.

Polygons are split into triangles as trimesh splits them: where every face has the same number
of corners, the first triangle of each face, then the second ...; where counts are mixed,
triangles first, then quads (as before), then the fans of larger polygons (``[0, i, i + 1]``);
OBJ's mixed faces in file order (quads ``[0, 1, 2], [2, 3, 0]``).

Example::

    loaded = read(Path("body.off").read_bytes(), "off")
    loaded.vertices.shape, loaded.faces.shape     # (n, 3) float64, (m, 3) int64
"""
from __future__ import annotations

import re
from typing import NamedTuple

import numpy as np

from ..errors import InvalidInputError

__all__ = ["Loaded", "Unsupported", "READERS", "read", "read_off", "read_ply", "read_obj", "read_stl"]


class Unsupported(Exception):
    """This reader cannot reproduce trimesh's result for the file exactly: read it with trimesh."""


class Loaded(NamedTuple):
    """A mesh as trimesh's loader makes it.

    Attributes:
      vertices: (n, 3) float64.
      faces: (m, 3) int64, triangles, every index in [0, n).
      extras: the other ``trimesh.Trimesh`` arguments trimesh's loader gives (``vertex_normals``,
        ``vertex_colors``, ``face_colors``, ``face_normals``, ``face_attributes``, ``visual``,
        ``metadata``: an STL's header or solid name); empty for most files.
    """

    vertices: np.ndarray
    faces: np.ndarray
    extras: dict

    def kwargs(self) -> dict:
        """The arguments of ``trimesh.Trimesh`` (add ``process=False``)."""
        return {"vertices": self.vertices, "faces": self.faces, **self.extras}


# --------------------------------------------------------------------------- numbers
_SEPARATOR = ";"  # never part of a number: marks line ends among the tokens
_SIGNED = re.compile(rb"-?[0-9]+(?: -?[0-9]+)*")


def _text(data: bytes) -> str:
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        raise Unsupported("not UTF-8 text") from None


def _tokens(lines):
    """Tokens of lines: (flat list of str, per-line counts (n,) int64)."""
    joined = f" {_SEPARATOR} ".join(lines)
    if lines and joined.count(_SEPARATOR) == len(lines) - 1:
        tokens = joined.split()
        first = len(lines[0].split()) if lines else 0
        n = len(lines)
        if len(tokens) == (first + 1) * n - 1 and tokens[first::first + 1].count(_SEPARATOR) == n - 1:
            del tokens[first::first + 1]  # every line has `first` tokens
            return tokens, np.full(n, first, np.int64)
    counts = np.fromiter(map(len, map(str.split, lines)), np.int64, len(lines))
    return " ".join(lines).split(), counts


def _floats(tokens) -> np.ndarray:
    """float64 of number tokens, as Python's ``float`` (and C's strtod, which agree on these)."""
    if not tokens:
        return np.zeros(0, np.float64)
    text = " ".join(tokens)
    if "_" in text or "x" in text or "X" in text:  # float() and strtod disagree on "1_0", "0x1p3"
        raise Unsupported("unusual number")
    try:
        return np.array(tokens, dtype=np.float64)
    except ValueError:
        raise Unsupported("a value that is not a number") from None


def _ints(tokens, negative=False) -> np.ndarray:
    """int64 of decimal integer tokens (``-`` allowed with `negative`)."""
    if not tokens:
        return np.zeros(0, np.int64)
    text = " ".join(tokens)
    raw = text.encode("ascii", "replace")
    if raw.translate(None, b"0123456789 ") and not (negative and _SIGNED.fullmatch(raw)):
        raise Unsupported("an index that is not an integer")
    return _in_range(np.fromstring(text, dtype=np.int64, sep=" "))


def _in_range(values):
    """Integers trimesh's float parsing keeps exactly (fromstring saturates past int64)."""
    if len(values) and (values.max() >= 10**15 or values.min() <= -(10**15)):
        raise Unsupported("an index too large")
    return values


def _line_tokens(block: bytes, lines: int) -> np.ndarray:
    """Tokens per line of `lines` lines joined by newlines, split at spaces, tabs and newlines."""
    chars = np.frombuffer(block, np.uint8)
    space = (chars == 32) | (chars == 9) | (chars == 10)
    start = ~space
    start[1:] &= space[:-1]
    return np.bincount(np.searchsorted(np.flatnonzero(chars == 10), np.flatnonzero(start)), minlength=lines)


def _triangle_lines(lines):
    """Faces (m, 3) of OFF lines that are all ``3 a b c`` with decimal digits only, read as one
    block; None for anything else."""
    block = "\n".join(lines).encode("utf-8")
    if block.translate(None, b"0123456789 \t\n"):
        return None
    counts = _line_tokens(block, len(lines))
    if not np.all(counts == 4):
        return None
    values = _in_range(np.fromstring(block, dtype=np.int64, sep=" ")).reshape(-1, 4)  # digits only: one per token
    if not np.all(values[:, 0] == 3):
        return None
    return values[:, 1:]


def _take(tokens, index) -> list:
    """tokens[index] for an int array (a list)."""
    if len(index) == 0:
        return []
    if len(index) == 1:
        return [tokens[int(index[0])]]
    from operator import itemgetter

    return list(itemgetter(*index.tolist())(tokens))


# --------------------------------------------------------------------------- triangles
def _starts(counts):
    """Where each of consecutive runs of `counts` items starts. (n,) int64."""
    starts = np.zeros(len(counts), np.int64)
    np.cumsum(counts[:-1], out=starts[1:])
    return starts


def _runs(starts, sizes):
    """Indices starts[i] + 0 .. sizes[i] - 1, run after run. (sum(sizes),) int64."""
    return np.repeat(starts, sizes) + np.arange(int(sizes.sum())) - np.repeat(np.cumsum(sizes) - sizes, sizes)


def _fans(flat, starts, counts):
    """Fan triangles [p0, p_j, p_j+1] of polygons, polygon by polygon, in order. (t, 3)."""
    per = counts - 2
    first = np.repeat(starts, per)
    step = np.arange(int(per.sum())) - np.repeat(np.cumsum(per) - per, per) + 1
    return np.column_stack((flat[first], flat[first + step], flat[first + step + 1]))


def _triangulate(flat, counts):
    """trimesh.geometry.triangulate_quads of polygons given as corners `flat` (all polygons in
    order) and their `counts` (each >= 3): all-triangle input as it is; else triangles, then quads
    split as [0, 1, 2] (all) then [2, 3, 0] (all), then fans of the larger polygons."""
    flat = np.asarray(flat, np.int64)
    if np.all(counts == 3):
        return flat.reshape(-1, 3)
    starts = _starts(counts)
    parts = []
    tri = starts[counts == 3]
    if len(tri):
        parts.append(flat[tri[:, None] + np.arange(3)])
    quad = starts[counts == 4]
    if len(quad):
        corners = flat[quad[:, None] + np.arange(4)]
        parts += [corners[:, [0, 1, 2]], corners[:, [2, 3, 0]]]
    big = counts > 4
    if np.any(big):
        parts.append(_fans(flat, starts[big], counts[big]))
    return np.concatenate(parts).astype(np.int64)


def _triangulate_inline(flat, counts):
    """OBJ's mixed faces as trimesh's loop splits them, face by face in file order: triangles as
    they are, quads [0, 1, 2], [2, 3, 0], larger polygons as fans."""
    flat = np.asarray(flat, np.int64)
    starts = _starts(counts)
    triangles = _fans(flat, starts, counts)
    quads = np.nonzero(counts == 4)[0]
    if len(quads):
        second = (np.cumsum(counts - 2) - 1)[quads]  # row of each quad's second triangle
        triangles[second] = flat[starts[quads][:, None] + np.array([2, 3, 0])]
    return triangles


def _checked(vertices, faces, extras=None) -> Loaded:
    vertices = np.ascontiguousarray(vertices, dtype=np.float64)
    faces = np.ascontiguousarray(faces, dtype=np.int64)
    if vertices.ndim != 2 or vertices.shape[1] != 3 or len(vertices) == 0:
        raise Unsupported("no vertices")
    if faces.ndim != 2 or faces.shape[1] != 3 or len(faces) == 0:
        raise Unsupported("no faces (a point cloud)")
    if faces.min() < 0 or faces.max() >= len(vertices):
        raise Unsupported("a face index out of range")
    return Loaded(vertices, faces, {k: v for k, v in (extras or {}).items() if v is not None})


# --------------------------------------------------------------------------- OFF
_OFF = re.compile("(COFF|OFF)")


def _comment_strip(text):
    """trimesh.util.comment_strip (``#`` to the end of its line, the newline included)."""
    split = (text + "\n").split("#")
    lead = "" if text.startswith("#") else split[0]
    removed = [i.split("\n", 1) for i in split]
    return (lead + "\n" + "\n".join(i[1] for i in removed if len(i) > 1 and len(i[1]) > 0)).strip()


def read_off(data: bytes) -> Loaded:
    """An OFF file's mesh, as ``trimesh.load(..., file_type="off", process=False)``.

    The common layout (:func:`_off_plain`: no comments, one space between values, triangles) is
    parsed on the bytes in a few C-level passes; anything else line by line.

    Raises:
      Unsupported: anything this reader does not reproduce exactly (read it with trimesh).
      InvalidInputError: fewer vertex or face lines than the counts line says, or a face line
        with fewer indices than its count (trimesh drops or shortens those without a word).
    """
    plain = _off_plain(data)
    if plain is not None:
        return plain
    text = _text(data)
    if "#" in text:
        text = _comment_strip(text)
    text = text.strip()
    found = _OFF.search(text)
    if found is None:
        raise Unsupported("no OFF header")
    raw = text[found.end():]
    lines = list(filter(None, map(str.strip, raw.splitlines())))
    if not lines:
        raise Unsupported("no counts")
    header = lines[0].split()
    if len(header) < 2 or not all(t.isascii() and t.isdigit() for t in header[:2]):
        raise Unsupported("a malformed count line")
    nv, nf = int(header[0]), int(header[1])
    block = lines[1:nv + 1]
    if nv == 0:
        raise Unsupported("no vertices")
    if len(block) < nv:
        raise InvalidInputError(f"cannot read OFF file: truncated, {len(block)} vertex lines of the {nv} its "
                                f"counts line says")
    tokens, counts = _tokens(block)
    if np.any(counts < 3):
        raise Unsupported("a vertex line with fewer than 3 values")
    starts = _starts(counts)
    vertices = _floats(_take(tokens, (starts[:, None] + np.arange(3)).ravel())) if np.any(counts != 3) \
        else _floats(tokens)
    block = lines[nv + 1:nv + nf + 1]
    if nf == 0:
        raise Unsupported("no faces")
    if len(block) < nf:
        raise InvalidInputError(f"cannot read OFF file: truncated, {len(block)} face lines of the {nf} its "
                                f"counts line says")
    triangles = _triangle_lines(block)
    if triangles is not None:
        return _checked(vertices.reshape(-1, 3), triangles)
    tokens, counts = _tokens(block)
    starts = _starts(counts)
    sizes = _ints(_take(tokens, starts))
    if np.any(sizes + 1 > counts):
        line = int(np.argmax(sizes + 1 > counts))
        raise InvalidInputError(f"cannot read OFF file: face line {line + 1} holds fewer indices than its count "
                                f"({block[line]!r}): a truncated or malformed file")
    if np.any(sizes < 3):
        raise Unsupported("a face with fewer than 3 corners")
    if np.all(counts == counts[0]) and np.all(sizes + 1 == counts):  # "3 a b c" lines, nothing more
        del tokens[::int(counts[0])]
        flat = _ints(tokens)
    else:
        flat = _ints(_take(tokens, _runs(starts + 1, sizes)))
    return _checked(vertices.reshape(-1, 3), _triangulate(flat, sizes))


_OFF_HEAD = re.compile(rb"[ \t\n]*C?OFF[ \t]*\n[ \t]*([0-9]+)[ \t]+([0-9]+)(?:[ \t]+[0-9]+)?[ \t]*\n")
_FLOAT_CHARS = b"0123456789+-.eE \n"
_INT_CHARS = b"0123456789 \n"


def _off_plain(data: bytes):
    """:func:`read_off` of a file in the layout most writers produce, or None for any other file.

    The layout: ASCII, no ``#``, ``\\n`` or ``\\r\\n`` line ends, an ``OFF`` / ``COFF`` line, a
    counts line ``nv nf [ne]``, then nv vertex lines and nf face lines of k values each (the same k
    on every vertex line, and on every face line), one space between values and none around them,
    every face ``3 a b c ...``; whatever follows the faces is ignored, as trimesh ignores it.
    Numbers go through one ``numpy.fromstring`` per block (Python's own correctly rounded string
    to double conversion, as ``float``): each value character is one of ``0-9+-.eE`` and the blocks'
    space positions prove each line has k non-empty values, so a count of k values per line
    means every value was one number (``fromstring`` raises on anything else).
    """
    if not data.isascii() or b"#" in data:
        return None
    if b"\r" in data:
        data = data.replace(b"\r\n", b"\n")
        if b"\r" in data:
            return None
    head = _OFF_HEAD.match(data)
    if head is None:
        return None
    nv, nf = int(head.group(1)), int(head.group(2))
    if nv == 0 or nf == 0:
        return None
    body = data[head.end():]
    if not body.endswith(b"\n"):
        body += b"\n"
    chars = np.frombuffer(body, np.uint8)
    newlines = np.flatnonzero(chars == 10)
    if len(newlines) < nv + nf:
        return None
    split = int(newlines[nv - 1]) + 1
    vertex_block, face_block = body[:split], body[split:int(newlines[nv + nf - 1]) + 1]
    if vertex_block.translate(None, _FLOAT_CHARS) or face_block.translate(None, _INT_CHARS):
        return None
    vertex_values = _plain_values(vertex_block, newlines[:nv], np.float64)
    face_values = _plain_values(face_block, newlines[nv:nv + nf] - split, np.int64)
    if vertex_values is None or face_values is None or vertex_values.shape[1] < 3 or face_values.shape[1] < 4 \
            or np.any(face_values[:, 0] != 3):
        return None
    return _checked(vertex_values[:, :3], _in_range(face_values[:, 1:4]))


def _plain_values(block: bytes, newlines, dtype):
    """The values of a block of lines that each hold k non-empty values split by single spaces, as
    an (lines, k) array of `dtype`; None where the lines differ in k, hold an empty value (two
    spaces, a space at a line's start or end, a blank line) or a value that is not one number.
    newlines: each line's ``\\n`` position in `block`."""
    chars = np.frombuffer(block, np.uint8)
    spaces = np.flatnonzero(chars == 32)
    lines = len(newlines)
    if len(spaces) % lines:
        return None
    per = len(spaces) // lines  # spaces per line, if each line holds its share
    starts = np.empty(lines, np.int64)
    starts[0], starts[1:] = 0, newlines[:-1] + 1
    at = spaces.reshape(lines, per)  # sorted: row i is line i's spaces exactly when these hold
    if per:
        if np.any(at[:, 0] <= starts) or np.any(at[:, -1] >= newlines - 1) or (per > 1 and np.any(np.diff(at, axis=1) < 2)):
            return None
    elif np.any(newlines <= starts):
        return None
    if dtype == np.float64:
        values = _decimals(chars, np.column_stack((starts, at + 1)).ravel(), np.column_stack((at, newlines)).ravel())
        if values is not None:
            return values.reshape(lines, per + 1)
    try:
        values = np.fromstring(block, dtype=dtype, sep=" ")
    except ValueError:  # a value that is not one number
        return None
    if len(values) != lines * (per + 1):
        return None
    return values.reshape(lines, per + 1)


def _decimals(chars, starts, ends):
    """float64 of the tokens chars[starts[i]:ends[i]] when every one is ``[-]digits.digits`` with the
    same number F <= 22 of decimals and at most 15 digits in all (``printf("%.6f")`` and the like);
    None for any other tokens. Each value is the integer M of its digits (below 2^53, so exact in a
    double) divided by 10^F (exact too): one correctly rounded division, hence the double nearest
    the decimal, which is what ``float`` and strtod give. (T,) int64 positions -> (T,) float64."""
    first = chars[starts[0]:ends[0]].tobytes()
    decimals = len(first) - first.rfind(b".") - 1
    if b"." not in first or decimals > 22:
        return None
    lengths = ends - starts
    negative = chars[starts] == 45  # "-"
    digits = lengths - 1 - negative
    width = int(lengths.max())
    if np.any(digits < 1) or np.any(digits > 15) or width > 17:
        return None
    padded = np.concatenate((np.full(width, 48, np.uint8), chars))
    table = np.lib.stride_tricks.sliding_window_view(padded, width)[ends]  # token i right-aligned in row i
    dot = width - decimals - 1
    if dot < 0:
        return None
    table[np.arange(width) < (width - digits - 1)[:, None]] = 48  # what precedes a token's digits: "0"
    if np.any(table[:, dot] != 46):  # "."
        return None
    table[:, dot] = 48
    table -= 48
    if np.any(table > 9):  # a character that is not a digit (below "0" it wrapped around)
        return None
    powers = np.zeros(width)
    powers[dot + 1:] = 10.0 ** np.arange(decimals - 1, -1, -1)
    powers[:dot] = 10.0 ** np.arange(dot + decimals - 1, decimals - 1, -1)
    whole = np.einsum("ij,j->i", table, powers)  # exact: sums of integers below 10^15 < 2^53
    values = whole / 10.0**decimals
    return np.negative(values, out=values, where=negative)


# --------------------------------------------------------------------------- PLY
_PLY_TYPES = {
    "char": "i1", "uchar": "u1", "short": "i2", "ushort": "u2", "int": "i4", "int8": "i1", "int16": "i2",
    "int32": "i4", "int64": "i8", "uint": "u4", "uint8": "u1", "uint16": "u2", "uint32": "u4", "uint64": "u8",
    "float": "f4", "float16": "f2", "float32": "f4", "float64": "f8", "double": "f8",
}
_PLY_INDEX = ("vertex_index", "vertex_indices")
_PLY_TEXTURE = {"texture_u", "texture_v", "u", "v", "s", "t"}
_PLY_COLORS = ("red", "green", "blue", "alpha")


def _ply_header(data):
    """(elements {name: (count, [(property, type, count type or None)])}, ascii, endian, data start)."""
    lines, position = [], 0
    while True:
        end = data.find(b"\n", position)
        if end < 0 or len(lines) > 10000:
            raise Unsupported("no end of the header")
        lines.append(data[position:end])
        position = end + 1
        if b"end_header" in lines[-1].split():
            break
    if b"ply" not in lines[0].lower() or len(lines) < 3:
        raise Unsupported("not a PLY file")
    try:
        words = [line.decode("utf-8").split() for line in lines[1:]]
    except UnicodeDecodeError:
        raise Unsupported("a header that is not UTF-8") from None
    fmt = words[0]
    if len(fmt) != 3 or fmt[0] != "format" or fmt[1] not in ("ascii", "binary_little_endian", "binary_big_endian"):
        raise Unsupported("an unknown format line")
    elements, current = {}, None
    for word in words[1:-1]:
        if not word or "texturefile" in " ".join(word).lower():
            raise Unsupported("an empty header line or a texture file")
        if word[0] == "element" and len(word) == 3 and word[2].isascii() and word[2].isdigit():
            if word[1] in elements:
                raise Unsupported("an element declared twice")
            current = elements[word[1]] = (int(word[2]), [])
        elif word[0] == "property" and current is not None and len(word) == 3 and word[1] in _PLY_TYPES:
            current[1].append((word[2], _PLY_TYPES[word[1]], None))
        elif (word[0] == "property" and current is not None and len(word) == 5 and word[1] == "list"
              and word[2] in _PLY_TYPES and word[3] in _PLY_TYPES and word[2][0] in "ui"):
            current[1].append((word[4], _PLY_TYPES[word[3]], _PLY_TYPES[word[2]]))
        elif word[0] in ("comment", "obj_info") or (word[0] == "end_header" and len(word) == 1):
            continue
        else:
            raise Unsupported(f"a header line this reader does not know: {' '.join(word)}")
        names = [p[0] for p in current[1]]
        if len(set(names)) != len(names):
            raise Unsupported("a property declared twice")
    if words[-1] != ["end_header"]:
        raise Unsupported("an unusual end_header line")
    return elements, fmt[1] == "ascii", ">" if "big" in fmt[1] else "<", position


def _ply_check(elements):
    if set(elements) != {"vertex", "face"} or list(elements)[0] != "vertex":
        raise Unsupported("elements other than vertex then face")
    vertex, face = elements["vertex"][1], elements["face"][1]
    names = {p[0] for p in vertex}
    if not {"x", "y", "z"} <= names or names & _PLY_TEXTURE or any(p[2] for p in vertex):
        raise Unsupported("vertices without x, y, z, or with texture coordinates or lists")
    lists = [p for p in face if p[2]]
    if len(lists) != 1 or lists[0][0] not in _PLY_INDEX or lists[0][1][0] not in "ui":
        raise Unsupported("faces without one vertex_indices list, or with other lists")
    if elements["vertex"][0] == 0 or elements["face"][0] == 0:
        raise Unsupported("no vertices or no faces")


def _ply_extras(vertex, face):
    """trimesh's vertex normals and colors of the columns {name: (n,) array}."""
    extras = {}
    if all(k in vertex for k in ("nx", "ny", "nz")):
        extras["vertex_normals"] = np.column_stack([vertex[k] for k in ("nx", "ny", "nz")])
    for name, columns in (("face_colors", face), ("vertex_colors", vertex)):
        found = [columns[k] for k in _PLY_COLORS if k in columns]
        if len(found) >= 3:
            extras[name] = np.column_stack(found)
    return extras


def read_ply(data: bytes) -> Loaded:
    """A PLY file's mesh, as ``trimesh.load(..., file_type="ply", process=False)``.

    Raises:
      Unsupported: anything this reader does not reproduce exactly (read it with trimesh).
    """
    elements, ascii, endian, start = _ply_header(data)
    _ply_check(elements)
    if ascii:
        vertex, face, flat, counts = _ply_ascii(data[start:], elements, endian)
    else:
        vertex, face, flat, counts = _ply_binary(data, start, elements, endian)
    vertices = np.column_stack([vertex[k] for k in "xyz"])
    faces = _triangulate(flat, counts)
    return _checked(vertices, faces, _ply_extras(vertex, face))


def _ply_binary(data, start, elements, endian):
    (nv, vprops), (nf, fprops) = elements["vertex"], elements["face"]
    vtype = np.dtype([(name, endian + kind) for name, kind, _ in vprops])
    face_start = start + nv * vtype.itemsize
    # trimesh's rule: every list as long as the face element's first one
    before = np.dtype([(name, endian + kind) for name, kind, _ in fprops[:[p[2] is not None for p in fprops].index(True)]])
    name, kind, count_kind = next(p for p in fprops if p[2])
    at = face_start + before.itemsize
    size = np.frombuffer(data[at:at + np.dtype(count_kind).itemsize], endian + count_kind)
    if len(size) != 1 or not 3 <= int(size[0]) <= 1000:
        raise Unsupported("a face list of fewer than 3 corners")
    size = int(size[0])
    ftype = np.dtype([(p[0], endian + p[1]) if p[2] is None else
                      (p[0], [("f0", endian + p[2]), ("f1", endian + p[1], (size,))]) for p in fprops])
    if len(data) - start != nv * vtype.itemsize + nf * ftype.itemsize:
        raise Unsupported("a file length that does not match its header (or lists of several lengths)")
    vertex = np.frombuffer(data, vtype, nv, start)
    face = np.frombuffer(data, ftype, nf, face_start)
    if np.any(face[name]["f0"] != size):
        raise Unsupported("face lists of several lengths")
    columns = {p[0]: face[p[0]] for p in fprops if p[2] is None}
    return ({k: vertex[k] for k in vertex.dtype.names}, columns, face[name]["f1"].reshape(-1),
            np.full(nf, size, np.int64))


def _ply_ascii(data, elements, endian):
    lines = _text(data).splitlines()
    (nv, vprops), (nf, fprops) = elements["vertex"], elements["face"]
    if len(lines) < nv + nf:
        raise Unsupported("fewer lines than the header's counts")
    block = lines[:nv]
    tokens, counts = _tokens(block)
    if np.any(counts != len(vprops)):
        raise Unsupported("a vertex line with more or fewer values than properties")
    values = _floats(tokens).reshape(nv, len(vprops))
    vertex = {name: values[:, i].astype(endian + kind) for i, (name, kind, _) in enumerate(vprops)}
    block = lines[nv:nv + nf]
    tokens, counts = _tokens(block)
    position = [p[2] is not None for p in fprops].index(True)
    scalars = len(fprops) - 1
    if np.any(counts < scalars + 1):
        raise Unsupported("a face line with fewer values than properties")
    starts = _starts(counts)
    values = _floats(_take(tokens, starts + position))
    sizes = values.astype(endian + fprops[position][2]).astype(np.int64)
    if np.any(values != sizes) or np.any(sizes < 3) or np.any(counts != scalars + 1 + sizes):
        raise Unsupported("a face list whose count is not its length")
    face = {}
    for i, (name, kind, _) in enumerate(fprops):  # the scalars before and after the list
        if i != position:
            at = starts + i + (0 if i < position else sizes)
            face[name] = _floats(_take(tokens, at)).astype(endian + kind)
    flat = _floats(_take(tokens, _runs(starts + position + 1, sizes))).astype(endian + fprops[position][1])
    return vertex, face, flat, sizes


# --------------------------------------------------------------------------- OBJ
_INDEX = r"-?[0-9]+"
_OBJ_FORMS = {form: re.compile(rf"{ref}(?: {ref})*") for form, ref in (
    ((0, False), _INDEX), ((1, False), f"{_INDEX}/{_INDEX}"), ((2, True), f"{_INDEX}//{_INDEX}"),
    ((2, False), f"{_INDEX}/{_INDEX}/{_INDEX}"))}

def read_obj(data: bytes) -> Loaded:
    """An OBJ file's mesh, as ``trimesh.load(..., file_type="obj", process=False)``.

    Raises:
      Unsupported: anything this reader does not reproduce exactly (read it with trimesh).
    """
    text = _text(data)
    text = "\n{}\n".format(text.strip().replace("\r\n", "\n")).replace("\\\n", "")
    if "usemtl" in text or "+e" in text or "-e" in text or "\r" in text:
        raise Unsupported("materials, or text trimesh's OBJ loader rewrites")
    lines = text.split("\n")
    keyed = {}
    for key in ("v", "vt", "vn", "f"):
        prefix = key + " "
        keyed[key] = [line[len(prefix):] for line in lines if line.startswith(prefix)]
    if sum(1 for line in lines if line[:1] == "f") != len(keyed["f"]):
        raise Unsupported("a line starting with f that is not a face")
    if not keyed["v"] or not keyed["f"]:
        raise Unsupported("no vertices or no faces")
    arrays = {}
    for key in ("v", "vt", "vn"):
        if keyed[key]:
            tokens, counts = _tokens(keyed[key])
            if np.any(counts != counts[0]) or counts[0] == 0:
                raise Unsupported(f"{key} lines of several lengths")
            arrays[key] = _floats(tokens).reshape(len(counts), int(counts[0]))
    v = arrays["v"]
    if v.shape[1] < 3:
        raise Unsupported("vertices with fewer than 3 values")
    colors = v[:, 3:6] if v.shape[1] >= 6 else None
    v = v[:, :3]
    vt = arrays["vt"][:, :2] if "vt" in arrays else None
    vn = arrays.get("vn")

    faces_lines = [line.strip() for line in keyed["f"]]
    references, refs = _tokens(faces_lines)  # refs: corners per face
    if np.any(refs < 3):
        raise Unsupported("a face with fewer than 3 corners")
    form = references[0].count("/"), "//" in references[0]  # v, v/vt, v//vn, v/vt/vn
    joined = " ".join(references)
    if form not in _OBJ_FORMS or not _OBJ_FORMS[form].fullmatch(joined):
        raise Unsupported("faces with several kinds of references")
    per = form[0] + 1 - form[1]  # values per corner
    flat = _ints(joined.replace("/", " ").split(), negative=True).reshape(-1, per)
    flat[flat > 0] -= 1  # 1-based; negative ones stay (trimesh: from the end of all vertices)
    tex = flat[:, 1] if per in (2, 3) and not form[1] else None
    norm = flat[:, per - 1] if (per == 2 and form[1]) or per == 3 else None
    if np.all(refs == refs[0]):  # trimesh's vectorized path: (n, k), triangulated by Trimesh later
        shape = (-1, int(refs[0]))
        faces, tex, norm = (None if a is None else a.reshape(shape) for a in (flat[:, 0], tex, norm))
    else:  # trimesh's loop: every face split in file order
        faces, tex, norm = (None if a is None else _triangulate_inline(a, refs) for a in (flat[:, 0], tex, norm))
    if np.any(faces < -len(v)) or np.any(faces >= len(v)):
        raise Unsupported("a face referencing a vertex that is not there")
    return _obj_mesh(v, vt, vn, colors, faces, tex, norm)


def _obj_mesh(v, vt, vn, colors, faces, tex, norm):
    """trimesh's OBJ loader from the parsed arrays: unmerge by UV / normal indices, keep referenced
    vertices, triangulate what is still polygons."""
    extras = {}
    if tex is not None or (vn is not None and norm is not None):
        from trimesh.visual.texture import unmerge_faces

        if tex is not None and norm is not None:
            faces, mask_v, mask_vt, mask_vn = unmerge_faces(faces, tex, norm, maintain_faces=False)
        elif tex is not None:
            (faces, mask_v, mask_vt), mask_vn = unmerge_faces(faces, tex, maintain_faces=False), None
        else:
            (faces, mask_v, mask_vn), mask_vt = unmerge_faces(faces, norm, maintain_faces=False), None
        if mask_vt is not None and vt is not None:  # (trimesh: no UV where there are none)
            if np.any(mask_vt >= len(vt)) or np.any(mask_vt < -len(vt)):
                raise Unsupported("faces referencing UV coordinates that are not there")
            uv = vt[mask_vt]
            if len(uv) == len(mask_v):
                from trimesh.visual.texture import TextureVisuals

                extras["visual"] = TextureVisuals(uv=uv)
    else:
        mask = np.zeros(len(v), bool)
        mask[faces] = True
        inverse = np.zeros(len(v), np.int64)
        inverse[mask] = np.arange(int(mask.sum()))
        faces, mask_v, mask_vn = inverse[faces], mask, None
    vertices = v[mask_v]
    if colors is not None:
        extras["vertex_colors"] = colors[mask_v]
    if mask_vn is not None and vn is not None:
        if np.any(mask_vn >= len(vn)) or np.any(mask_vn < -len(vn)) or vn.shape[1] != 3:
            raise Unsupported("faces referencing normals that are not there")
        extras["vertex_normals"] = vn[mask_vn]
    faces = np.asarray(faces, np.int64)
    if faces.shape[1] != 3:  # the Trimesh constructor's triangulate_quads
        faces = _triangulate(faces.reshape(-1), np.full(len(faces), faces.shape[1], np.int64))
    return _checked(vertices, faces, extras)


# --------------------------------------------------------------------------- STL
_STL_FACET = np.dtype([("normals", "<f4", (3,)), ("vertices", "<f4", (3, 3)), ("attributes", "<u2")])


def read_stl(data: bytes) -> Loaded:
    """An STL file's mesh (binary, or ASCII with one solid), as ``trimesh.load(..., file_type="stl",
    process=False)``: three vertices per triangle, in order (duplicates are not merged here).

    Raises:
      Unsupported: anything this reader does not reproduce exactly (read it with trimesh).
    """
    if len(data) >= 84 and 84 + 50 * int.from_bytes(data[80:84], "little") == len(data):
        facets = np.frombuffer(data, _STL_FACET, offset=84)
        vertices = facets["vertices"].reshape(-1, 3)
        faces = np.arange(len(vertices), dtype=np.int64).reshape(-1, 3)
        try:
            header = data[:80].decode("utf-8").strip()
        except UnicodeDecodeError:
            raise Unsupported("a header that is not UTF-8") from None
        return _checked(vertices, faces, {"face_normals": facets["normals"].reshape(-1, 3),
                                          "face_attributes": {"stl": facets["attributes"]},
                                          "metadata": {"header": header}})
    raw = _text(data).strip()
    text = raw.lower()
    if len(text) != len(raw):
        raise Unsupported("text whose lower case changes its length")
    if text.count("endsolid") != 1 or text.count("solid") != 2 or not text.startswith("solid") \
            or text.find("solid", text.find("endsolid") + 8) >= 0:
        raise Unsupported("not one ASCII solid")
    solid = text[:text.find("endsolid")]
    values = {}
    for key in ("vertex", "normal"):
        pieces = solid.split(key)[1:]
        lines = [piece[:piece.find("\n")] for piece in pieces]
        tokens, counts = _tokens(lines) if lines else ([], np.zeros(0, np.int64))
        if np.any(counts != 3):
            raise Unsupported(f"{key} lines without 3 values")
        values[key] = _floats(tokens).reshape(-1, 3)
    vertices = values["vertex"]
    if len(vertices) == 0 or len(vertices) % 3:
        raise Unsupported("no triangles")
    normals = values["normal"] if len(values["normal"]) * 3 == len(vertices) else None
    faces = np.arange(len(vertices), dtype=np.int64).reshape(-1, 3)
    from trimesh.util import unique_name  # the solid's name, as trimesh's loader names it

    name = unique_name(raw[:solid.find("\n")][6:].strip(), {})
    return _checked(vertices, faces, {"face_normals": normals, "metadata": {"name": name}})


# --------------------------------------------------------------------------- registry
READERS = {"off": read_off, "ply": read_ply, "obj": read_obj, "stl": read_stl}


def read(data: bytes, file_type: str) -> Loaded:
    """The mesh of a file's bytes in `file_type` (a key of :data:`READERS`).

    Raises:
      Unsupported: no fast reader for the format, or one that cannot reproduce trimesh exactly.
      InvalidInputError: a file that is certainly broken, where trimesh would read part of it
        without a word: an OFF file with fewer vertex or face lines than its counts line says, or
        a face line with fewer indices than its count (the message names no file: the caller's
        does).
    """
    reader = READERS.get(file_type)
    if reader is None:
        raise Unsupported(f"no fast reader for {file_type!r}")
    try:
        return reader(bytes(data))
    except InvalidInputError:
        raise
    except (ValueError, IndexError, TypeError, OverflowError, MemoryError) as exc:  # a file none of the checks foresaw
        raise Unsupported(f"{type(exc).__name__}: {exc}") from None
