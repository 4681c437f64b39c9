"""The state of a batch output folder across runs: an exclusive lock and an append-only journal.

``OUTDIR/.jaxpose/`` holds ``lock`` (held with ``flock`` for the whole run, so a second run on the
same folder is refused while the first is alive; the kernel releases it when a process dies, even
by SIGKILL) and ``journal.jsonl``, one JSON line per finished input, appended with a single
``write`` (a killed run leaves whole lines; a torn last line is ignored). The journal is what a
rerun consults to skip finished inputs; the transforms table is rebuilt from it.

Records name inputs and outputs by absolute path, and each names the folder it was written in
(``outdir``, its real path). A folder found elsewhere (moved, with its inputs or alone) is read with
each output at the same path relative to the folder where it is now (:func:`rebase`); inputs stay
as recorded, and which of this run's inputs an output belongs to is the batch's question (it knows
this run's inputs: :func:`jaxpose.batch.batch.run_batch`; :func:`moved_input` names where a
record's input would be had it moved with the folder). Records of versions before ``outdir`` are
read so too, the folder they were written in told by where their outputs are found now
(:func:`former_folder`).

A shard's run (``--shard I/N``, machines sharing one OUTDIR) has a journal and a lock of its own
(``journal.shard-I-of-N.jsonl``, ``lock.shard-I-of-N``) and holds ``lock`` shared: shards run side
by side, a second run of one shard is refused, and so is an unsharded run while shards run.

An output folder on a remote file system (:mod:`jaxpose.io.remote`) is a :class:`RemoteOutputFolder`:
object stores have neither locks nor appends, so it has no lock (two runs into one remote folder
are not refused: give each its own folder, or its own shard) and its journal is one object per
(input, output) pair under ``.jaxpose/records/``, each written whole in one PUT after the output.
"""
from __future__ import annotations

import hashlib
import json
import os
import time
from pathlib import Path

from .._validate import JaxposeError
from ..errors import UsageError
from ..io.atomic import check_folder_writable, is_temporary

__all__ = ["STATE_FOLDER", "OutputFolder", "RemoteOutputFolder", "open_output_folder", "FolderBusyError",
           "check_no_foreign", "shard_name", "rebase", "moved_input", "former_folder"]

STATE_FOLDER = ".jaxpose"

BROWSER_FILES = frozenset({".DS_Store", "Thumbs.db", "desktop.ini"})
"""What file browsers leave in a folder they show (macOS Finder, Windows Explorer): a new output
folder holding only these is taken as empty (a folder made, opened in Finder, then given as OUTDIR
was refused as holding "files that jaxpose did not write")."""


def check_no_foreign(root, names):
    """Refuse an output folder ``root`` (new to jaxpose: no records) holding files of ``names``
    beyond :data:`BROWSER_FILES`: UsageError naming the first three."""
    foreign = sorted(name for name in names if name not in BROWSER_FILES)
    if foreign:
        listed = ", ".join(foreign[:3]) + (f" and {len(foreign) - 3} more" if len(foreign) > 3 else "")
        raise UsageError(f"output folder {root} holds files that jaxpose did not write ({listed}); "
                         "use an empty or new folder (or --force / force=True to write into it)")


class FolderBusyError(JaxposeError):
    """Another run holds the output folder's lock."""


def shard_name(shard) -> str:
    """``"shard-I-of-N"`` for shard (I, N), ``""`` for None: the suffix of a shard's files."""
    return "" if shard is None else f"shard-{shard[0]}-of-{shard[1]}"


