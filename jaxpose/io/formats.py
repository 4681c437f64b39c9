"""What a mesh file's bytes hold: the format its first bytes announce, and text in any encoding.

Plain functions of bytes (no trimesh): :mod:`jaxpose.mesh` uses them to name a file whose content
is another format than its suffix, to decode text formats itself (trimesh falls back to the
optional ``charset_normalizer`` for text that is not UTF-8), and to hand trimesh and the fast
readers text in the form they read as the file says (:func:`as_read`).
"""
from __future__ import annotations

import re

from .._validate import InvalidInputError

__all__ = ["TEXT_FORMATS", "sniff_format", "binary_stl", "binary_stl_mismatch", "as_text", "without_bom",
           "as_read"]

TEXT_FORMATS = ("obj", "off", "xyz")  # text formats: decoded here (UTF-8, else Latin-1), any encoding reads
_BOM = b"\xef\xbb\xbf"  # UTF-8's byte-order mark (Windows editors and .NET writers put it first)
_BOMS_16 = (b"\xff\xfe", b"\xfe\xff")  # UTF-16's, little- and big-endian (Windows PowerShell's text files)


def without_bom(data: bytes) -> bytes:
    """`data` without a leading UTF-8 byte-order mark (trimesh reads one as part of the first line:
    an OBJ lost its first vertex, every face then one vertex off; an XYZ's first number failed)."""
    return data[len(_BOM):] if data.startswith(_BOM) else data


def as_read(data: bytes, ext: str) -> bytes:
    """A text mesh file's bytes (after :func:`as_text`) in the form trimesh's loaders and the fast
    readers read as the file says: an OFF file without its ``#`` comments (trimesh repeats the
    lines before a comment that follows the first line end: the counts line read as the first
    vertex); an OBJ file with its tabs as spaces (trimesh's and the fast reader's keywords are
    ``v `` and ``f ``: a ``v\\t0 0 1`` line was dropped, every later vertex one number off) and
    without the ``#`` comments that end its data lines (``v 0 0 0 # a``: trimesh read the comment
    as values, "could not be read to its end due to unmatched data";
    :func:`jaxpose.io.readers.obj.without_comments`) and without the white space that starts its
    lines (``  v 0 0 0``: trimesh dropped the line; :func:`jaxpose.io.readers.obj.without_indent`);
    an XYZ file with its commas as spaces and its comments cut (:func:`_xyz`: trimesh counted the
    first line's columns before it took commas as spaces)."""
    if ext == "off":
        from .readers.off import without_comments

        return without_comments(data)
    if ext == "obj":
        from .readers.obj import without_comments, without_indent

        data = without_indent(without_comments(data))
        return data.replace(b"\t", b" ") if b"\t" in data else data
    if ext == "xyz":
        return _xyz(data)
    return data


_XYZ_COMMENT = re.compile(rb"(?m)^[ \t]*//[^\n]*|#[^\n]*")  # '#' to the line's end anywhere; '//' a whole line


def _xyz(data: bytes) -> bytes:
    """An XYZ file's bytes as trimesh's loader reads them right: ``#`` comments cut to the line's
    end wherever they start (``1 0 0 # c`` is a point), as an OFF's are, ``//`` lines (CloudCompare's
    header ``//X Y Z``) blanked, commas as spaces (trimesh counts the columns of
    the first line before it replaces them: every ``x,y,z`` file was "not enough columns").

    Raises:
      InvalidInputError: a line holding another number of values than the first (trimesh reads
        the values in rows of the first line's count: where the total divides, silently other points).
    """
    import numpy as np

    if b"#" in data or b"//" in data:
        data = _XYZ_COMMENT.sub(b"", data)
    if b"," in data:
        data = data.replace(b",", b" ")
    chars = np.frombuffer(data, np.uint8)
    space = (chars == 32) | ((chars >= 9) & (chars <= 13))  # C's isspace (as trimesh's split)
    start = ~space
    start[1:] &= space[:-1]
    ends = np.flatnonzero(chars == 10)
    counts = np.bincount(np.searchsorted(ends, np.flatnonzero(start)), minlength=len(ends) + 1)
    lines = np.flatnonzero(counts)
    if len(lines) > 1 and np.any(counts[lines] != counts[lines[0]]):
        line = int(lines[np.argmax(counts[lines] != counts[lines[0]])])
        raise InvalidInputError(f"cannot read XYZ file: line {line + 1} holds {int(counts[line])} values, line "
                                f"{int(lines[0]) + 1} (the first) {int(counts[lines[0]])}: a truncated or malformed file")
    return data


