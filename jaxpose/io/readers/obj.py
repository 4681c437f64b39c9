"""OBJ: ``v``, ``vt``, ``vn`` and faces of every reference form, as trimesh reads them."""
from __future__ import annotations

import re

import numpy as np

from ...errors import InvalidInputError
from .base import (Loaded, Unsupported, file_bytes, _checked, _floats, _ints, _text, _tokens, _triangulate,
                   _triangulate_inline)

__all__ = ["read_obj", "check_vertex_references", "check_texture_references", "without_comments", "without_indent"]


_INDEX = r"-?[0-9]+"
_OBJ_FORMS = {form: re.compile(rf"{ref}(?: {ref})*") for form, ref in (
    ((0, False), _INDEX), ((1, False), f"{_INDEX}/{_INDEX}"), ((2, True), f"{_INDEX}//{_INDEX}"),
    ((2, False), f"{_INDEX}/{_INDEX}/{_INDEX}"))}

_INLINE_COMMENT = re.compile(  # a data line, with the lines a backslash at its end continues it into, to its '#'
    rb"(?m)^([ \t]*(?:v|vt|vn|vp|f|l|p)[ \t](?:[^#\r\n]|\\\r?\n)*)#[^\r\n]*")


def without_comments(data: bytes) -> bytes:
    """An OBJ file's bytes with the ``#`` comment that ends a data line (``v``, ``vt``, ``vn``,
    ``vp``, ``f``, ``l``, ``p``: ``v 0 0 0 # a``, ``f 1 2 3 # tri``; on a line such a line continues
    into, ``f 1 2 \\`` then ``3 # c``) cut to its line end (the line end kept), as the file says; trimesh's loader and the fast reader's copy of it read such a line's
    comment as values ("could not be read to its end due to unmatched data"). Other lines are kept
    whole: comment lines (every reader skips them) and names (``o``, ``g``, ``usemtl``, ``mtllib``
    may hold a ``#``). `data` itself where it holds no ``#``."""
    at = data.find(b"#")
    while at >= 0:  # (comment lines only, as most files' headers: the bytes left as they are, unsearched)
        start = data.rfind(b"\n", 0, at) + 1
        if data[start:at].strip(b" \t\r") or data[max(start - 3, 0):start].rstrip(b"\r\n").endswith(b"\\"):
            # a '#' after some text on its line, or on a line continued into
            return _INLINE_COMMENT.sub(rb"\1", data)
        end = data.find(b"\n", at)
        at = -1 if end < 0 else data.find(b"#", end)
    return data


_INDENT = re.compile(rb"(?m)(?<!\\\n)^[ \t]+")  # white space that starts a line (not a continued one)


def without_indent(data: bytes) -> bytes:
    """An OBJ file's bytes without the white space that starts its lines (``  v 1 0 0``), a line
    continued by a ``\\`` at the end of the one before excepted (there it separates values);
    trimesh's loader and the fast reader's copy of it know a line by its first characters (``v ``,
    ``f ``): an indented vertex was dropped (every later face then one vertex off) and a file whose
    faces were all indented read as a point cloud, without a word. `data` itself where no line
    starts with white space."""
    if not (data[:1] in (b" ", b"\t") or b"\n " in data or b"\n\t" in data):
        return data
    return _INDENT.sub(b"", data)