class OutputFolder:
    """An output folder opened for one run: locked, with its journal. A context manager.

    Args:
      root: the output folder; created (with parents) when missing.
      force: accept an existing, non-empty folder that no jaxpose run made.
      shard: (index, count) for one shard's run (its own journal and lock), or None.

    Raises:
      FolderBusyError: another run holds the lock (message names its pid).
      UsageError (an InvalidInputError): the folder is not writable, or (without `force`) it holds files but no
        ``.jaxpose`` state, i.e. it was not made by jaxpose (named in the message; what file browsers
        leave, :data:`BROWSER_FILES`, does not count).

    Example::

        with OutputFolder("normalized") as folder:
            done = folder.records()            # {input: last record}
            folder.append({"input": "/data/a.ply", "status": "ok"})
    """

    def __init__(self, root, force=False, shard=None):
        self.root = Path(root)
        self.state = self.root / STATE_FOLDER
        self.force = force
        self.shard = shard
        suffix = f".{shard_name(shard)}" if shard is not None else ""
        self.journal = self.state / f"journal{suffix}.jsonl"
        self._shard_lock = self.state / f"lock{suffix}" if shard is not None else None
        self._locks = []  # (descriptor, the bytes before this run wrote its pid, or None)
        self._journal = None
        self._made = []  # what opening the folder created, in that order (folders, lock files, journal)
        self._outdir = None  # its real path, once a record is written
        self.discarded = False

    def __enter__(self):
        if self.root.exists() and not self.root.is_dir():
            raise UsageError(f"output folder {self.root} is a file")
        if not self.root.exists():
            parent = _existing_parent(self.root)
            check_folder_writable(parent, what=f"output folder {self.root}: the parent")
            missing = [self.root.absolute()]
            while missing[-1].parent != parent:
                missing.append(missing[-1].parent)
            self.root.mkdir(parents=True, exist_ok=True)
            self._made += reversed(missing)  # outermost first
        check_folder_writable(self.root, what="output")
        if not self.state.is_dir() and not self.force:
            check_no_foreign(self.root, (p.name for p in self.root.iterdir()))
        self._made += [p for p in (self.state, self.state / "lock", self._shard_lock, self.journal)
                       if p is not None and not os.path.lexists(p)]
        self.state.mkdir(exist_ok=True)
        try:
            self._locks.append(_lock(self.state / "lock", shared=self.shard is not None))
            if self._shard_lock is not None:
                self._locks.append(_lock(self._shard_lock))
            self._journal = os.open(self.journal, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o666)
        except BaseException:
            try:
                self._restore_pids()
            finally:
                self._release()
            raise
        return self

    def __exit__(self, *exc):
        try:
            if self.discarded:
                self._restore_pids()
        finally:
            self._release()
        if self.discarded:
            for path in reversed(self._made):  # the journal and lock files, then the folders, inner first
                try:
                    path.rmdir() if path.is_dir() else path.unlink()
                except OSError:  # a folder that holds something else (made meanwhile): kept
                    pass
        return False

    def discard(self) -> None:
        """On leaving, remove what opening the folder created (the folder itself, with the parents it
        needed, ``.jaxpose/``, the lock and journal files) and write back the lock files' pid lines
        it replaced: for a run that recorded nothing, so that a run that could not start leaves the
        folder as it found it."""
        self.discarded = True

    def _restore_pids(self):
        """The lock files' pid lines as they were before this run (while it still holds the locks);
        where the file cannot be written (a full disk), it keeps this run's pid: the error that
        ended the run is the one to report, and the locks are released all the same."""
        for fd, before in self._locks:
            if before is not None:
                try:
                    _rewrite(fd, before)
                except OSError:
                    pass

    def _release(self):
        for fd in (self._journal, *(fd for fd, _ in self._locks)):
            if fd is not None:
                os.close(fd)  # closing a lock file releases its lock
        self._journal, self._locks = None, []

    def records(self) -> dict:
        """{input path: its last journal record} (dicts), ordered by those records (latest last)."""
        return _latest_by_input(self.entries())

    def entries(self) -> list:
        """The last record of each (input, output) pair (a failed one has output ""), in the order
        they were written (latest last); torn or foreign lines skipped. Records written where the
        folder was before it moved have their outputs where they are now (:func:`rebase`)."""
        return _read_journal(self.journal, self.where())

    def other_entries(self) -> list:
        """:meth:`entries` of the folder's other journals (the shards' beside the whole run's, or
        the whole run's beside a shard's), one list after the other."""
        return [record for path in sorted(self.state.glob("journal*.jsonl")) if path != self.journal
                for record in _read_journal(path, self.where())]

    def where(self) -> str:
        """The folder's real path now (what each record's ``outdir`` holds)."""
        return os.path.realpath(self.root)

    def append(self, record: dict) -> None:
        """Append one record as one JSON line, in one ``write`` call, with the folder's real path
        (``outdir``: where a later run finds it moved, :func:`rebase`)."""
        if self._outdir is None:
            self._outdir = self.where()
        record = {**record, "outdir": self._outdir}
        line = (json.dumps(record, separators=(",", ":"), allow_nan=True) + "\n").encode("utf-8")
        written = os.write(self._journal, line)
        if written != len(line):  # a full disk: leave no half line to the next record
            raise OSError(f"{self.journal}: short write ({written} of {len(line)} bytes)")

    def remove_temporaries(self, targets=None, everywhere=None) -> int:
        """Remove the temporaries that killed runs left; returns how many.

        Args:
          targets: the run's outputs: each one's own temporaries, beside it or, for a symbolic
            link, beside its target (:func:`jaxpose.io.atomic.remove_temporaries`); None: none.
          everywhere: also every temporary under the folder (this run holds it alone; a shard's
            does not: other shards may be writing theirs); `targets` are then searched only where
            their temporaries lie outside it (a link's target elsewhere, a linked subfolder).
            None (the default): ``targets is None``, so that ``remove_temporaries()`` removes every
            temporary under the folder and ``remove_temporaries(outputs)`` only those outputs'.
        """
        from ..io.atomic import remove_temporaries

        if everywhere is None:
            everywhere = targets is None
        targets = () if targets is None else targets
        removed = 0
        if everywhere:
            for folder, dirs, files in os.walk(self.root):
                for name in files:
                    if is_temporary(name):
                        try:
                            os.unlink(os.path.join(folder, name))
                            removed += 1
                        except FileNotFoundError:
                            pass
            root, parents = os.path.join(os.path.realpath(self.root), ""), {}

            def within(target):  # where its temporaries lie: beside it, or beside a link's target
                if os.path.islink(target):
                    return os.path.join(os.path.dirname(os.path.realpath(target)), "").startswith(root)
                parent = os.path.dirname(target)  # (one realpath a folder)
                if parent not in parents:
                    parents[parent] = os.path.join(os.path.realpath(parent), "").startswith(root)
                return parents[parent]

            targets = [t for t in targets if not within(t)]
        return removed + sum(remove_temporaries(t) for t in targets)


    def exists(self, path) -> bool:
        """Whether an output (a path in a record) is there."""
        return os.path.exists(path)


