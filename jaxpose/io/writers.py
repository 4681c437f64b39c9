"""Fast writers: trimesh's text OFF and binary PLY of a plain mesh, byte for byte, with NumPy.

``off_bytes(vertices, faces)`` is ``trimesh.exchange.off.export_off(mesh).encode()`` (coordinates
as ``"{:.10f}"``, faces as ``3 a b c``), built with array arithmetic instead of one Python format
call per number (digits five at a time from a table, each vertex index's text made once). The
decimal digits are exact: each coordinate times 10^10 is split into two doubles whose sum is the
exact product (Dekker's product), and rounded half to even from there, as Python's formatting
rounds the exact binary value. Coordinates of 2^52 / 10^10 (about 450,000) and
more raise :class:`Unsupported` (the caller then writes with trimesh).

``ply_bytes(vertices, faces)`` is ``trimesh.exchange.ply.export_ply(mesh)`` of a mesh with no
colors, normals or attributes (trimesh's header, float32 coordinates, ``uchar int`` face lists):
what the batch writes without making a trimesh object.

Example::

    data = off_bytes(mesh.vertices, mesh.faces)   # == mesh.export(file_type="off").encode()
    data = ply_bytes(mesh.vertices, mesh.faces)   # == mesh.export(file_type="ply") of a plain mesh
"""
from __future__ import annotations

import numpy as np

from .readers import Unsupported

__all__ = ["off_bytes", "ply_bytes", "fixed_decimals"]

DIGITS = 10  # trimesh's export_off
_SPLIT = 134217729.0  # 2^27 + 1, Veltkamp's splitter for doubles


def _split(a):
    c = _SPLIT * a
    high = c - (c - a)
    return high, a - high


def _scaled(x, digits):
    """round_half_even(|x| * 10^digits) as int64, exactly. (n,) float64 -> (n,) int64."""
    a = np.abs(x)
    b = float(10**digits)
    p = a * b
    if not np.all(p < 2.0**52):
        raise Unsupported("coordinates too large to format exactly here")
    ah, al = _split(a)
    bh, bl = _split(np.float64(b))
    err = ((ah * bh - p) + ah * bl + al * bh) + al * bl  # a * b == p + err exactly
    whole = np.floor(p)
    half = (p - whole) - 0.5  # exact: p and whole share their last binary place
    whole = whole.astype(np.int64)
    up = (half > -err) | ((half == -err) & (whole & 1 == 1))  # past the half, or a tie to even
    return whole + up  # (an exact value just below `whole` still rounds to it)


