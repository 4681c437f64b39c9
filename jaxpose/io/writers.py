"""Fast writers: trimesh's text OFF, byte for byte, formatted with NumPy.

``off_bytes(vertices, faces)`` is ``trimesh.exchange.off.export_off(mesh).encode()`` (coordinates
as ``"{:.10f}"``, faces as ``3 a b c``), built with array arithmetic instead of one Python format
call per number. The decimal digits are exact: each coordinate times 10^10 is split into two
doubles whose sum is the exact product (Dekker's product), and rounded half to even from there, as
Python's formatting rounds the exact binary value. Coordinates of 2^52 / 10^10 (about 450,000) and
more raise :class:`Unsupported` (the caller then writes with trimesh).

Example::

    data = off_bytes(mesh.vertices, mesh.faces)   # == mesh.export(file_type="off").encode()
"""
from __future__ import annotations

import numpy as np

from .readers import Unsupported

__all__ = ["off_bytes", "fixed_decimals", "integers"]

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
    """Right-aligned decimal digits of non-negative int64 `values` in a (n, width) uint8 matrix of
    ASCII, and each value's digit count."""
    out = np.empty((len(values), width), np.uint8)
    rest = values.copy()
    for column in range(width - 1, -1, -1):
        out[:, column] = 48 + rest % 10
        rest //= 10
    count = np.ones(len(values), np.int64)
    bound = values.copy()
    for _ in range(width - 1):
        bound //= 10
        count += bound > 0
    return out, count


def fixed_decimals(x, digits=DIGITS, separators=None):
    """``"{:.<digits>f}".format(v)`` of every value, each followed by its separator byte. Returns the
    (values, width) character matrix and its keep mask, row per value."""
    x = np.asarray(x, np.float64).reshape(-1)
    scaled = _scaled(x, digits)
    whole, fraction = np.divmod(scaled, 10**digits)
    width = max(1, len(str(int(whole.max())))) if len(whole) else 1
    whole_chars, count = _digits_matrix(whole, width)
    fraction_chars, _ = _digits_matrix(fraction, digits)
    sign = np.where(np.signbit(x), ord("-"), ord(" ")).astype(np.uint8)
    matrix = np.concatenate([sign[:, None], whole_chars, np.full((len(x), 1), ord("."), np.uint8), fraction_chars,
                             separators[:, None]], axis=1)
    keep = np.ones(matrix.shape, bool)
    keep[:, 1:width + 1] = np.arange(width) >= (width - count)[:, None]
    keep[:, 0] = np.signbit(x)
    return matrix, keep


def integers(values, separators):
    """Decimal text of non-negative integers, each followed by its separator: (matrix, keep)."""
    values = np.asarray(values, np.int64).reshape(-1)
    width = max(1, len(str(int(values.max())))) if len(values) else 1
    chars, count = _digits_matrix(values, width)
    matrix = np.concatenate([chars, separators[:, None]], axis=1)
    keep = np.ones(matrix.shape, bool)
    keep[:, :width] = np.arange(width) >= (width - count)[:, None]
    return matrix, keep


def _rows(n, columns):
    """Separators of a table's cells: spaces, a newline after each row's last cell."""
    separators = np.full((n, columns), ord(" "), np.uint8)
    separators[:, -1] = ord("\n")
    return separators.reshape(-1)


def off_bytes(vertices, faces) -> bytes:
    """trimesh's OFF export of a mesh, exactly: ``OFF``, the counts, ``"{:.10f}"`` coordinates, then
    ``3 a b c`` faces, newline-terminated. vertices (n, 3) float, faces (m, 3) int >= 0.

    Raises:
      Unsupported: values this writer does not format (coordinates of 450,000 or more, NaN).
    """
    vertices = np.asarray(vertices, np.float64)
    faces = np.asarray(faces, np.int64)
    if vertices.ndim != 2 or vertices.shape[1] != 3 or faces.ndim != 2 or faces.shape[1] != 3 \
            or not len(vertices) or not len(faces) or not np.all(np.isfinite(vertices)) or faces.min() < 0:
        raise Unsupported("not a mesh this writer formats")
    matrix, keep = fixed_decimals(vertices, DIGITS, _rows(len(vertices), 3))
    coordinates = matrix[keep].tobytes()
    stacked = np.column_stack((np.full(len(faces), 3, np.int64), faces))
    matrix, keep = integers(stacked, _rows(len(faces), 4))
    head = f"OFF\n{len(vertices)} {len(faces)} 0\n".encode()
    return head + coordinates + matrix[keep].tobytes()