@file_bytes
def read_obj(data: bytes) -> Loaded:
    """An OBJ file's mesh, as ``trimesh.load(..., file_type="obj", process=False)``.

    Raises:
      Unsupported: anything this reader does not reproduce exactly (read it with trimesh).
      InvalidInputError: a face referencing index 0 (trimesh reads it as the last vertex); a vertex
        line with fewer than 3 values or a face line with fewer than 3 corners (trimesh drops such a
        line without a word: most often a truncated file's last line; in a file with materials, which
        trimesh reads, the last line only); a face referencing a texture coordinate beyond the
        file's ``vt`` lines (trimesh drops all of the file's UV coordinates without a word:
        :func:`check_texture_references`); a last line that is a vertex whose last value is not a
        number (``v 0 -0.5 -``: a file cut within it), or a texture coordinate or a normal of that
        kind, or a face whose last corner is not a reference of its first corner's form (``f 1 2
        -``, ``f 1 2 3/``: trimesh reads a wrong face); lines that end in a lone carriage return (trimesh: NumPy's "could not be read to its
        end due to unmatched data"). A file cut at the end of a line, or within
        a number that stays one, reads as a valid OBJ file: no reader can tell.

    A ``#`` comment that ends a data line (``f 1 2 3 # tri``) is cut (:func:`without_comments`).
    Normal references (``v//vn``, ``v/vt/vn``) are not checked, nor texture references of a file
    without ``vt`` lines: those data are never used (:func:`jaxpose.io.mesh.read` drops the file's
    normals; a file without UV has none to lose), and trimesh reads such a file as this reader does.
    """
    text = _text(without_indent(without_comments(data)))  # "v 0 0 0 # a": the comment cut (trimesh read it
    # as values); "  v 0 0 0": the line's indent (trimesh dropped the line)
    text = text.replace("\t", " ")  # white space (trimesh knows "v " and "f ": it dropped "v\t" lines)
    text = "\n{}\n".format(text.strip().replace("\r\n", "\n")).replace("\\\n", "")
    if "\r" in text and "\n" not in text.strip():  # (trimesh: NumPy's "could not be read to its end ...")
        raise InvalidInputError("cannot read OBJ file: its lines end in a lone carriage return (classic Mac OS "
                                "line ends), which jaxpose does not read: convert them to \\n")
    _cut_last_number(text)  # (a vertex cut within its last number, "v 0 0.5 -": trimesh's NumPy "unmatched data"; a
    # face within its last corner, "f 1 2 -", "f 1 2 3/": a wrong face), for every file, whichever reader reads it
    if "usemtl" in text or "+e" in text or "-e" in text or "\r" in text:
        _cut_last_line(text)  # (a cut file's last line: trimesh drops it without a word)
        raise Unsupported("materials, or text trimesh's OBJ loader rewrites")
    bare = re.search(r"^[vf][ \t]*$", text, re.M)
    if bare:
        raise InvalidInputError(f"cannot read OBJ file: a line {bare.group().strip()!r} without values: a truncated or "
                                "malformed file")
    lines = text.split("\n")
    keyed = {}
    for key in ("v", "vt", "vn", "f"):
        prefix = key + " "
        keyed[key] = [line[len(prefix):] for line in lines if line.startswith(prefix)]
    if sum(1 for line in lines if line[:1] == "f") != len(keyed["f"]):
        raise Unsupported("a line starting with f that is not a face")
    parsed = {key: _tokens(keyed[key], c_numbers=True) for key in ("v", "vt", "vn") if keyed[key]}
    if "v" in parsed and np.any(parsed["v"][1] < 3):  # (a point cloud's too: checked before the next line)
        at = int(np.argmax(parsed["v"][1] < 3))
        raise InvalidInputError(f"cannot read OBJ file: vertex {at + 1} has fewer than 3 coordinates "
                                f"('v {keyed['v'][at].strip()}'): a truncated or malformed file")
    if not keyed["v"] or not keyed["f"]:
        raise Unsupported("no vertices or no faces")
    arrays = {}
    for key, (tokens, counts) in parsed.items():
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
    references, refs = _tokens(faces_lines, c_numbers=True)  # refs: corners per face (trimesh: fromstring)
    if np.any(refs < 3):
        at = int(np.argmax(refs < 3))
        raise InvalidInputError(f"cannot read OBJ file: face {at + 1} ('f {faces_lines[at]}') has fewer than 3 "
                                "corners: a truncated or malformed file")
    joined = " ".join(references)
    values = _ints(joined.replace("/", " ").split(), negative=True)  # (every form: the numbers between "/")
    if np.any(values == 0):  # trimesh reads a 0 as the last vertex (faces of several forms too)
        raise InvalidInputError("cannot read OBJ file: a face references index 0 (OBJ indices count from 1, or "
                                "from -1 backwards)")
    form = references[0].count("/"), "//" in references[0]  # v, v/vt, v//vn, v/vt/vn
    if form not in _OBJ_FORMS or not _OBJ_FORMS[form].fullmatch(joined):
        raise Unsupported("faces with several kinds of references")
    per = form[0] + 1 - form[1]  # values per corner
    flat = values.reshape(-1, per)
    flat[flat > 0] -= 1  # 1-based; negative ones stay (trimesh: from the end of all vertices)
    tex = flat[:, 1] if per in (2, 3) and not form[1] else None
    norm = flat[:, per - 1] if (per == 2 and form[1]) or per == 3 else None
    if np.all(refs == refs[0]):  # trimesh's vectorized path: (n, k), triangulated by Trimesh later
        shape = (-1, int(refs[0]))
        faces, tex, norm = (None if a is None else a.reshape(shape) for a in (flat[:, 0], tex, norm))
    else:  # trimesh's loop: every face split in file order
        faces, tex, norm = (None if a is None else _triangulate_inline(a, refs) for a in (flat[:, 0], tex, norm))
    outside = (faces < -len(v)) | (faces >= len(v))
    if np.any(outside):  # (trimesh: a raw IndexError, counted from 0)
        at = faces[outside].flat[0]
        raise _outside(at + 1 if at >= 0 else at, len(v))
    if tex is not None and vt is not None and np.any(beyond := (tex < -len(vt)) | (tex >= len(vt))):
        at = tex[beyond].flat[0]  # (trimesh: every UV coordinate of the file dropped)
        raise _outside_uv(at + 1 if at >= 0 else at, len(vt))
    return _obj_mesh(v, vt, vn, colors, faces, tex, norm)