def open_output_folder(root, force=False, shard=None):
    """:class:`OutputFolder` for a local folder, :class:`RemoteOutputFolder` for a remote one."""
    from ..io.remote import RemotePath

    kind = RemoteOutputFolder if isinstance(root, RemotePath) else OutputFolder
    return kind(root, force=force, shard=shard)


class RemoteOutputFolder:
    """An output folder on a remote file system, opened for one run (a context manager), with the
    interface of :class:`OutputFolder`: no lock; the journal is one JSON object per (input,
    output) pair (``.jaxpose/records[.shard-I-of-N]/<sha256 of input NUL output>.json``), replaced
    whole.

    Args:
      root: a :class:`jaxpose.io.remote.RemotePath`; force, shard: as :class:`OutputFolder`'s.

    Raises:
      UsageError (an InvalidInputError): the folder is a file, or (without `force`) holds files but no
        ``.jaxpose`` state.
    """

    def __init__(self, root, force=False, shard=None):
        self.root = root
        self.state = root / STATE_FOLDER
        self.force = force
        self.shard = shard
        self.journal = self.state / (f"records.{shard_name(shard)}" if shard is not None else "records")
        self._made = False  # whether opening the folder created it
        self.discarded = False

    def __enter__(self):
        fs = self.root.fs
        if self.root.is_file():
            raise UsageError(f"output folder {self.root} is a file")
        exists = self.root.exists()
        if not self.force and not self.state.exists() and exists:  # (it refused a folder holding only .DS_Store)
            check_no_foreign(self.root, (str(p).rstrip("/").rpartition("/")[2] for p in fs.ls(self.root.path, detail=False)))
        self.root.mkdir(parents=True, exist_ok=True)
        self._made = not exists
        return self

    def __exit__(self, *exc):
        if self.discarded and self._made:
            try:
                self.root.fs.rmdir(self.root.path)  # an empty folder (nothing at all on object stores)
            except Exception:  # fsspec's file systems raise their own errors; one that holds something stays
                pass
        return False

    def discard(self) -> None:
        """On leaving, remove the folder if opening it created it (:meth:`OutputFolder.discard`)."""
        self.discarded = True

    def records(self) -> dict:
        """{input path: its last record}, ordered by those records (latest last)."""
        return _latest_by_input(self.entries())

    def entries(self) -> list:
        """The last record of each (input, output) pair, in the order they were written."""
        return self._read(self.journal)

    def other_entries(self) -> list:
        """:meth:`entries` of the folder's other record folders (shards' or the whole run's)."""
        try:
            folders = [p for p in self.root.fs.ls(self.state.path, detail=False)
                       if p.rstrip("/").rsplit("/", 1)[-1].startswith("records")]
        except FileNotFoundError:
            return []
        own = self.journal.path.rstrip("/")
        return [record for folder in sorted(folders) if folder.rstrip("/") != own
                for record in self._read(self.state / folder.rstrip("/").rsplit("/", 1)[-1])]

    def _read(self, journal):
        fs = self.root.fs
        try:
            names = [n for n in fs.find(journal.path) if n.endswith(".json")]
        except FileNotFoundError:
            return []
        found = []
        for blob in (fs.cat(names).values() if names else ()):
            try:
                record = json.loads(blob)
            except (ValueError, TypeError):
                continue
            if isinstance(record, dict) and "input" in record:
                found.append(record)
        found.sort(key=lambda r: r.get("written_ns", 0))
        return found

    def append(self, record: dict) -> None:
        """Write the record of an (input, output) pair (replacing its earlier one) in one PUT."""
        record = {**record, "written_ns": time.time_ns()}
        pair = os.fsencode(record["input"]) + b"\0" + os.fsencode(record.get("output") or "")
        name = hashlib.sha256(pair).hexdigest() + ".json"
        line = json.dumps(record, separators=(",", ":"), allow_nan=True).encode("utf-8")
        (self.journal / name).write_bytes(line)

    def remove_temporaries(self, targets=None, everywhere=None) -> int:
        """Nothing to remove: remote outputs are written in one PUT, without temporaries."""
        return 0

    def exists(self, path) -> bool:
        from ..io.remote import location

        return location(path).exists()


