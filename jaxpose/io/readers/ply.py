"""PLY: ``ascii``, ``binary_little_endian`` and ``binary_big_endian``, as trimesh reads them."""
from __future__ import annotations

import re

import numpy as np

from ...errors import InvalidInputError
from .base import (Loaded, Unsupported, file_bytes, _checked, _floats, _runs, _starts, _take, _text, _tokens,
                   _triangulate)

__all__ = ["read_ply", "check_vertex_lines"]


_PLY_TYPES = {
    "char": "i1", "uchar": "u1", "short": "i2", "ushort": "u2", "int": "i4", "int8": "i1", "int16": "i2",
    "int32": "i4", "int64": "i8", "uint": "u4", "uint8": "u1", "uint16": "u2", "uint32": "u4", "uint64": "u8",
    "float": "f4", "float16": "f2", "float32": "f4", "float64": "f8", "double": "f8",
}
_PLY_INDEX = ("vertex_index", "vertex_indices")
_PLY_TEXTURE = {"texture_u", "texture_v", "u", "v", "s", "t"}
_PLY_COLORS = ("red", "green", "blue", "alpha")


def _ply_header(data):
    """(elements {name: (count, [(property, type, count type or None)])}, ascii, endian, data start,
    texture: whether a comment names a texture file).

    Raises InvalidInputError for a header that trimesh's reader fails on too, in its own words: one
    that ends before its ``end_header`` line (a truncated file), a blank line, an ``element`` line
    that is not ``element <name> <count>`` with a whole number count (``element face 4e9``), a
    property of a type PLY does not have; Unsupported for the others this reader does not read."""
    lines, position = [], 0
    while True:
        end = data.find(b"\n", position)
        if end < 0 and b"end_header" in data[position:].split():  # the file ends with it: trimesh's last readline
            end = len(data)
        if end < 0 and b"ply" in data.split(b"\n", 1)[0].lower():
            raise InvalidInputError(f"cannot read PLY file: truncated inside its header, {len(data)} bytes without "
                                    "the 'end_header' line that ends a PLY header")
        if end < 0 or len(lines) > 10000:
            raise Unsupported("no end of the header")
        lines.append(data[position:end])
        position = min(end + 1, len(data))
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
    elements, current, texture = {}, None, False
    for number, word in enumerate(words[1:-1], start=3):
        if word[:1] == ["element"] and len(word) == 3 and word[2].startswith("-") and word[2][1:].isdigit():
            raise InvalidInputError(f"cannot read PLY file: element {word[1]} has a negative count ({word[2]})")
        if not word:
            raise InvalidInputError(f"cannot read PLY file: line {number} of its header is blank (a PLY header "
                                    "holds none): a malformed file")
        if word[0] == "element" and (len(word) != 3 or not _is_int(word[2])):
            raise InvalidInputError(f"cannot read PLY file: header line {number} {' '.join(word)!r} is not "
                                    "'element <name> <count>' with a whole number count: a malformed file")
        if word[0] == "property" and current is not None and (
                (len(word) == 3 and word[1] not in _PLY_TYPES) or (len(word) == 5 and word[1] == "list" and (
                unknown := [t for t in word[2:4] if t not in _PLY_TYPES]))):
            kind = word[1] if len(word) == 3 else unknown[0]
            raise InvalidInputError(f"cannot read PLY file: header line {number} {' '.join(word)!r} has the type "
                                    f"{kind!r}, which is no PLY type (char, uchar, short, ushort, int, uint, float, double, "
                                    "or int8 ... float64): a malformed file")
        if word[0] in ("comment", "obj_info") and "texturefile" in " ".join(word).lower():
            texture = True  # (refused after the length check: a short file is told as such)
            continue
        if "texturefile" in " ".join(word).lower():
            raise Unsupported("a texture file")
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
    return elements, fmt[1] == "ascii", ">" if "big" in fmt[1] else "<", position, texture


def _is_int(text):
    """Whether trimesh's ``int(count)`` reads `text`."""
    try:
        int(text)
    except ValueError:
        return False
    return True


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


