"""STL: binary, and ASCII with one solid, as trimesh reads them."""
from __future__ import annotations

import numpy as np

from ...errors import InvalidInputError
from .base import Loaded, Unsupported, file_bytes, _checked, _floats, _text, _tokens

__all__ = ["read_stl"]


_STL_FACET = np.dtype([("normals", "<f4", (3,)), ("vertices", "<f4", (3, 3)), ("attributes", "<u2")])


@file_bytes
def read_stl(data: bytes) -> Loaded:
    """An STL file's mesh (binary, or ASCII with one solid), as ``trimesh.load(..., file_type="stl",
    process=False)``: three vertices per triangle, in order (duplicates are not merged here).

    Raises:
      Unsupported: anything this reader does not reproduce exactly (read it with trimesh).
      InvalidInputError: an ASCII file whose solid has no ``endsolid`` line (a truncated file:
        trimesh reads no vertices of it).
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
    if text.startswith("solid") and "endsolid" not in text and "facet" in text:  # (trimesh: no vertices)
        raise InvalidInputError("cannot read STL file: an ASCII STL without the 'endsolid' line that ends its "
                                "solid: a truncated file")
    if text.count("endsolid") != 1 or text.count("solid") != 2 or not text.startswith("solid") \
            or text.find("solid", text.find("endsolid") + 8) >= 0:
        raise Unsupported("not one ASCII solid")
    solid = text[:text.find("endsolid")]
    values = {}
    for key in ("vertex", "normal"):
        pieces = solid.split(key)[1:]
        lines = [piece[:piece.find("\n")] for piece in pieces]
        tokens, counts = _tokens(lines, c_numbers=True) if lines else ([], np.zeros(0, np.int64))
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