def _read_journal(path, outdir=None):
    """The last record of each (input, output) pair of the journal `path`, in the order written;
    with `outdir` (the folder's real path now), read as written there (:func:`rebase`). Records are
    kept one per pair as they are read (memory in proportion to the pairs, not the lines), then
    rebased, then one per pair again (records written in two places may name one output)."""
    out = {}
    try:
        with open(path, "rb") as handle:
            for line in handle:
                try:
                    record = json.loads(line)
                except ValueError:
                    continue  # a line torn by a crash
                if isinstance(record, dict) and "input" in record:
                    key = (record["input"], record.get("output") or "")
                    out.pop(key, None)
                    out[key] = record
    except FileNotFoundError:
        pass
    if outdir is None:
        return list(out.values())
    records, out = rebase(list(out.values()), outdir), {}
    for record in records:
        key = (record["input"], record.get("output") or "")
        out.pop(key, None)
        out[key] = record
    return list(out.values())


def rebase(records, outdir) -> list:
    """Journal records as if written in the output folder `outdir` (its real path now), where
    they were written elsewhere (the folder moved, with its inputs or alone).

    A record's folder is its ``outdir``; for one without (an earlier version's), the folder that
    the records without one were written in (:func:`former_folder`), then set as its ``outdir``.
    Where that is not `outdir`, its ``output`` is the same path relative to `outdir` (a URL as it
    is). Its ``input`` stays as recorded: whether an output belongs to an input of a run is told by
    that run, which knows its inputs (the recorded one, or the one at :func:`moved_input`, with the
    record's size and modification time).

    Args:
      records: the records (dicts), in the order written; outdir: the folder's real path.

    Returns:
      The records, each moved one a new dict (the others as they are).
    """
    from ..io.remote import is_url

    outdir = str(outdir)
    legacy = [r["output"] for r in records if "outdir" not in r and r.get("output")]
    guess = former_folder(legacy, outdir) if legacy else None
    out = []
    for record in records:
        was = record.get("outdir", guess)
        if not was or was == outdir:
            out.append(record)
            continue
        changed = {"outdir": was}
        output = record.get("output")
        if output and not is_url(output) and _inside(output, was):
            changed["output"] = os.path.join(outdir, os.path.relpath(output, was))
        out.append({**record, **changed})
    return out


