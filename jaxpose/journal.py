"""The state of a batch output folder across runs: an exclusive lock and an append-only journal.

``OUTDIR/.jaxpose/`` holds ``lock`` (held with ``flock`` for the whole run, so a second run on the
same folder is refused while the first is alive; the kernel releases it when a process dies, even
by SIGKILL) and ``journal.jsonl``, one JSON line per finished input, appended with a single
``write`` (a killed run leaves whole lines; a torn last line is ignored). The journal is what a
rerun consults to skip finished inputs; the transforms table is rebuilt from it.
"""
from __future__ import annotations

import json
import os
from pathlib import Path

from ._validate import InvalidInputError, JaxposeError
from .atomic import check_folder_writable, is_temporary

__all__ = ["STATE_FOLDER", "OutputFolder", "FolderBusyError"]

STATE_FOLDER = ".jaxpose"


class FolderBusyError(JaxposeError):
    """Another run holds the output folder's lock."""


class OutputFolder:
    """An output folder opened for one run: locked, with its journal. A context manager.

    Args:
      root: the output folder; created (with parents) when missing.
      force: accept an existing, non-empty folder that no jaxpose run made.

    Raises:
      FolderBusyError: another run holds the lock (message names its pid).
      InvalidInputError: the folder is not writable, or (without `force`) it holds files but no
        ``.jaxpose`` state, i.e. it was not made by jaxpose.

    Example::

        >>> with OutputFolder("normalized") as folder:
        ...     done = folder.records()            # {input: last record}
        ...     folder.append({"input": "/data/a.ply", "status": "ok"})
    """

    def __init__(self, root, force=False):
        self.root = Path(root)
        self.state = self.root / STATE_FOLDER
        self.force = force
        self._lock = None
        self._journal = None

    def __enter__(self):
        if self.root.exists() and not self.root.is_dir():
            raise InvalidInputError(f"output folder {self.root} is a file")
        if not self.root.exists():
            check_folder_writable(_existing_parent(self.root), what=f"output folder {self.root}: the parent")
            self.root.mkdir(parents=True, exist_ok=True)
        check_folder_writable(self.root, what="output")
        if not self.state.is_dir() and any(self.root.iterdir()) and not self.force:
            raise InvalidInputError(f"output folder {self.root} holds files that jaxpose did not write; "
                                    "use an empty or new folder (or --force / force=True to write into it)")
        self.state.mkdir(exist_ok=True)
        self._lock = _lock(self.state / "lock")
        try:
            self._journal = os.open(self.state / "journal.jsonl", os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o666)
        except BaseException:
            self._release()
            raise
        return self

    def __exit__(self, *exc):
        self._release()
        return False

    def _release(self):
        for fd in (self._journal, self._lock):
            if fd is not None:
                os.close(fd)  # closing the lock file releases the lock
        self._journal = self._lock = None

    def records(self) -> dict:
        """{input path: its last journal record} (dicts), torn or foreign lines skipped."""
        out = {}
        try:
            with open(self.state / "journal.jsonl", "rb") as handle:
                for line in handle:
                    try:
                        record = json.loads(line)
                    except ValueError:
                        continue  # a line torn by a crash
                    if isinstance(record, dict) and "input" in record:
                        out[record["input"]] = record
        except FileNotFoundError:
            pass
        return out

    def append(self, record: dict) -> None:
        """Append one record as one JSON line, in one ``write`` call."""
        line = (json.dumps(record, separators=(",", ":"), allow_nan=True) + "\n").encode("utf-8")
        written = os.write(self._journal, line)
        if written != len(line):  # a full disk: leave no half line to the next record
            raise OSError(f"{self.state / 'journal.jsonl'}: short write ({written} of {len(line)} bytes)")

    def remove_temporaries(self) -> int:
        """Remove the temporaries that killed runs left anywhere under the folder; returns how many."""
        removed = 0
        for folder, dirs, files in os.walk(self.root):
            for name in files:
                if is_temporary(name):
                    try:
                        os.unlink(os.path.join(folder, name))
                        removed += 1
                    except FileNotFoundError:
                        pass
        return removed


def _existing_parent(path):
    path = path.absolute()
    while not path.exists() and path != path.parent:
        path = path.parent
    return path


def _lock(path):
    """An exclusive, non-blocking lock on `path` (held while the returned descriptor is open)."""
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o666)
    try:
        _try_lock(fd)
    except BlockingIOError:
        try:
            holder = os.pread(fd, 64, 0).decode("ascii", "replace").strip() or "unknown"
        finally:
            os.close(fd)
        raise FolderBusyError(f"another jaxpose run (pid {holder}) is writing to {path.parent.parent}; "
                              "wait for it to finish or use another output folder") from None
    except BaseException:
        os.close(fd)
        raise
    os.ftruncate(fd, 0)
    os.pwrite(fd, f"{os.getpid()}\n".encode("ascii"), 0)
    return fd


def _try_lock(fd):
    import fcntl  # POSIX (Linux, macOS)

    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
