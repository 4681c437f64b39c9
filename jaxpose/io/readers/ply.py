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
    """Refuse a binary file whose length after the header is not what its elements take, each list
    as long as its count. Where every list of an element is as long as its first item's (trimesh's
    rule), the length is computed from the header and the first lists, in O(1); where it differs,
    the elements are walked (:func:`_walk`): a file that ends inside an element, or holds bytes
    after its last one, is refused, naming where; one whose lists have several lengths and whose
    length is exactly what they take is valid (Blender's and MeshLab's binary PLY of triangles and
    quads): returns the walk, which :func:`read_ply` reads. Returns None where the first rule's
    length is the file's. Counts are Python integers: a header that claims billions of elements
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
    walked = _walk(data, start, elements, endian)
    if isinstance(walked, dict):
        return walked
    name, index, end = walked
    if end > len(data):
        raise InvalidInputError(f"cannot read PLY file: truncated, {have} bytes after the header end inside its {name} "
                                f"{index + 1} of {elements[name][0]} (its {declared} elements, every list as long as "
                                "its count): a truncated or malformed file")
    extra = len(data) - end
    raise InvalidInputError(f"cannot read PLY file: {extra} byte{'s' if extra != 1 else ''} after its last element "
                            f"(its {declared} elements take {end - start}, every list as long as its count): a "
                            "truncated or malformed file")


_STRUCT = {"i1": "b", "u1": "B", "i2": "h", "u2": "H", "i4": "i", "u4": "I", "i8": "q", "u8": "Q"}


def _gather(data, positions, dtype):
    """The values of `dtype` (with its byte order) that start at the byte `positions` (int64) of
    `data`, aligned or not: (len(positions),) of dtype. Reads each through one of the dtype's
    itemsize shifted views of the bytes: no per-byte index."""
    size, out = dtype.itemsize, np.empty(len(positions), dtype)
    shift = positions % size
    for k in np.unique(shift).tolist():
        chosen = shift == k
        view = np.frombuffer(data, dtype, (len(data) - k) // size, k)
        out[chosen] = view[positions[chosen] // size]
    return out


def _walk(data, start, elements, endian):
    """The binary file's elements item by item, each list as long as its own count: {name: (first
    byte, starts, lengths)}, ``starts`` (count,) int64 the first byte of each item and ``lengths``
    (count, lists) int64 for an element with lists of several lengths, None and None for one
    without lists or whose lists all have its first item's lengths; where the elements end exactly
    at the file's end. Else (name, index, end): the element and item where the file ends inside it
    (end > len(data), the end that item would need), or the last element's end where bytes are left
    after it. An element's items are first tried at its first item's lengths (NumPy, O(1) in
    Python); only an element whose lists differ is walked item by item in Python (its count is
    bounded by the file's bytes: :func:`_ply_length` checked each item's least size first)."""
    import struct
    from array import array

    out, position, size = {}, start, len(data)
    for name, (count, props) in elements.items():
        begin = position
        if count <= 0:
            out[name] = (begin, None, None)
            continue
        segments, fixed = [], 0  # (bytes before the list, its count's struct, the size of one of its items)
        for _, kind, count_kind in props:
            if count_kind is None:
                fixed += np.dtype(kind).itemsize
            else:
                segments.append((fixed, struct.Struct(endian + _STRUCT[count_kind]), np.dtype(kind).itemsize))
                fixed = 0
        first, item, at = [], 0, position  # the first item's lengths, its size
        for skip, unpack, width in segments:
            at += skip
            if at + unpack.size > size:
                return name, 0, at + unpack.size
            first.append(unpack.unpack_from(data, at)[0])
            at += unpack.size + max(first[-1], 0) * width
        item = at + fixed - position
        fits = min(count, (size - position) // item) if item else count
        uniform, offset = True, 0
        reach = fits + 1 if fits < count else fits  # (and the item the file ends in, where its counts are there)
        for (skip, unpack, width), length in zip(segments, first):  # every such item's counts at the first's
            offset += skip
            places = position + offset + item * np.arange(reach, dtype=np.int64)
            places = places[places + unpack.size <= size]
            if np.any(_gather(data, places, np.dtype(unpack.format)) != length):
                uniform = False
                break
            offset += unpack.size + max(length, 0) * width
        if uniform:
            if fits < count:  # (the first lengths to the end: the file ends inside item `fits`)
                return name, fits, position + (fits + 1) * item
            position += count * item
            out[name] = (begin, None, None)
            continue
        starts, lengths = array("q"), array("q")
        for index in range(count):
            starts.append(position)
            for skip, unpack, width in segments:
                position += skip
                if position + unpack.size > size:
                    return name, index, position + unpack.size
                length = unpack.unpack_from(data, position)[0]
                lengths.append(length)
                position += unpack.size + max(length, 0) * width
            position += fixed
            if position > size:
                return name, index, position
        out[name] = (begin, np.frombuffer(starts, np.int64),
                     np.frombuffer(lengths, np.int64).reshape(count, len(segments)))
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
    walked = None if ascii else lines
    if walked is None:
        try:
            if texture:
                raise Unsupported("a texture file")
            _ply_check(elements)
        except Unsupported:  # trimesh reads it, unless its lists have several lengths whose bytes add up
            several = None if ascii else _walk(data, start, elements, endian)
            if not isinstance(several, dict) or all(w[1] is None for w in several.values()):
                raise
            walked = several
    if walked is None:
        if ascii:
            vertex, face, flat, counts = _ply_ascii(lines, elements, endian, data[:start].count(b"\n") + 1)
        else:
            got = _ply_binary(data, start, elements, endian)
            walked = _walk(data, start, elements, endian) if got is None else None  # (several lengths that fit)
            if got is None and not isinstance(walked, dict):
                raise InvalidInputError(f"cannot read PLY file: its {walked[0]} {walked[1] + 1} has lists that do not "
                                        "end where its file does: a malformed file")
            vertex, face, flat, counts = got or (None,) * 4
    if walked is not None:  # binary lists of several lengths (trimesh refuses the file: "unexpected length")
        vertex, face, flat, counts = _ply_walked(data, elements, endian, walked)
    vertices = np.column_stack([vertex[k] for k in "xyz"])
    faces = _triangulate(flat, counts)
    if walked is not None and len(faces) and (faces.min() < 0 or faces.max() >= len(vertices)):
        bad = int(faces.min()) if faces.min() < 0 else int(faces.max())  # (trimesh cannot read it: said here)
        raise InvalidInputError(f"cannot read PLY file: a face references vertex {bad} of {len(vertices)}: a "
                                "malformed file")
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
    ftype = _face_type(fprops, endian, size)
    if len(data) - start != nv * vtype.itemsize + nf * ftype.itemsize:
        raise Unsupported("a file length that does not match its header (or lists of several lengths)")
    vertex = np.frombuffer(data, vtype, nv, start)
    face = np.frombuffer(data, ftype, nf, face_start)
    if np.any(face[name]["f0"] != size):  # (lists of several lengths whose bytes add up: read_ply walks them)
        return None
    columns = {p[0]: face[p[0]] for p in fprops if p[2] is None}
    return ({k: vertex[k] for k in vertex.dtype.names}, columns, face[name]["f1"].reshape(-1),
            np.full(nf, size, np.int64))


def _face_type(fprops, endian, size):
    """The row dtype of a binary face element whose one list is `size` long in every row (trimesh's
    rule): its scalars by name, the list as (``f0`` its count, ``f1`` its `size` items)."""
    return np.dtype([(p[0], endian + p[1]) if p[2] is None else
                     (p[0], [("f0", endian + p[2]), ("f1", endian + p[1], (size,))]) for p in fprops])


def _ply_walked(data, elements, endian, walked):
    """:func:`_ply_binary`'s columns of a file whose face lists have several lengths (`walked`:
    :func:`_walk`'s). Reads the vertices' scalars (texture coordinates dropped: nothing reads
    them) and the faces' vertex indices and scalars, whatever other elements the file holds;
    InvalidInputError where the file has no such vertices and faces (trimesh refuses such a file)."""
    vertex, face = elements.get("vertex"), elements.get("face")
    lists = [p for p in face[1] if p[2]] if face else []
    problem = ("no vertex element" if vertex is None else "no face element" if face is None else
               "vertices without x, y, z, or with lists" if not {"x", "y", "z"} <= {p[0] for p in vertex[1]}
               or any(p[2] for p in vertex[1]) else
               "faces without one vertex_indices list of integers, or with other lists"
               if len(lists) != 1 or lists[0][0] not in _PLY_INDEX or lists[0][1][0] not in "ui" else
               "no vertices or no faces" if vertex[0] == 0 or face[0] == 0 else None)
    if problem:
        several = sorted({n for w in walked.values() if w[2] is not None for n in np.unique(w[2]).tolist()})
        raise InvalidInputError(f"cannot read PLY file: a binary PLY whose lists have several lengths "
                                f"({', '.join(map(str, several))}) and {problem}: jaxpose does not read it (nor does "
                                "trimesh)")
    (nv, vprops), (nf, fprops) = vertex, face
    columns = np.frombuffer(data, np.dtype([(n, endian + kind) for n, kind, _ in vprops]), nv, walked["vertex"][0])
    begin, offset, sizes = walked["face"]
    if offset is None:  # (a face element of one length beside lists of several elsewhere)
        return {k: columns[k] for k in columns.dtype.names}, *_uniform_faces(data, begin, face, endian)
    sizes = sizes[:, 0]
    if np.any(sizes < 3):
        at = int(np.argmax(sizes < 3))
        raise InvalidInputError(f"cannot read PLY file: face {at + 1} has {int(sizes[at])} corners, fewer than 3: "
                                "a malformed file")
    out = {}
    for name, kind, count_kind in fprops:
        dtype = np.dtype(endian + kind)
        if count_kind is None:
            out[name] = _gather(data, offset, dtype)
            offset = offset + dtype.itemsize
        else:
            offset = offset + np.dtype(count_kind).itemsize
            corner = _runs(np.zeros(len(sizes), np.int64), sizes)  # 0 .. size - 1, face after face
            flat = _gather(data, np.repeat(offset, sizes) + dtype.itemsize * corner, dtype)
            offset = offset + sizes * dtype.itemsize
    return {k: columns[k] for k in columns.dtype.names}, out, flat, sizes


def _uniform_faces(data, begin, face, endian):
    """The face element at byte `begin` whose lists all have its first item's length (walked:
    lists of several lengths elsewhere in the file): (columns, flat, counts)."""
    count, fprops = face
    position = [p[2] is not None for p in fprops].index(True)
    before = sum(np.dtype(p[1]).itemsize for p in fprops[:position])
    size = int(np.frombuffer(data, endian + fprops[position][2], 1, begin + before)[0])
    if size < 3:
        raise InvalidInputError(f"cannot read PLY file: its faces have {size} corners, fewer than 3: a malformed file")
    rows = np.frombuffer(data, _face_type(fprops, endian, size), count, begin)
    columns = {p[0]: rows[p[0]] for p in fprops if p[2] is None}
    return columns, rows[fprops[position][0]]["f1"].reshape(-1), np.full(count, size, np.int64)


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
