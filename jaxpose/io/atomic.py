"""Atomic file writes: a temporary name beside the target, fsync, then ``os.replace``.

A reader never sees a partial file: the target either keeps its old content or gets the whole new
one. The temporary is ``.NAME.<random>.tmp`` in the target's folder (same file system, so the
rename is atomic); it is removed when the write fails or is interrupted (``KeyboardInterrupt``,
``SystemExit``). Only a process killed outright (SIGKILL, power loss) can leave one behind:
:func:`remove_temporaries` clears those, and the batch runner calls it before writing again.
"""
from __future__ import annotations

import errno
import os
import secrets
from pathlib import Path

from ..errors import InvalidInputError, UsageError  # (not _validate: the command line imports this before NumPy)

__all__ = ["write_atomic", "written_path", "temporary_path", "is_temporary", "remove_temporaries", "check_folder_writable",
           "check_output_file", "check_creatable", "check_replaceable"]

_SUFFIX = ".tmp"


_NAME_MAX = 255  # bytes of one file name (Linux, macOS, Windows' NTFS in UTF-16 units)


def _stem(name) -> str:
    """The NAME part of `name`'s temporaries: `name` itself, or, where ``.NAME.<12 hex>.tmp``
    would pass :data:`_NAME_MAX` bytes (an output name of 238 bytes or more), its first bytes and
    ``~`` and 8 hex digits of its SHA-256 (one per name)."""
    raw = os.fsencode(name)
    if len(raw) + 18 <= _NAME_MAX:
        return name
    import hashlib

    return os.fsdecode(raw[:_NAME_MAX - 18 - 9]) + "~" + hashlib.sha256(raw).hexdigest()[:8]


def temporary_path(path) -> Path:
    """A fresh temporary name for `path`: ``.NAME.<12 hex digits>.tmp`` in the same folder (NAME
    shortened where the temporary's name would be too long for the file system; :func:`_stem`)."""
    path = Path(path)
    return path.with_name(f".{_stem(path.name)}.{secrets.token_hex(6)}{_SUFFIX}")


def is_temporary(name) -> bool:
    """Whether a file name is one of :func:`temporary_path`'s (``.NAME.<12 hex digits>.tmp``)."""
    name = str(name)
    if not (name.startswith(".") and name.endswith(_SUFFIX)):
        return False
    stem = name[1:-len(_SUFFIX)]
    target, _, token = stem.rpartition(".")
    return bool(target) and len(token) == 12 and all(c in "0123456789abcdef" for c in token)


def remove_temporaries(path) -> int:
    """Remove the temporaries of `path` that a killed writer left (``.NAME.<12 hex>.tmp``).

    Args:
      path: the target file (it need not exist, nor its folder: a file or a link to one where
        its folder would be holds none); only its own temporaries are touched.

    Returns:
      How many were removed.
    """
    path = written_path(path)  # (a link's: those beside its target)
    folder = path.parent if str(path.parent) else Path(".")
    prefix = f".{_stem(path.name)}."
    removed = 0
    try:
        names = os.listdir(folder)
    except OSError as exc:  # no folder there (a file, or a loop of links, where it is needed): none
        if exc.errno not in (errno.ENOENT, errno.ENOTDIR, errno.ELOOP):
            raise
        return 0
    for name in names:
        if name.startswith(prefix) and is_temporary(name) and name[len(prefix):-len(_SUFFIX)].count(".") == 0:
            try:
                os.unlink(folder / name)
                removed += 1
            except FileNotFoundError:
                pass
    return removed


def check_folder_writable(folder, what="output") -> Path:
    """Raise :class:`UsageError` (an InvalidInputError) unless `folder` is an existing folder we may create files in.

    Args:
      folder: the folder; what: how the message names it ("output", "table", ...).

    Returns:
      The folder as a :class:`Path`.
    """
    folder = Path(folder) if str(folder) else Path(".")
    if not folder.exists():
        raise UsageError(f"{what} folder {folder} does not exist")
    if not folder.is_dir():
        raise UsageError(f"{what} folder {folder} is not a folder")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise UsageError(f"{what} folder {folder} is not writable")
    return folder