def _ply_length(data, start, elements, ascii, endian="<"):
    """Refuse a file that cannot hold what its header declares (any elements: checked before the
    elements this reader reads, as trimesh reads a short file's first part, a point cloud's or a
    mesh's vertices without their faces, without a word). Returns an ASCII file's lines; for a
    binary one, :func:`_binary_length`'s walk of lists of several lengths, or None."""
    counts = {name: count for name, (count, _) in elements.items()}
    declared = ", ".join(f"{count} {name}" for name, count in counts.items())
    if ascii:  # trimesh reads one element per line
        lines = _text(data[start:]).splitlines()
        _refuse_blank_line(data, start, lines, elements)
        if len(lines) < sum(counts.values()):
            raise InvalidInputError(f"cannot read PLY file: truncated, {len(lines)} lines of the "
                                    f"{sum(counts.values())} ({declared}) its header says")
        return lines
    # each element at least its scalars and its lists' counts (a list may be empty)
    least = sum(count * sum(np.dtype(kind if size is None else size).itemsize for _, kind, size in props)
                for count, props in elements.values())
    if len(data) - start < least:
        raise InvalidInputError(f"cannot read PLY file: truncated, {len(data) - start} bytes after the header, fewer "
                                f"than the {least} its {declared} elements need at the least")
    return _binary_length(data, start, elements, endian, declared)


def _binary_length(data, start, elements, endian, declared):
    """Refuse a binary file whose length after the header is not what its elements take. Where
    every list of an element is as long as its first item's (trimesh's rule), the length is
    computed from the header and the first lists; otherwise the lists are walked one by one
    (:func:`_walk`): a file that ends inside an element, or holds bytes after its last one, is
    refused, naming where; a file whose lists have several lengths and whose length is exactly what
    they take is valid (Blender's and MeshLab's binary PLY of triangles and quads): returns the
    walk, {name: (starts, lengths) or None}, which :func:`read_ply` reads. Returns None for a file
    of the first rule. Counts are Python integers: a header that claims billions of elements
    allocates nothing."""
    have, position, lengths = len(data) - start, start, []
    for name, (count, props) in elements.items():
        if count <= 0:
            continue
        size = 0
        for prop, kind, count_kind in props:
            if count_kind is None:
                size += np.dtype(kind).itemsize
                continue
            width = np.dtype(count_kind).itemsize
            if position + size + width > len(data):
                raise InvalidInputError(f"cannot read PLY file: truncated, {have} bytes after the header end before "
                                        f"its first {name}'s {prop} list (its {declared} elements)")
            length = int(np.frombuffer(data, endian + count_kind, 1, position + size)[0])
            lengths.append(f"{name} {prop} of {length}")
            size += width + max(length, 0) * np.dtype(kind).itemsize
        position += count * size
    if have == position - start:
        return None
    walked = _walk(data, start, elements, endian) if lengths else None
    if isinstance(walked, dict):
        return walked
    if walked is not None:  # (name, index, end): the walk's verdict
        name, index, end = walked
        if end > len(data):
            raise InvalidInputError(f"cannot read PLY file: truncated, {have} bytes after the header end inside its "
                                    f"{name} {index + 1} of {elements[name][0]} (its {declared} elements, every list "
                                    "as long as its count): a truncated or malformed file")
        raise InvalidInputError(f"cannot read PLY file: {len(data) - end} bytes after its last element (its {declared} "
                                f"elements take {end - start}, every list as long as its count): a truncated or malformed file")
    lists = f" (every list as long as its element's first: {', '.join(lengths)})" if lengths else ""
    raise InvalidInputError(f"cannot read PLY file: {have} bytes after the header, where its {declared} elements "
                            f"take {position - start}{lists}: a truncated or malformed file")


_STRUCT = {"i1": "b", "u1": "B", "i2": "h", "u2": "H", "i4": "i", "u4": "I", "i8": "q", "u8": "Q"}


