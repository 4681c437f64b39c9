"""What the format readers share: the result type, the refusal, number tokens and triangulation.

Every reader of :mod:`jaxpose.io.readers` returns :class:`Loaded` (the arrays and the other
``trimesh.Trimesh`` arguments trimesh's loader gives) or raises :class:`Unsupported` (the caller
reads the file with trimesh). The helpers parse whitespace-separated number tokens as Python's
``float`` does and split polygons into triangles as trimesh does.
"""
from __future__ import annotations

import functools
import re
from operator import itemgetter
from typing import NamedTuple

import numpy as np

__all__ = ["Loaded", "Unsupported", "file_bytes"]


def file_bytes(reader):
    """``reader(data)`` that refuses, at its boundary, ``data`` that is not a file's bytes (bytes,
    bytearray or memoryview; the latter two read as bytes): a TypeError naming what it got and what
    to pass (a str was an AttributeError or TypeError from deep inside)."""
    @functools.wraps(reader)
    def checked(data, *args, **kwargs):
        if not isinstance(data, bytes):
            if not isinstance(data, (bytearray, memoryview)):
                hint = (": pass the file's bytes, Path(path).read_bytes() for a path or text.encode() for its text"
                        if isinstance(data, str) else "")
                raise TypeError(f"{reader.__name__} reads a file's bytes (bytes, bytearray or memoryview), got "
                                f"{type(data).__name__}{hint}")
            data = bytes(data)
        return reader(data, *args, **kwargs)

    return checked


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


_SEPARATOR = ";"  # never part of a number: marks line ends among the tokens
_SIGNED = re.compile(rb"-?[0-9]+(?: -?[0-9]+)*")


def _text(data: bytes) -> str:
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        raise Unsupported("not UTF-8 text") from None


_NOT_C_SPACE = "\x1c\x1d\x1e\x1f"  # white space to str.split, not to C's isspace


def _tokens(lines, c_numbers=False):
    """Tokens of lines: (flat list of str, per-line counts (n,) int64).

    c_numbers: lines that trimesh parses with ``numpy.fromstring`` (C's strtod and isspace: ASCII
    digits, ASCII white space); text that ``str.split`` and ``float`` read and it does not (other
    digits such as ``\u0663``, U+00A0 and the other Unicode spaces, ``\x1c``-``\x1f``) raises
    :class:`Unsupported` (trimesh refuses such a file).
    """
    joined = f" {_SEPARATOR} ".join(lines)
    if c_numbers and (not joined.isascii() or any(c in joined for c in _NOT_C_SPACE)):
        raise Unsupported("text trimesh's numpy.fromstring does not read as numbers")
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




def _take(tokens, index) -> list:
    """tokens[index] for an int array (a list)."""
    if len(index) == 0:
        return []
    if len(index) == 1:
        return [tokens[int(index[0])]]
    return list(itemgetter(*index.tolist())(tokens))


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