_OFF_HEADERS = (b"OFF", b"COFF", b"NOFF", b"CNOFF", b"STOFF", b"4OFF")


def sniff_format(data: bytes):
    """The format a file's first bytes announce, or None: ``ply`` (``ply`` magic), ``glb``
    (``glTF``), ``stl`` (binary: 84 + 50 n bytes for the n triangles of its header; ASCII:
    ``solid``), ``off`` (an OFF header); text after a UTF-8 byte-order mark too."""
    if data.startswith(b"ply"):
        return "ply"
    if data.startswith(b"glTF"):
        return "glb"
    if binary_stl(data):
        return "stl"
    text = without_bom(data)
    if text.startswith(b"ply"):
        return "ply"
    first = text.lstrip()[:16].split()
    if first and first[0].lower() == b"solid":
        return "stl"
    if first and first[0] in _OFF_HEADERS:
        return "off"
    return None


def binary_stl(data: bytes):
    """A binary STL: an 80-byte header, a triangle count n, then 50 bytes per triangle."""
    return len(data) > 84 and 84 + 50 * int.from_bytes(data[80:84], "little") == len(data)


def binary_stl_mismatch(data: bytes):
    """Why `data`, a binary STL (not text: it holds NUL bytes, as an ASCII STL never does), is not
    whole, or None: fewer bytes than its 84-byte header, fewer or more than the 84 + 50 n its count
    of n triangles takes (a truncated copy, a download cut short; bytes after the last triangle)."""
    if b"\x00" not in data or binary_stl(data):
        return None
    if len(data) < 84:
        return f"a truncated binary STL: {len(data)} bytes, fewer than its 84-byte header"
    count = int.from_bytes(data[80:84], "little")
    expected = 84 + 50 * count
    if len(data) == expected:
        return None  # whole, without triangles
    if len(data) < expected:
        return (f"a truncated binary STL: its header counts {count} triangles ({expected} bytes), the file has "
                f"{len(data)} bytes")
    return (f"a binary STL whose size does not match its header: {count} triangles take {expected} bytes, the file "
            f"has {len(data)} ({len(data) - expected} bytes after the last triangle, or a wrong count)")


def as_text(data: bytes, name: str, ext: str) -> bytes:
    """A text file's bytes as UTF-8, without a byte-order mark.

    Args:
      data: the file's bytes; name: how messages call the file; ext: its format (for messages).

    Returns:
      ``data`` when it is UTF-8 (a leading byte-order mark dropped); UTF-16 text that starts with
      its byte-order mark re-encoded as UTF-8; else its Latin-1 reading re-encoded as UTF-8 (every
      byte is a character in Latin-1, and mesh data itself is ASCII: only comments and names change).

    Raises:
      InvalidInputError: NUL bytes (binary data, not text), UTF-16 that does not decode.
    """
    data = without_bom(data)
    if data.startswith(_BOMS_16):
        try:
            return data.decode("utf-16").encode("utf-8")
        except UnicodeDecodeError:
            raise InvalidInputError(f"{name}: not text: it starts as UTF-16 but does not decode as UTF-16") from None
    if b"\x00" in data:
        raise InvalidInputError(f"{name}: binary data, not a text {ext.upper()} file (does the extension match the content?)")
    try:
        data.decode("utf-8")
        return data
    except UnicodeDecodeError:
        return data.decode("latin-1").encode("utf-8")