def _digits_matrix(values, width):
    """Right-aligned decimal digits of non-negative int64 `values` (each below 10^width) in a
    (n, width) uint8 matrix of ASCII: five digits at a time from a table of 00000-99999."""
    out = np.empty((len(values), -(-width // 5) * 5), np.uint8)
    rest = np.asarray(values, np.int64)
    for column in range(out.shape[1] - 5, -1, -5):
        out[:, column:column + 5] = np.take(_five_digits(), rest % 100000, axis=0)
        rest = rest // 100000
    return out[:, out.shape[1] - width:]


def _digit_counts(values, width):
    """How many decimal digits each non-negative int64 of `values` has (0 has one), up to `width`."""
    count = np.ones(len(values), np.int64)
    for power in range(1, width):
        count += values >= 10**power
    return count


_FIVE = []


def _five_digits():
    """The (100000, 5) uint8 ASCII digits of 00000 ... 99999, made once."""
    if not _FIVE:
        table = np.empty((100000, 5), np.uint8)
        rest = np.arange(100000)
        for column in range(4, -1, -1):
            table[:, column] = 48 + rest % 10
            rest //= 10
        _FIVE.append(table)
    return _FIVE[0]


def fixed_decimals(x, digits=DIGITS, separators=None):
    """``"{:.<digits>f}".format(v)`` of every value, each followed by its separator byte. Returns the
    (values, width) character matrix and its keep mask, row per value."""
    x = np.asarray(x, np.float64).reshape(-1)
    scaled = _scaled(x, digits)
    whole, fraction = np.divmod(scaled, 10**digits)
    width = max(1, len(str(int(whole.max())))) if len(whole) else 1
    matrix = np.empty((len(x), width + digits + 3), np.uint8)
    matrix[:, 0] = np.where(np.signbit(x), ord("-"), ord(" "))
    matrix[:, 1:width + 1] = _digits_matrix(whole, width)
    count = _digit_counts(whole, width)
    matrix[:, width + 1] = ord(".")
    matrix[:, width + 2:width + 2 + digits] = _digits_matrix(fraction, digits)
    matrix[:, -1] = separators
    keep = np.ones(matrix.shape, bool)
    keep[:, 1:width + 1] = np.arange(width) >= (width - count)[:, None]
    keep[:, 0] = np.signbit(x)
    return matrix, keep


def _rows(n, columns):
    """Separators of a table's cells: spaces, a newline after each row's last cell."""
    separators = np.full((n, columns), ord(" "), np.uint8)
    separators[:, -1] = ord("\n")
    return separators.reshape(-1)


def _triangles(faces):
    """The ``3 a b c`` lines of triangles (m, 3) int in [0, 10^7): each index's text with a space
    (or a newline after the third) made once in an 8-byte cell, and the cells gathered per corner."""
    top = int(faces.max())
    width = len(str(top))
    if width > 7:
        raise Unsupported("vertex indices of more than 7 digits")
    indices = np.arange(top + 1)
    cells = np.zeros((top + 1, 8), np.uint8)
    cells[:, :width] = _digits_matrix(indices, width)
    shown = np.zeros(cells.shape, bool)
    shown[:, :width + 1] = np.arange(width + 1) >= (width - _digit_counts(indices, width))[:, None]
    spaced, ended = cells.copy(), cells
    spaced[:, width], ended[:, width] = ord(" "), ord("\n")
    rows = np.empty((len(faces), 4), np.uint64)  # "3 " and the three corners
    keep = np.empty(rows.shape, np.uint64)
    rows[:, 0] = np.frombuffer(b"3 \0\0\0\0\0\0", np.uint64)[0]
    keep[:, 0] = np.frombuffer(b"\1\1\0\0\0\0\0\0", np.uint64)[0]
    for corner, text in enumerate((spaced, spaced, ended)):
        rows[:, 1 + corner] = text.view(np.uint64)[faces[:, corner], 0]
        keep[:, 1 + corner] = shown.view(np.uint64)[faces[:, corner], 0]
    return rows.view(np.uint8)[keep.view(bool)].tobytes()


def off_bytes(vertices, faces) -> bytes:
    """trimesh's OFF export of a mesh, exactly: ``OFF``, the counts, ``"{:.10f}"`` coordinates, then
    ``3 a b c`` faces, newline-terminated. vertices (n, 3) float, faces (m, 3) int >= 0.

    Raises:
      Unsupported: values this writer does not format (coordinates of 450,000 or more, NaN, 10^7
        vertices or more, faces of vertices that are not there).
    """
    vertices = np.asarray(vertices, np.float64)
    faces = np.asarray(faces, np.int64)
    if vertices.ndim != 2 or vertices.shape[1] != 3 or faces.ndim != 2 or faces.shape[1] != 3 \
            or not len(vertices) or not len(faces) or not np.all(np.isfinite(vertices)) or faces.min() < 0 \
            or faces.max() >= len(vertices):
        raise Unsupported("not a mesh this writer formats")
    matrix, keep = fixed_decimals(vertices, DIGITS, _rows(len(vertices), 3))
    coordinates = matrix[keep].tobytes()
    head = f"OFF\n{len(vertices)} {len(faces)} 0\n".encode()
    return head + coordinates + _triangles(faces)


_PLY_HEAD = ("ply\nformat binary_little_endian 1.0\ncomment https://github.com/mikedh/trimesh\n"
             "element vertex {}\nproperty float x\nproperty float y\nproperty float z\n"
             "element face {}\nproperty list uchar int vertex_indices\nend_header\n")
_PLY_FACE = np.dtype([("count", "<u1"), ("index", "<i4", (3,))])


def ply_bytes(vertices, faces) -> bytes:
    """trimesh's binary PLY export of a mesh without colors, normals or attributes, exactly: its
    header, the vertices as little-endian float32, each face as ``3`` (uchar) and three int32.
    vertices (n, 3) float, faces (m, 3) int in [0, n).

    Raises:
      Unsupported: not a mesh of that kind, or 2^31 vertices or more.
    """
    vertices = np.asarray(vertices, np.float64)
    faces = np.asarray(faces, np.int64)
    if vertices.ndim != 2 or vertices.shape[1] != 3 or faces.ndim != 2 or faces.shape[1] != 3 \
            or not len(faces) or faces.min() < 0 or faces.max() >= min(len(vertices), 2**31):
        raise Unsupported("not a mesh this writer writes")
    packed = np.zeros(len(faces), _PLY_FACE)
    packed["count"] = 3
    packed["index"] = faces
    return (_PLY_HEAD.format(len(vertices), len(faces)).encode() + vertices.astype("<f4").tobytes()
            + packed.tobytes())