def _walk(data, start, elements, endian):
    """Walk a binary file's elements item by item, each list as long as its own count: {name:
    (starts (count,) int64 of each item's first byte, lengths (count, lists) int64) or None for an
    element without lists} where the elements end exactly at the file's end; else (name, index,
    end): the element and item where the walk ran past the end (end > len(data)), or the end of the
    last element where bytes are left after it. Runs over the items in Python: the elements' counts
    are bounded by the file's bytes (:func:`_ply_length` checked each item's least size first)."""
    import struct

    out, position, size = {}, start, len(data)
    for name, (count, props) in elements.items():
        if count <= 0:
            out[name] = None
            continue
        if all(p[2] is None for p in props):
            out[name] = None
            item = sum(np.dtype(kind).itemsize for _, kind, _ in props)
            if position + count * item > size:
                index = (size - position) // item if item else 0
                return name, index, position + (index + 1) * item
            position += count * item
            continue
        segments, fixed = [], 0
        for _, kind, count_kind in props:
            if count_kind is None:
                fixed += np.dtype(kind).itemsize
            else:
                segments.append((fixed, struct.Struct(endian + _STRUCT[count_kind]), np.dtype(kind).itemsize))
                fixed = 0
        starts, lengths = [], []
        for index in range(count):
            starts.append(position)
            for skip, unpack, item in segments:
                position += skip
                if position + unpack.size > size:
                    return name, index, position + unpack.size
                length = unpack.unpack_from(data, position)[0]
                lengths.append(length)
                position += unpack.size + max(length, 0) * item
            position += fixed
            if position > size:
                return name, index, position
        out[name] = (np.asarray(starts, np.int64), np.asarray(lengths, np.int64).reshape(count, len(segments)))
    return out if position == size else (name, count - 1, position)


_BLANK_LINE = re.compile(rb"\n[ \t\r\f\v]*\n")


def _refuse_blank_line(data, start, lines, elements):
    """Refuse an ASCII file whose first blank line lies among its elements' lines: one element a
    line, every later line would be read as the element before it (trimesh failed: "setting an
    array element with a sequence.", "index 0 is out of bounds"). Blank lines after them (nothing
    reads them), or among an element's of no properties, pass."""
    found = _BLANK_LINE.search(data, start - 1)
    if found is None:
        return
    at = data.count(b"\n", start, found.start() + 1)  # the blank line's index among `lines`
    end = 0
    for name, (count, properties) in elements.items():
        end += max(count, 0)
        if at < end:
            if properties and at < len(lines) and not lines[at].strip():
                number = data.count(b"\n", 0, start) + at + 1
                raise InvalidInputError(f"cannot read PLY file: line {number} is blank, inside its {name} data "
                                        "(ASCII PLY holds one element a line: every later line would be read as "
                                        "the element before it); remove the line")
            return


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


@file_bytes
def read_ply(data: bytes) -> Loaded:
    """A PLY file's mesh, as ``trimesh.load(..., file_type="ply", process=False)``; a binary file of
    vertices and faces whose face lists have several lengths (triangles and quads: Blender and
    MeshLab write such files; trimesh refuses them, "PLY is unexpected length!") as trimesh reads
    the same faces written as ASCII PLY (polygons triangulated, face colors kept).

    Raises:
      Unsupported: anything this reader does not reproduce exactly (read it with trimesh).
      InvalidInputError: a file shorter than its header's counts (an ASCII file with fewer lines,
        a binary one with fewer bytes than its elements need at the least; whatever its elements:
        a point cloud's too), a blank line among an ASCII file's element lines, an ASCII vertex line without all of its x, y, z (fewer values than its
        properties up to them: trimesh's "setting an array element with a sequence."; a line that
        lacks only a later column, a color, is read by trimesh), or a face line with fewer values
        than its count, or a negative element count (trimesh reads part of such a file without a
        word), or an ASCII face index that is not an integer of its type (``4294967296`` or
        ``1e300`` for a ``uint``, ``-1`` for a ``uchar``, ``nan``, ``1.5``: trimesh casts it to some
        index without a word); a binary file whose length is not what its elements take, every list
        as long as its count (one that ends inside an element, or holds bytes after its last: named;
        trimesh's words were "PLY is unexpected length!", or a NumPy "C int" error for a list count
        of billions), a binary file of lists of several lengths beside elements other than vertex
        and face (which trimesh refuses too), a header cut before its
        ``end_header``, a blank header line, an element count that is not a whole number
        (``4e9``), a property type PLY does not have (trimesh's own words were "list index out of
        range", "invalid literal for int()", the type name). Header counts are never allocated.
    """
    elements, ascii, endian, start, texture = _ply_header(data)
    lines = _ply_length(data, start, elements, ascii, endian)
    walked = None if ascii else lines  # (binary lists of several lengths: trimesh refuses the file)
    try:
        if texture:
            raise Unsupported("a texture file")
        _ply_check(elements)
    except Unsupported as exc:
        if walked is None:
            raise
        several = sorted({n for w in walked.values() if w is not None for n in np.unique(w[1]).tolist()})
        raise InvalidInputError(f"cannot read PLY file: a binary PLY whose lists have several lengths "
                                f"({', '.join(map(str, several))}) and {exc}: jaxpose reads such lists in a file of "
                                "vertices and faces alone; save it as ASCII PLY") from None
    if ascii:
        vertex, face, flat, counts = _ply_ascii(lines, elements, endian, data[:start].count(b"\n") + 1)
    elif walked is not None:
        vertex, face, flat, counts = _ply_walked(data, start, elements, endian, walked["face"])
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


