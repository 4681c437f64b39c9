"""OFF (text): ``OFF`` / ``COFF`` headers, ``#`` comments, blank lines, any line endings, extra
values on a line (colors), triangles, quads and polygons; the common layout parsed on the bytes."""
from __future__ import annotations

import re

import numpy as np

from ...errors import InvalidInputError
from .base import (Loaded, Unsupported, file_bytes, _checked, _floats, _in_range, _ints, _runs, _starts, _take, _text,
                   _tokens, _triangulate)

__all__ = ["read_off", "without_comments"]


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


_OFF = re.compile("(COFF|OFF)")


def _comment_strip(text):
    """Each line cut at its first ``#`` (a comment runs to the end of its line; every line kept), as
    ``trimesh.util.comment_strip`` does where the text before the first ``#`` holds no line end
    (a file that starts with a comment, or whose first comment is on its first line). Where it
    does, trimesh repeats that text's lines after the first (``OFF\\n4 4 0\\n# vertices\\n...``:
    ``4 4 0`` a second time, read as the first vertex, every vertex one line late, the last face
    lost, without a word); here the file is read as it says."""
    return "\n".join(line.split("#", 1)[0] for line in text.split("\n"))


def without_comments(data: bytes) -> bytes:
    """An OFF file's bytes with every ``#`` comment cut (to the end of its line, the line end
    kept), for a reader that would garble them (trimesh: :func:`_comment_strip`); `data` itself
    when it holds none."""
    if b"#" not in data:
        return data
    return re.sub(rb"#[^\r\n]*", b"", data)


def _file_line(text, start, k):
    """The file's line number (from 1; a line ends in \\n, \\r\\n or a lone \\r, as an editor counts
    them) of the `k`-th (from 0) of the lines after ``text[start]`` that hold a value, as
    :func:`read_off` counts those (``str.splitlines``, blank ones left out). Only for a message."""
    at = start
    for piece in text[start:].splitlines(keepends=True):
        if piece.strip():
            if k == 0:
                break
            k -= 1
        at += len(piece)
    return len(re.findall(r"\r\n|\r|\n", text[:at])) + 1


@file_bytes
def read_off(data: bytes) -> Loaded:
    """An OFF file's mesh, as ``trimesh.load(..., file_type="off", process=False)``.

    The common layout (:func:`_off_plain`: no comments, one space between values, triangles) is
    parsed on the bytes in a few C-level passes; anything else line by line.

    Raises:
      Unsupported: anything this reader does not reproduce exactly (read it with trimesh).
      InvalidInputError: fewer vertex or face lines than the counts line says, or a face line
        with fewer indices than its count (trimesh drops or shortens those without a word); a
        counts line that trimesh fails on (fewer than 2 values, one that is not a whole number,
        ``3 x 0``, one beyond int64, a negative count); a vertex line of fewer than 3 values.
    """
    plain = _off_plain(data)
    if plain is not None:
        return plain
    text = _text(data)
    if "#" in text:
        text = _comment_strip(text)  # (the file's lines kept: their numbers are named)
    found = _OFF.search(text)
    if found is None or not text[found.end():].strip():  # (nothing after it: the counts line is missing)
        raise Unsupported("no OFF header" if found is None else "no counts")
    lines = list(filter(None, map(str.strip, text[found.end():].splitlines())))  # each line after it that holds a value
    header = lines[0].split()
    _check_counts(lines[0], header)
    if not all(t.isascii() and t.isdigit() for t in header[:2]) \
            or not all(t.isascii() and t.isdigit() and len(t) <= 18 for t in header[2:]):
        raise Unsupported("an unusual count line")  # ("+12": trimesh reads every count as an int64)
    nv, nf = int(header[0]), int(header[1])
    block = lines[1:nv + 1]
    if nv == 0:
        raise Unsupported("no vertices")
    if len(block) < nv:
        raise InvalidInputError(f"cannot read OFF file: truncated, {len(block)} vertex lines of the {nv} its "
                                f"counts line says")
    tokens, counts = _tokens(block)
    if np.any(counts < 3):  # (trimesh fails: "setting an array element with a sequence", or a reshape)
        line = int(np.argmax(counts < 3))
        raise InvalidInputError(f"cannot read OFF file: vertex {line + 1} (line {_file_line(text, found.end(), 1 + line)} of the file) "
                                f"holds {int(counts[line])} value{'s' if counts[line] != 1 else ''}, fewer than its 3 "
                                f"coordinates ({block[line]!r}): a truncated or malformed file")
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
        raise InvalidInputError(f"cannot read OFF file: face {line + 1} (line {_file_line(text, found.end(), 1 + nv + line)} of the "
                                f"file) holds fewer indices than its count ({block[line]!r}): a truncated or "
                                "malformed file")
    if np.any(sizes < 3):
        raise Unsupported("a face with fewer than 3 corners")
    if np.all(counts == counts[0]) and np.all(sizes + 1 == counts):  # "3 a b c" lines, nothing more
        del tokens[::int(counts[0])]
        flat = _ints(tokens)
    else:
        flat = _ints(_take(tokens, _runs(starts + 1, sizes)))
    return _checked(vertices.reshape(-1, 3), _triangulate(flat, sizes))


_INT64_MAX = 2**63 - 1


def _check_counts(line, header):
    """Refuse an OFF counts line that trimesh's reader fails on (it reads every value as an int64):
    fewer than two values, a value that is not a whole number (``3 x 0``, ``12.0``), one beyond
    int64 (``99999999999999999999``), and a negative count (trimesh reads lines before the end as
    vertices, or fails)."""
    def whole(token):
        try:
            return int(token)
        except ValueError:
            return None

    values = [whole(t) for t in header]
    expected = "'vertices faces [edges]' as whole numbers"
    if len(header) < 2 or None in values:
        raise InvalidInputError(f"cannot read OFF file: its counts line {line!r} is not {expected}: a malformed file")
    if any(abs(v) > _INT64_MAX for v in values):
        raise InvalidInputError(f"cannot read OFF file: its counts line {line!r} holds a count beyond any file's "
                                f"(more than {_INT64_MAX}): a malformed file")
    if any(v < 0 for v in values[:2]):
        raise InvalidInputError(f"cannot read OFF file: its counts line {line!r} holds a negative count: a "
                                "malformed file")


_OFF_HEAD = re.compile(rb"[ \t\n]*C?OFF[ \t]*\n[ \t]*([0-9]+)[ \t]+([0-9]+)(?:[ \t]+[0-9]{1,18})?[ \t]*\n")
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
