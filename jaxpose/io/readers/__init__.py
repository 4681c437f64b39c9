"""Fast readers for OFF, PLY, OBJ and STL: what trimesh's loaders give, parsed with NumPy.

Each reader takes a file's bytes (bytes, bytearray or memoryview; anything else, a path or text
as str included, is a TypeError at its boundary) and returns :class:`Loaded`: the vertices and faces that
``trimesh.load(file, process=False)`` gives for it (equal arrays: the same values, order and
triangulation), and the other arguments trimesh's loader hands to ``trimesh.Trimesh`` (vertex
normals and colors, face colors, an STL's face normals and attributes, an OBJ's UV coordinates), so
that ``trimesh.Trimesh(**loaded.kwargs(), process=False)`` is the mesh trimesh would have made.

What they read (anything else raises :class:`Unsupported`, and the caller reads the file with
trimesh: never a silently different mesh):

* OFF (text): ``OFF`` / ``COFF`` headers, ``#`` comments, blank lines, any line endings, extra
  values on a line (colors), triangles, quads and polygons. A comment runs to the end of its
  line wherever it is (trimesh's own reading of a comment after the first line end repeats the
  lines before it: the counts line read as the first vertex; here, and in
  :func:`jaxpose.mesh.load`, which hands trimesh the file without comments, as the file says).
* PLY: ``ascii``, ``binary_little_endian`` and ``binary_big_endian``; a ``vertex`` element with
  ``x``, ``y``, ``z`` and any other scalar properties (``nx ny nz`` become vertex normals,
  ``red green blue [alpha]`` colors, as trimesh does); a ``face`` element with a
  ``vertex_indices`` (or ``vertex_index``) list of any count and index types and any other scalar
  properties. Binary lists all of the length of the first (trimesh's own rule).
* OBJ: ``v`` (3, 4 or 6 values: ``x y z [w]`` or ``x y z r g b``), ``vt``, ``vn``, faces of
  ``v``, ``v/vt``, ``v//vn`` and ``v/vt/vn`` references (negative ones count from the end of the
  file's vertices, as in trimesh), triangles, quads and polygons, ``o`` / ``g`` / ``s`` lines,
  comments, ``\\`` line continuations; values separated by spaces or tabs (trimesh's loader
  knows ``v `` and ``f `` only and drops ``v\\t`` lines: :func:`jaxpose.mesh.load` hands it the
  tabs as spaces). No ``usemtl`` (materials split the mesh).
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

from ...errors import InvalidInputError
from .base import Loaded, Unsupported, file_bytes
from .obj import read_obj
from .off import read_off
from .ply import read_ply
from .stl import read_stl

__all__ = ["Loaded", "Unsupported", "READERS", "read", "read_off", "read_ply", "read_obj", "read_stl"]

READERS = {"off": read_off, "ply": read_ply, "obj": read_obj, "stl": read_stl}


@file_bytes
def read(data: bytes, file_type: str) -> Loaded:
    """The mesh of a file's bytes in `file_type` (a key of :data:`READERS`).

    Raises:
      Unsupported: no fast reader for the format, or one that cannot reproduce trimesh exactly.
      InvalidInputError: a file that is certainly broken, where trimesh would read part of it
        (or a wrong mesh) without a word: an OFF or ASCII PLY file with fewer vertex or face lines
        than its counts say or a blank line among them (one element a line), a binary PLY file with fewer bytes than its elements need (a PLY
        point cloud too), a face line with fewer indices than its count, a PLY element with a
        negative count, an ASCII PLY face index that is not an integer of its type, an OBJ face
        referencing vertex 0 (OBJ counts from 1), an OBJ face of fewer than 3 corners or vertex of
        fewer than 3 values, an OBJ cut within its last line's last value or reference (``v 0 0
        -``, ``f 1 2 -``, ``f 1 2 3/``), a file that trimesh fails on for a reason the reader can name
        (a binary PLY whose length is not what its header's elements take, a PLY header cut before
        its end or with a count that is not a whole number, an OFF counts line that is not whole
        numbers, an OFF vertex line of fewer than 3 values, an ASCII STL without ``endsolid``)
        (the message names no file: the caller's does).
      TypeError: ``data`` is not bytes-like (a str: pass the file's bytes).
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