def _ply_walked(data, start, elements, endian, walked):
    """:func:`_ply_binary`'s columns of a file whose face lists have several lengths (`walked`:
    :func:`_walk`'s starts and lengths of the face element)."""
    (nv, vprops), (nf, fprops) = elements["vertex"], elements["face"]
    vertex = np.frombuffer(data, np.dtype([(name, endian + kind) for name, kind, _ in vprops]), nv, start)
    sizes = walked[1][:, 0]
    if np.any(sizes < 3):
        at = int(np.argmax(sizes < 3))
        raise InvalidInputError(f"cannot read PLY file: face {at + 1} has {int(sizes[at])} corners, fewer than 3: "
                                "a malformed file")
    raw, offset, columns = np.frombuffer(data, np.uint8), walked[0], {}
    read = lambda where, dtype: raw[where[:, None] + np.arange(dtype.itemsize)].copy().view(dtype).reshape(-1)
    for name, kind, count_kind in fprops:  # (one list: _ply_check)
        dtype = np.dtype(endian + kind)
        if count_kind is None:
            columns[name] = read(offset, dtype)
            offset = offset + dtype.itemsize
        else:
            offset = offset + np.dtype(count_kind).itemsize
            flat = read(_runs(offset, sizes * dtype.itemsize)[::dtype.itemsize], dtype)
            offset = offset + sizes * dtype.itemsize
    return {k: vertex[k] for k in vertex.dtype.names}, columns, flat, sizes


def _in_range(values, dtype):
    """(n,) bool: which float64 `values` the integer `dtype` holds (min <= v < max + 1; NaN not)."""
    info = np.iinfo(dtype)
    return (values >= float(info.min)) & (values < float(info.max) + 1)


def _as(values, kind):
    """float64 values as the PLY type `kind`, as trimesh's ``astype`` makes them; Unsupported where
    that cast is undefined: a value beyond an integer type's range, or NaN (C leaves the result to
    the machine, and NumPy's loops differ, so trimesh's value may differ from this one)."""
    dtype = np.dtype(kind)
    if dtype.kind in "iu" and not np.all(_in_range(values, dtype)):
        raise Unsupported(f"a value beyond the range of its type {dtype}")
    return values.astype(dtype)


def _refuse_short_vertex(block, counts, vprops, first_line=None):
    """Raise the InvalidInputError for the first of the vertex lines `block` (their value `counts`)
    that lacks a coordinate: fewer values than the vertex's scalar properties up to the last of x,
    y, z (trimesh: "setting an array element with a sequence."). A line that lacks only later
    columns (a color) passes: trimesh reads it (it drops the colors); so do lines among which one is
    blank (the lines after it shifted: no line is known to be short). `first_line`: the file's line
    number of the first vertex line, named where given."""
    names = [p[0] for p in vprops]
    if not {"x", "y", "z"} <= set(names) or any(p[2] for p in vprops[:max(map(names.index, "xyz")) + 1]):
        return
    need = max(map(names.index, "xyz")) + 1
    short = np.asarray(counts) < need
    if np.any(short) and np.all(np.asarray(counts) > 0):  # (a blank line: every later line shifted, not short)
        at = int(np.argmax(short))
        where = "" if first_line is None else f" (line {first_line + at} of the file)"
        raise InvalidInputError(f"cannot read PLY file: vertex {at + 1}{where} holds {int(counts[at])} values, fewer "
                                f"than the {need} its properties need up to x, y, z ({block[at]!r}): a truncated or "
                                "malformed file")