def _outside(reference, count):
    """The error for a face that references vertex ``reference`` (OBJ's numbering) of ``count``."""
    return InvalidInputError(f"cannot read OBJ file: a face references vertex {reference} of the {count} it has "
                             "(OBJ counts from 1, or from -1 backwards)")


@file_bytes
def check_vertex_references(data: bytes):
    """Raise :func:`read_obj`'s InvalidInputError where a face of an OBJ file references a vertex
    that is not there (beyond its count of ``v`` lines, or before the first counting back): for a
    file trimesh reads (materials, faces of several forms), whose loader fails with a raw
    IndexError there. Returns None where every reference is in range (or the text is not UTF-8)."""
    try:
        text = _text(data)
    except Unsupported:
        return None
    lines = text.replace("\r\n", "\n").replace("\\\n", "").split("\n")
    count = sum(1 for line in lines if line[:2] in ("v ", "v\t"))
    for line in lines:
        if line[:2] not in ("f ", "f\t"):
            continue
        for corner in line.split()[1:]:
            try:
                reference = int(corner.split("/")[0])
            except ValueError:  # (not a reference: trimesh's error stands)
                continue
            if reference > count or reference < -count:
                raise _outside(reference, count)
    return None


def _outside_uv(reference, count):
    """The error for a face that references texture coordinate ``reference`` (OBJ's numbering) of
    ``count``."""
    return InvalidInputError(f"cannot read OBJ file: a face references texture coordinate {reference} of the "
                             f"{count} it has ('vt' lines; OBJ counts from 1, or from -1 backwards): its UV "
                             "coordinates would be dropped")


_TEXTURE_REFERENCE = re.compile(r"(?<!\S)-?[0-9]+/(-?[0-9]+)")  # a corner's second number (v/vt, v/vt/vn)


