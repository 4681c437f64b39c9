"""Remote paths for the batch command: inputs, OUTDIR and tables as fsspec URLs.

``s3://bucket/scans/``, ``gs://...``, ``memory://...`` and every other protocol fsspec knows name
files on that file system (``pip install 'jaxpose[remote]'`` installs fsspec; a store's own
package, such as s3fs or gcsfs, comes from fsspec's usual extras). ``file://`` URLs are plain
local paths (no fsspec needed) and keep every local guarantee.

:func:`location` turns what a user gives into a local :class:`pathlib.Path` or a
:class:`RemotePath`, which has the few methods of ``Path`` the batch code uses (``/``, ``name``,
``suffix``, ``parent``, ``with_suffix``, ``relative_to``, ``exists``, ``is_dir``, ``is_file``,
``mkdir``, ``read_bytes``) plus :meth:`RemotePath.write_bytes`: one PUT, which object stores (S3,
GCS, Azure) make atomic: the object appears whole or not at all.
"""
from __future__ import annotations

import os
import posixpath
import re
from pathlib import Path, PurePosixPath
from urllib.parse import unquote, urlparse

from .._validate import InvalidInputError

__all__ = ["RemotePath", "location", "is_url", "filesystem", "modified_ns"]

_URL = re.compile(r"^[A-Za-z][A-Za-z0-9+.-]*://")


def is_url(path) -> bool:
    """Whether `path` is a URL (``scheme://...``), ``file://`` included."""
    return isinstance(path, str) and bool(_URL.match(path))


def filesystem(url):
    """(fsspec file system, its path) of a URL.

    Raises:
      InvalidInputError: fsspec is not installed (naming the extra), or it does not know the
        protocol (naming the package that brings it, as fsspec does).
    """
    try:
        import fsspec
    except ImportError:
        raise InvalidInputError(f"{url}: remote paths need fsspec: pip install 'jaxpose[remote]'") from None
    try:
        return fsspec.core.url_to_fs(url)
    except (ImportError, ValueError) as exc:  # an unknown protocol, or its package missing
        raise InvalidInputError(f"{url}: {' '.join(str(exc).split())}") from None


def location(path):
    """A local absolute :class:`~pathlib.Path` (a ``file://`` URL too) or a :class:`RemotePath`."""
    if isinstance(path, RemotePath):
        return path
    if isinstance(path, os.PathLike):
        path = os.fspath(path)
    if is_url(path):
        if path.lower().startswith("file://"):
            return Path(os.path.abspath(unquote(urlparse(path).path)))
        return RemotePath(*filesystem(path))
    return Path(os.path.abspath(path))


class RemotePath:
    """A file or folder on an fsspec file system (the part of ``pathlib.Path`` batch runs use).

    Args:
      fs: the fsspec file system; path: the path on it (as fsspec strips it from the URL).
    """

    __slots__ = ("fs", "path")

    def __init__(self, fs, path):
        self.fs = fs
        self.path = path.rstrip("/") or "/"

    def __str__(self):
        return self.fs.unstrip_protocol(self.path)

    def __repr__(self):
        return f"RemotePath({str(self)!r})"

    def __eq__(self, other):
        return isinstance(other, RemotePath) and str(self) == str(other)

    def __hash__(self):
        return hash(str(self))

    def __truediv__(self, other):
        return RemotePath(self.fs, posixpath.join(self.path, PurePosixPath(other).as_posix()))

    @property
    def name(self) -> str:
        return posixpath.basename(self.path)

    @property
    def suffix(self) -> str:
        return posixpath.splitext(self.name)[1]

    @property
    def parent(self) -> "RemotePath":
        return RemotePath(self.fs, posixpath.dirname(self.path))

    @property
    def parts(self) -> tuple:
        return PurePosixPath(self.path).parts

    def with_suffix(self, suffix) -> "RemotePath":
        return RemotePath(self.fs, posixpath.splitext(self.path)[0] + suffix)

    def relative_to(self, root) -> PurePosixPath:
        """The path below `root` (a RemotePath of the same file system)."""
        if not (isinstance(root, RemotePath) and self.fs.protocol == root.fs.protocol
                and (self.path == root.path or self.path.startswith(root.path.rstrip("/") + "/"))):
            raise ValueError(f"{self} is not below {root}")
        return PurePosixPath(posixpath.relpath(self.path, root.path))

    def exists(self) -> bool:
        return self.fs.exists(self.path)

    def is_dir(self) -> bool:
        return self.fs.isdir(self.path)

    def is_file(self) -> bool:
        return self.fs.isfile(self.path)

    def mkdir(self, parents=False, exist_ok=False):
        self.fs.makedirs(self.path, exist_ok=True)  # nothing on object stores: folders are key prefixes

    def read_bytes(self) -> bytes:
        return self.fs.cat_file(self.path)

    def write_bytes(self, data) -> "RemotePath":
        """Write the whole object in one PUT (atomic on object stores)."""
        self.fs.pipe_file(self.path, bytes(data))
        return self

    def info(self) -> dict:
        return self.fs.info(self.path)


def modified_ns(info) -> int | None:
    """A file's modification time (ns since the epoch) from an fsspec ``info`` dict, or None
    where the store gives none (keys differ: ``mtime``, ``LastModified``, ``updated``, ``created``)."""
    import datetime

    for key in ("mtime", "LastModified", "last_modified", "updated", "modified", "created"):
        value = info.get(key)
        if value is None:
            continue
        if isinstance(value, (int, float)):
            return int(round(value * 1e9))
        if isinstance(value, str):
            try:
                value = datetime.datetime.fromisoformat(value.replace("Z", "+00:00"))
            except ValueError:
                continue
        if isinstance(value, datetime.datetime):
            if value.tzinfo is None:
                value = value.replace(tzinfo=datetime.timezone.utc)
            return int(value.timestamp() * 10**6) * 1000
    return None