@file_bytes
def check_vertex_lines(data: bytes):
    """Raise :func:`read_ply`'s InvalidInputError where a vertex line of an ASCII PLY file lacks
    a coordinate (fewer values than its properties up to the last of x, y, z), naming the line: for
    a file trimesh reads (other elements, lists), whose loader fails with "setting an array element
    with a sequence." there. Returns None otherwise (a binary file, a header this module does not
    read, a line that lacks only a color: trimesh reads it)."""
    try:
        elements, ascii, _, start, _ = _ply_header(data)
        if not ascii or "vertex" not in elements:
            return None
        lines = _text(data[start:]).splitlines()
    except Unsupported:
        return None
    before = 0
    for name, (count, _) in elements.items():  # (trimesh: one line per element, in the header's order)
        if name == "vertex":
            break
        before += count
    block = lines[before:before + elements["vertex"][0]]
    if not all(line.split() for line in lines[:before]):  # (a blank line: every later line shifted)
        return None
    counts = [len(line.split()) for line in block]
    _refuse_short_vertex(block, counts, elements["vertex"][1], data[:start].count(b"\n") + before + 1)
    return None


def _ply_ascii(lines, elements, endian, first_line):
    """The columns of an ASCII file's `lines` (as many as the header's counts at least: _ply_length);
    `first_line`: the file's line number of the first vertex line (named in an error)."""
    (nv, vprops), (nf, fprops) = elements["vertex"], elements["face"]
    block = lines[:nv]
    tokens, counts = _tokens(block, c_numbers=True)
    if np.any(counts != len(vprops)):
        _refuse_short_vertex(block, counts, vprops, first_line)  # (one that lacks only later columns: trimesh reads it)
        raise Unsupported("a vertex line with more or fewer values than properties")
    columns = _floats(tokens).reshape(nv, len(vprops))
    block = lines[nv:nv + nf]
    tokens, counts = _tokens(block, c_numbers=True)
    position = [p[2] is not None for p in fprops].index(True)
    scalars = len(fprops) - 1
    if np.any(counts < scalars + 1):
        raise Unsupported("a face line with fewer values than properties")
    starts = _starts(counts)
    values = _floats(_take(tokens, starts + position))
    sizes = values.astype(endian + fprops[position][2]).astype(np.int64)
    short = (values == sizes) & (counts < scalars + 1 + sizes)
    if np.any(short):  # trimesh would read the face shortened, or drop it
        line = int(np.argmax(short))
        raise InvalidInputError(f"cannot read PLY file: face line {line + 1} holds fewer values than its count "
                                f"({block[line]!r}): a truncated or malformed file")
    if np.any(values != sizes) or np.any(sizes < 3) or np.any(counts != scalars + 1 + sizes):
        raise Unsupported("a face list whose count is not its length")
    flat = _floats(_take(tokens, _runs(starts + position + 1, sizes)))
    index = np.dtype(endian + fprops[position][1])
    wrong = ~(_in_range(flat, index) & (flat == np.floor(flat)))  # (NaN too)
    if np.any(wrong):  # trimesh casts it to some index of the type (which: the machine's choice)
        line = int(np.argmax(np.cumsum(sizes) > int(np.argmax(wrong))))
        raise InvalidInputError(f"cannot read PLY file: face line {line + 1} holds an index that is not an integer "
                                f"of its type {index.name} ({block[line]!r}): a corrupted or malformed file")
    flat = flat.astype(index)
    # the other columns after the faces' errors (a value for trimesh to read must not hide one)
    face = {}
    for i, (name, kind, _) in enumerate(fprops):  # the scalars before and after the list
        if i != position:
            at = starts + i + (0 if i < position else sizes)
            face[name] = _as(_floats(_take(tokens, at)), endian + kind)
    vertex = {name: _as(columns[:, i], endian + kind) for i, (name, kind, _) in enumerate(vprops)}
    return vertex, face, flat, sizes