@file_bytes
def check_texture_references(data: bytes):
    """Raise :func:`read_obj`'s InvalidInputError where a face of an OBJ file references a texture
    coordinate that is not there (beyond its count of ``vt`` lines, before the first counting
    back, or 0): for a file trimesh reads (materials, faces of several forms), whose loader then
    drops every UV coordinate of the file without a word. Returns None where every reference is in
    range, the file has no ``vt`` lines (no UV to lose), or the text is not UTF-8."""
    try:
        text = _text(data)
    except Unsupported:
        return None
    text = text.replace("\r\n", "\n").replace("\\\n", "")
    count = len(re.findall(r"^vt[ \t]", text, re.M))
    if not count:
        return None
    corners = " ".join(re.findall(r"^f[ \t](.*)$", text, re.M))
    found = _TEXTURE_REFERENCE.findall(corners)
    huge = next((r for r in found if len(r.lstrip("-")) > 18), None)  # (beyond int64: beyond any count too)
    if huge is not None:
        raise _outside_uv(int(huge), count)
    references = np.array(found, np.int64)
    beyond = (references > count) | (references < -count) | (references == 0)
    if np.any(beyond):
        raise _outside_uv(int(references[beyond][0]), count)
    return None


def _cut_last_line(text):
    """Raise InvalidInputError where the last line of an OBJ file's `text` is a vertex of fewer than
    3 values, a face of fewer than 3 corners, or a line :func:`_cut_last_number` refuses (``v 0
    0.5 -``, ``f 1 2 -``): what a file cut within its last line ends in. O(1): the other lines are not looked at."""
    last = _last_line(text)  # (a longer line: no "v" or "f" among its last words)
    if last[:1] in (["v"], ["f"]) and len(last) < 4:
        what = "vertex of fewer than 3 values" if last[0] == "v" else "face of fewer than 3 corners"
        raise InvalidInputError(f"cannot read OBJ file: its last line {' '.join(last)!r} is a {what}: a truncated or "
                                "malformed file")
    _cut_last_number(text)


def _last_line(text):
    """The words of the last line of an OBJ file's `text` (lines end in \\n, \\r\\n or a lone \\r).
    O(1): the last 4096 characters."""
    return re.split(r"[\r\n]", text[-4096:].rstrip())[-1].split()


def _cut_last_number(text):
    """Raise InvalidInputError where the last line of an OBJ file's `text` is a vertex, a texture
    coordinate or a normal whose last value is not a number (``v 0 0.5 -``, ``vn 0 0 -``), or a
    face of 3 corners or more whose last corner is not a reference of its first corner's form
    (``f 1 2 -``, ``f 1 2 3/``, ``f 1/1 2/2 3/``, ``f 1/1/1 2/2/2 3/3``; a form is ``v``, ``v/vt``,
    ``v//vn`` or ``v/vt/vn``): a file cut within it (trimesh reads ``-`` as vertex 0 and ``3/`` as
    ``3``: a wrong face, without a word). O(1)."""
    last = _last_line(text)
    if (last[:1] == ["v"] and len(last) >= 4 or last[:1] in (["vt"], ["vn"]) and len(last) >= 2) and not _is_number(
            last[-1]):  # (a vertex of fewer values: the messages of fewer than 3)
        raise InvalidInputError(f"cannot read OBJ file: its last line {' '.join(last)!r} ends in {last[-1]!r}, which is "
                                "not a number: a truncated or malformed file")
    if last[:1] == ["f"] and len(last) >= 4 and _CORNER.sub("N", last[-1]) != _CORNER.sub("N", last[1]):
        # (a face of fewer corners: the messages of fewer than 3)
        raise InvalidInputError(f"cannot read OBJ file: its last line {' '.join(last)!r} ends in {last[-1]!r}, which is "
                                f"not a reference of the form of its first corner {last[1]!r}: a truncated or "
                                "malformed file")


_CORNER = re.compile(r"[-+]?[0-9]+")  # a number of a face's corner: the rest is its form ("N", "N/N", "N//N", "N/N/N")


def _is_number(token):
    try:
        float(token)
    except ValueError:
        return False
    return True


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