def _not_a_file(path):
    """Why an existing `path` (its link followed) cannot be replaced by a written file: "a FIFO",
    "a character device" (a terminal), "a link to an open file descriptor" (``/dev/stdout``,
    ``/dev/fd/1``, ``/proc/self/fd/1``, whatever they point to), ...; None for a regular file or a
    missing one. Replacing it would put a file where the device, FIFO or socket was, or where the
    link was: ``--transform /dev/stdout --force`` as root replaced the system's /dev/stdout."""
    import stat

    if _fd_link(path):
        return "a link to an open file descriptor (a standard stream)"
    try:
        mode = os.stat(path).st_mode
    except OSError:
        return None
    if stat.S_ISREG(mode) or stat.S_ISDIR(mode):  # a folder: the callers' own refusals name it
        return None
    for test, kind in ((stat.S_ISFIFO, "a FIFO"), (stat.S_ISCHR, "a character device"),
                       (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket")):
        if test(mode):
            return kind
    return "not a regular file"


def _fd_link(path) -> bool:
    """Whether `path` is, or passes through links to, a link in ``/proc`` or ``/dev/fd`` (a
    process's file descriptors: ``/dev/stdout`` -> ``/proc/self/fd/1``)."""
    current = os.path.abspath(path)
    for _ in range(40):  # the kernel's own limit on links followed
        if current.startswith(("/proc/", "/dev/fd/")):
            return True
        if not os.path.islink(current):
            return False
        try:
            target = os.readlink(current)
        except OSError:
            return False
        current = os.path.normpath(os.path.join(os.path.dirname(current), target))
    return False


def check_replaceable(path, what=""):
    """Refuse (UsageError) a `path` a write cannot replace: a folder (or a link to one), not a regular
    file (:func:`_not_a_file`), a symbolic link that cannot be resolved (a loop), or one whose
    target's folder is missing or not writable (its file is written
    there, :func:`written_path`; that folder is never made). A missing `path`, a regular file or a
    link to one passes; `path`'s own folder is not checked (:func:`check_creatable` does).

    Args:
      path: the file a write would replace; what: how the message names it (``"--json"``), or "".
    """
    named = f"{what}{' ' if what else ''}{path}"
    if os.path.islink(path):
        try:
            os.stat(path)
        except FileNotFoundError:  # dangling: its target is made
            pass
        except OSError as exc:  # a loop of links: realpath stops somewhere in it, and the rename replaced that link
            raise UsageError(f"{named} is a symbolic link that cannot be resolved ({exc.strerror}); "
                             "name a regular file") from None
    if os.path.isdir(path):  # (also through a link)
        raise UsageError(f"{named} is a folder; name a file")
    kind = _not_a_file(path)
    if kind is not None:
        raise UsageError(f"{named} is {kind}, not a file: jaxpose writes whole files (a "
                         "temporary, then renamed over the name), which would replace it; name a regular file")
    target = written_path(path)
    if target != Path(path):
        check_folder_writable(target.parent, what=f"{named} (a link to {target}): the")


def write_atomic(path, data, force=False) -> Path:
    """Write bytes (or text, as UTF-8) to `path` via a temporary file and ``os.replace``.

    Args:
      path: the target file; its folder must exist and be writable.
      data: bytes or str.
      force: replace an existing `path` (its permission bits are kept); otherwise refuse it.
        A symbolic link is written through: the file it points to is replaced atomically (its
        temporary beside it), the link kept (:func:`written_path`).

    Returns:
      `path` as a :class:`Path`.

    Raises:
      InvalidInputError: `path` exists (without `force`), is not a regular file (a folder, a FIFO,
        a device such as ``/dev/stdout``, a link to one, a loop of links: even with `force`), or its folder is missing or
        not writable.
      OSError: the write itself failed (disk full, ...); nothing is left behind.
    """
    path = Path(path)
    check_replaceable(path)
    if path.exists() and not force:
        raise InvalidInputError(f"{path} exists (use force / --force to overwrite)")
    target = written_path(path)  # (a link's target folder: checked above)
    check_folder_writable(target.parent, what=f"{path}: the")
    if isinstance(data, str):
        data = data.encode("utf-8")
    old_mode = (target.stat().st_mode & 0o777) if target.exists() else None
    tmp = temporary_path(target)
    try:
        try:
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)  # the umask applies
        except FileExistsError:  # someone else's temporary of the same name: not ours to remove
            tmp = None
            raise
        with os.fdopen(fd, "wb") as handle:
            if old_mode is not None:
                os.chmod(handle.fileno(), old_mode)
            handle.write(data)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, target)
    except BaseException:  # errors, KeyboardInterrupt, SystemExit: never leave the temporary
        if tmp is not None:
            try:
                os.unlink(tmp)
            except FileNotFoundError:
                pass
        raise
    return path


def written_path(path) -> Path:
    """The file that :func:`write_atomic` replaces for `path`: `path` itself, or for a symbolic
    link the file it points to (its real path; a dangling link's target, made): written through,
    the link kept (the rename replaced the link with a file and left its target as it was)."""
    path = Path(path)
    return Path(os.path.realpath(path)) if os.path.islink(path) else path


def check_output_file(path, force=False, what="--json"):
    """Refuse, before any work, an output file that cannot be written: a folder, an existing file
    without ``force``, or a folder that cannot be made or written (raises UsageError, an InvalidInputError).
    A missing folder is made when the file is written. A FIFO or a device (``/dev/stdout``) is
    refused, ``force`` or not."""
    path = Path(path)
    if path.is_dir():
        raise UsageError(f"{what} {path} is a folder; name a file")
    check_replaceable(path, what)
    if path.exists() and not force:
        raise UsageError(f"{path} exists (use --force to overwrite)")
    check_creatable(path.parent, f"{what} {path}")


def check_creatable(folder, what):
    """Refuse (UsageError) a `folder` that a write cannot make or write in. It passes where it
    exists and is writable, or where its nearest existing parent (a symbolic link counted as
    there, as ``mkdir`` meets it) is a writable folder; a file there (``out/a`` a regular file
    where ``out/a/b/`` is needed) is ``"{what}: out/a is a file, not a folder"``, a symbolic link
    to one ``"{what}: out/a is a symbolic link to a file, not a folder"``, one to nothing (missing,
    or a loop of links) ``"{what}: out/a is a symbolic link to a missing folder (TARGET)"``, a
    folder not writable ``"{what}: the folder out/a is not writable"``."""
    folder = Path(folder) if str(folder) else Path(".")
    while not os.path.lexists(folder) and folder != folder.parent:
        folder = folder.parent
    if folder.is_symlink() and not folder.exists():
        raise UsageError(f"{what}: {folder} is a symbolic link to a missing folder ({os.readlink(folder)})")
    if not folder.is_dir():
        link = " a symbolic link to" if folder.is_symlink() else ""
        raise UsageError(f"{what}: {folder} is{link} a file, not a folder")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise UsageError(f"{what}: the folder {folder} is not writable")