def moved_input(record, outdir):
    """Where a record's input would be had it moved with the output folder: the same path
    relative to `outdir` (the folder's real path now) as to the folder the record was written in
    (its ``outdir``, after :func:`rebase`), ``mv data data2`` moving ``data/scans/a.ply`` with
    ``data/out`` to ``data2/scans/a.ply``; None for a record written in `outdir`, or a URL."""
    from ..io.remote import is_url

    was, source = record.get("outdir"), record.get("input")
    if not was or was == str(outdir) or not source or is_url(source):
        return None
    return os.path.normpath(os.path.join(str(outdir), os.path.relpath(source, was)))


def former_folder(outputs, outdir):
    """The folder where records without ``outdir`` (an earlier version's) were written, told by
    their `outputs` (absolute paths): None where one of them is inside `outdir` (not moved), or
    the real path of the folder of one of the latest 64 is (named through a link to it, as
    versions before its real path did), or none is found; else, of the folder holding all of
    them and each folder above it, the one that puts the most of them (the latest 64) at an
    existing path when taken relative to it under `outdir`, the deepest of those tied."""
    if any(_inside(output, outdir) for output in outputs):
        return None
    sample = [output for output in outputs[-64:] if os.path.isabs(output)]
    if not sample or any(_inside(os.path.join(os.path.realpath(os.path.dirname(output)), ""), outdir)
                         for output in sample):
        return None
    try:
        candidate = os.path.commonpath([os.path.dirname(output) for output in sample])
    except ValueError:
        return None
    best, found = None, 0
    while True:
        count = sum(os.path.lexists(os.path.join(outdir, os.path.relpath(output, candidate))) for output in sample)
        if count > found:
            best, found = candidate, count
        parent = os.path.dirname(candidate)
        if parent == candidate:
            return best
        candidate = parent


def _inside(path, folder) -> bool:
    """Whether the absolute `path` is in `folder` (at any depth)."""
    return path.startswith(os.path.join(folder, ""))


def _latest_by_input(entries):
    out = {}
    for record in entries:
        out.pop(record["input"], None)
        out[record["input"]] = record
    return out


def _existing_parent(path):
    path = path.absolute()
    while not path.exists() and path != path.parent:
        path = path.parent
    return path


def _lock(path, shared=False):
    """A non-blocking lock on `path`, exclusive or `shared`, held while the returned descriptor is
    open: -> (descriptor, before). An exclusive holder writes its pid in the file, for the message
    of the next one, and gets the bytes it replaced as before (None for a shared lock)."""
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o666)
    try:
        _try_lock(fd, shared)
    except BlockingIOError:
        try:
            holder = os.pread(fd, 64, 0).decode("ascii", "replace").strip() or "unknown"
        finally:
            os.close(fd)
        raise FolderBusyError(f"another jaxpose run (pid {holder}{', or shards' if path.name == 'lock' and not shared else ''}) is writing to "
                              f"{path.parent.parent}; wait for it to finish or use another output folder") from None
    except BaseException:
        os.close(fd)
        raise
    if shared:
        return fd, None
    try:
        before = os.pread(fd, os.fstat(fd).st_size, 0)
        _rewrite(fd, f"{os.getpid()}\n".encode("ascii"))
    except BaseException:
        os.close(fd)
        raise
    return fd, before


def _rewrite(fd, data: bytes):
    """Make the open file ``fd`` hold ``data``: written first, the rest cut after (a write that fails
    leaves the earlier content)."""
    os.pwrite(fd, data, 0)
    os.ftruncate(fd, len(data))


def _try_lock(fd, shared):
    import fcntl  # POSIX (Linux, macOS)

    fcntl.flock(fd, (fcntl.LOCK_SH if shared else fcntl.LOCK_EX) | fcntl.LOCK_NB)
