"""The inputs of a batch run: files, folders and manifests -> (input, output) pairs, checked.

An INPUT is a mesh file, a folder (searched recursively for :data:`MESH_SUFFIXES`, hidden files
and folders skipped, and folders below it that hold ``.jaxpose/``: earlier runs' output folders,
whose outputs are not inputs again; narrowed by a glob) or a manifest (:data:`MANIFEST_SUFFIXES`: one path per
line, ``#`` comments; or a CSV whose ``path`` / ``input`` column, else first column, holds them:
a header naming that column ``file``, ``filename``, ``mesh`` ... is refused; relative paths are
relative to the manifest). Outputs mirror the inputs' tree: each input's path
relative to the deepest folder common to all inputs (a folder INPUT counts as that folder, a file
or a manifest's entry as the file's folder: one folder INPUT is its own root, several folders
keep their names), under the output folder, with the input's format or the one asked for.

A folder search takes regular files (and links to them); other files it meets (FIFOs, sockets,
devices, links to them) are returned apart, to be recorded as failed without being opened, and
links to folders are not followed (a link loop cannot trap it); a sub-folder it cannot list
(permissions) is returned apart too, to be recorded as failed, naming it. A regular file or a FIFO named as
an INPUT or in a manifest is read (a FIFO delivers a stream; a silent one fails after
:data:`jaxpose.io.mesh.PIPE_WAIT_S` seconds, or sooner with ``--timeout``); sockets and devices
fail there too ("not a file").

:func:`shard_index` splits inputs among N machines by a stable hash of their relative path.
"""
from __future__ import annotations

import csv
import fnmatch
import hashlib
import os
import posixpath
import re
import stat
from pathlib import Path
from typing import NamedTuple

from .._validate import InvalidInputError
from ..config import _integer
from ..errors import UsageError
from ..io.remote import RemotePath, is_url, location
from .journal import STATE_FOLDER

__all__ = ["MESH_SUFFIXES", "MANIFEST_SUFFIXES", "Item", "Found", "find_inputs", "plan_outputs", "is_batch_input",
           "shard_index", "check_shard", "file_kind"]

MESH_SUFFIXES = (".ply", ".obj", ".off", ".stl", ".glb", ".gltf", ".xyz")
MANIFEST_SUFFIXES = (".txt", ".csv", ".lst", ".list")
WRITTEN_AS = {".gltf": ".glb"}  # read but not written: an input kept in its own format is written as this one


class Item(NamedTuple):
    """One input file and where its output goes.

    Attributes:
      source: the input file, absolute (it may be missing: a manifest's entry; it then fails); a
        run names it by its folder's real path (:func:`jaxpose.batch.batch.run_batch`).
      output: the output file, absolute (None until :func:`plan_outputs`).
    """

    source: Path | RemotePath
    output: Path | RemotePath | None = None


class Found(NamedTuple):
    """What :func:`find_inputs` found.

    Attributes:
      files: absolute input paths (sorted within each folder; manifest order kept), no repeats: a
        file found under several names (links to it) keeps the first name that is not a link.
      root: the common folder their outputs are mirrored from.
      irregular: {path: what it is ("a FIFO", ...)} for the files of `files` that a folder search
        met and that are not regular files: they fail without being opened.
      unsearchable: {path: why (``"Permission denied"``)} for the folders below a searched folder
        that could not be listed (a ``chmod 000`` sub-folder): each is in `files`, where its files
        would be, and fails, naming it (they were left out without a word).
    """

    files: list
    root: Path
    irregular: dict
    unsearchable: dict = {}


def file_kind(mode) -> str:
    """What a file mode stands for, in words: "a regular file", "a FIFO", "a socket", ..."""
    for test, name in ((stat.S_ISREG, "a regular file"), (stat.S_ISDIR, "a folder"), (stat.S_ISFIFO, "a FIFO"),
                       (stat.S_ISSOCK, "a socket"), (stat.S_ISCHR, "a character device"),
                       (stat.S_ISBLK, "a block device")):
        if test(mode):
            return name
    return "not a regular file"


def is_batch_input(path) -> bool:
    """Whether a command-line INPUT is a folder or a manifest (not a single mesh file)."""
    path = location(path)
    return path.suffix.lower() in MANIFEST_SUFFIXES or _is_dir(path)


def _is_dir(path) -> bool:
    """``path.is_dir()``, False where the path cannot be looked at (a file in a folder this user may
    not search: ``pathlib`` raises PermissionError there): it is then taken as a file, which fails
    when read, saying why ("cannot read: Permission denied")."""
    try:
        return path.is_dir()
    except PermissionError:
        return False


def _exists(path) -> bool:
    """``path.exists()``, True where the path cannot be looked at (as :func:`_is_dir`): not missing,
    but unreadable, which its read reports."""
    try:
        return path.exists()
    except PermissionError:
        return True


def find_inputs(inputs, glob=None, exclude=()) -> Found:
    """The input files of files, folders and manifests, in a deterministic order, without repeats.

    Args:
      inputs: paths (str or Path) or URLs (:mod:`jaxpose.io.remote`) of files, folders and
        manifests, all on one file system.
      glob: narrows folder searches (fnmatch): matched against the file name, or, when it contains
        ``/``, against the path relative to the searched folder, where ``*`` also spans folders
        (``"kid_*/pose_0?.ply"``) and ``**/`` is any number of folders, none too (``"**/*.ply"``);
        case is ignored, as the suffixes are (``"*.ply"`` takes ``SCAN.PLY``).
      exclude: folders never searched (the output folder, when it lies inside an input folder);
        folders below a searched one that hold ``.jaxpose/`` (other runs' output folders) are not
        searched either.

    Returns:
      :class:`Found`: the files, their root, the irregular files and the folders that cannot be
      listed met by folder searches.

    Raises:
      InvalidInputError: inputs that are not paths, an INPUT that does not exist, an INPUT folder
        that cannot be listed ("cannot search the folder scans/: Permission denied"), an unreadable
        manifest or one of numbers (a point cloud named .txt / .csv), a .csv manifest whose header
        names its paths' column otherwise than ``path`` / ``input`` (``file``, ``filename``, ...:
        :data:`_PATH_LIKE`), nothing found, INPUTs on different file systems.
    """
    paths = (str, os.PathLike, RemotePath)
    if not isinstance(inputs, paths) and (isinstance(inputs, bytes) or not hasattr(inputs, "__iter__")):
        raise InvalidInputError(f"inputs must be a path (str, Path or URL) or paths, got {inputs!r:.80}")
    inputs = [inputs] if isinstance(inputs, paths) else list(inputs)
    if not inputs:
        raise InvalidInputError("no inputs given")
    for given in inputs:
        if not isinstance(given, paths):
            raise InvalidInputError(f"inputs must be paths (str, Path or URL), got {given!r:.80} among them")
    exclude = {identity(location(e)) for e in exclude}
    files, roots, irregular, unsearchable = [], [], {}, {}
    for given in inputs:
        path = location(given)
        if isinstance(path, RemotePath) and path.is_dir():
            roots.append(path)
            files += _search_remote(path, glob, exclude)
        elif _is_dir(path):
            roots.append(path)
            files += _search(path, glob, exclude, irregular, unsearchable, given)
        elif not _exists(path):
            raise InvalidInputError(f"no such file or folder: {given}")
        elif path.suffix.lower() in MANIFEST_SUFFIXES:
            listed = _read_manifest(path)
            roots += [p.parent for p in listed]
            files += listed
        else:
            roots.append(path.parent)
            files.append(path)
    keys = [identity(path) for path in files]
    chosen = {}  # one name per file: the first that is not a link, else the first (a link to it)
    for i, (path, key) in enumerate(zip(files, keys)):
        if key not in chosen or (_is_link(files[chosen[key]]) and not _is_link(path)):
            chosen[key] = i
    unique = [path for i, (path, key) in enumerate(zip(files, keys)) if chosen[key] == i]
    if not unique:
        hint = f" matching {glob!r}" if glob else f" ({', '.join(MESH_SUFFIXES)})"
        raise InvalidInputError(f"no mesh files found in {', '.join(map(str, inputs))}{hint}")
    return Found(unique, _common_root(roots), {p: irregular[p] for p in unique if p in irregular},
                 {p: unsearchable[p] for p in unique if p in unsearchable})


def _is_link(path) -> bool:
    return not isinstance(path, RemotePath) and os.path.islink(path)


def identity(path) -> str:
    """What makes two paths the same file: the real path of a local one, a remote one's URL."""
    return str(path) if isinstance(path, RemotePath) else os.path.realpath(path)


def _common_root(roots):
    remote = [r for r in roots if isinstance(r, RemotePath)]
    if not remote:
        return Path(os.path.commonpath([str(r) for r in roots]))
    if len(remote) < len(roots) or len({r.fs.protocol for r in remote}) > 1:
        raise InvalidInputError("the INPUTs are on different file systems ("
                                f"{', '.join(sorted({str(r).split('://')[0] if isinstance(r, RemotePath) else 'local' for r in roots}))}"
                                "); give each its own run")
    return RemotePath(remote[0].fs, posixpath.commonpath([r.path for r in remote]))


def _search_remote(folder, glob, exclude):
    """A folder search on a remote file system, in the order of the local one (each folder's
    files sorted, then its sub-folders)."""
    found, outputs = [], set()
    for name, info in folder.fs.find(folder.path, detail=True).items():
        if info.get("type", "file") != "file":
            continue
        path = RemotePath(folder.fs, name)
        relative = path.relative_to(folder)
        if STATE_FOLDER in relative.parts[1:-1]:  # an earlier run's OUTDIR below the searched folder
            outputs.add(relative.parts[:relative.parts.index(STATE_FOLDER, 1)])
        if any(part.startswith(".") for part in relative.parts) or relative.suffix.lower() not in MESH_SUFFIXES:
            continue
        if any(identity(folder / Path(*relative.parts[:i])) in exclude for i in range(1, len(relative.parts))):
            continue
        if glob is None or _matches(relative, glob):
            found.append((relative, path))
    found = [(relative, path) for relative, path in found
             if not any(relative.parts[:i] in outputs for i in range(1, len(relative.parts)))]
    return [path for _, path in sorted(found, key=lambda pair: _walk_order(pair[0]))]


def _walk_order(relative):
    parts = relative.parts
    return [(1, p) for p in parts[:-1]] + [(0, parts[-1])]


def _search(folder, glob, exclude, irregular, unsearchable, given):
    found = []

    def unlisted(exc):  # a folder os.walk cannot list (it skipped it without a word)
        if os.path.abspath(exc.filename) == os.path.abspath(folder):
            raise InvalidInputError(f"cannot search the folder {given}: {exc.strerror}") from None
        path = Path(exc.filename)
        found.append(path)  # where its files would be, in walk order: a failed row, naming it
        unsearchable[path] = exc.strerror or type(exc).__name__

    for here, dirs, names in os.walk(folder, onerror=unlisted):  # links to folders are listed in dirs, not followed
        dirs[:] = sorted(d for d in dirs if not d.startswith(".")
                         and os.path.realpath(os.path.join(here, d)) not in exclude
                         and not os.path.isdir(os.path.join(here, d, STATE_FOLDER)))  # an earlier run's OUTDIR
        for name in sorted(names):
            if name.startswith(".") or os.path.splitext(name)[1].lower() not in MESH_SUFFIXES:
                continue
            path = Path(here) / name
            if glob is None or _matches(path.relative_to(folder), glob):
                found.append(path)
                try:
                    mode = os.stat(path).st_mode
                except OSError:  # a dangling link: it fails when read, saying so
                    continue
                if not stat.S_ISREG(mode):
                    irregular[path] = file_kind(mode)
    return found


def _matches(relative, glob):
    """Whether a found file matches `glob`, ignoring case as the suffix filter does (on every system:
    ``fnmatch.fnmatch`` ignores it on Windows only). ``**/`` stands for any number of folders, none
    too (as in ``pathlib`` and shells' globstar: ``**/*.ply`` takes the searched folder's own files;
    to ``fnmatch`` it is ``*`` then ``/``, at least one folder, and those files were left out)."""
    text = (relative.as_posix() if "/" in glob else relative.name).casefold()
    return any(fnmatch.fnmatchcase(text, pattern) for pattern in _globstar_patterns(glob.casefold()))


def _globstar_patterns(glob):
    """`glob` with each subset of its ``**/`` taken out (``a/**/b`` -> ``a/**/b``, ``a/b``): their
    union matches ``**/`` as zero or more folders, since ``*`` spans folders. Only a ``**/`` that
    starts the pattern or follows a ``/`` is any folders, as in ``glob(recursive=True)``: in a name
    (``kid**/x.ply``) it is two ``*`` (``kid1/x.ply``, not ``kidx.ply``)."""
    parts = re.split(r"(?<![^/])\*\*/", glob)
    patterns = {parts[0]}
    for part in parts[1:]:
        patterns = {p + "**/" + part for p in patterns} | {p + part for p in patterns}
    return sorted(patterns)


_PATH_LIKE = ("file", "filename", "file_name", "filepath", "file_path", "mesh")
"""Header names of a .csv manifest's column of paths that are not 'path' or 'input': refused, naming
those (its first column, header included, was read: 'id,file' gave ids as paths)."""


def _read_manifest(path):
    try:
        text = path.read_bytes().decode("utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        raise InvalidInputError(f"{path}: cannot read the manifest: {exc}") from None
    if path.suffix.lower() == ".csv":
        rows = [r for r in csv.reader(text.splitlines()) if r and r[0].strip()]
        column = 0
        if rows:
            header = [c.strip().lower() for c in rows[0]]
            named = [header.index(n) for n in ("path", "input") if n in header]
            if named:
                column, rows = named[0], rows[1:]
            elif likely := [c for c in header if c in _PATH_LIKE]:  # (its first column, the header line too)
                raise InvalidInputError(f"{path}: a .csv manifest's paths are read from its column named 'path' or "
                                        "'input', else from its first column (the first line too); its header "
                                        f"{','.join(c.strip() for c in rows[0])!r:.80} names {likely[0]!r}: rename "
                                        "that column 'path'")
        entries = [r[column].strip() if column < len(r) else "" for r in rows]
    else:
        entries = [line.strip() for line in text.splitlines()]
    entries = [e for e in entries if e and not e.startswith("#")]
    body = entries[1:101] if len(entries) > 1 else entries  # (below a header line such as "x,y,z")
    if body and all(_numbers(e) for e in body):  # every path would fail "no such file: 0 0 0"
        csv_hint = (" (or a CSV whose paths are in a column named neither 'path' nor 'input': the first column is "
                    "read then)") if path.suffix.lower() == ".csv" else ""
        raise InvalidInputError(f"{path}: a manifest (.txt and .csv INPUTs list mesh paths, one a line) whose lines "
                                f"are numbers ({body[0]!r}): is it a point cloud? name it .xyz{csv_hint}")
    if isinstance(path, RemotePath):  # relative to the manifest, on its file system
        return [location(e) if is_url(e) else path.parent / e for e in entries]
    return [location(e) if is_url(e) else Path(os.path.abspath(path.parent / Path(e).expanduser())) for e in entries]


def _numbers(entry) -> bool:
    """Whether a manifest's entry is numbers (``0 0 0``, ``1.5,2,3``): a coordinate line, not a path."""
    values = entry.replace(",", " ").split()
    try:
        return bool(values) and all(float(v) == float(v) for v in values)
    except ValueError:
        return False


def plan_outputs(files, root, output_dir, file_format=None, table=None, given=()) -> list:
    """Pair each input with its output under `output_dir`, refusing every kind of aliasing.

    Args:
      files, root: from :func:`find_inputs`.
      output_dir: the output folder.
      file_format: an output format for all (``"ply"``), or None to keep each input's (one jaxpose
        reads but does not write, :data:`WRITTEN_AS`: ``model.gltf`` is written ``model.glb``); an
        input already in it keeps its name (``A.PLY`` is written ``A.PLY``, as without a format).
      table: the transforms table's path, checked against inputs and outputs too.
      given: the INPUTs as given (manifests among them), which the table must not overwrite either.

    Returns:
      list of :class:`Item` with absolute outputs, in the order of `files`.

    Raises:
      InvalidInputError: two inputs with one output (also two outputs whose names differ only in
        case: one file on macOS and Windows), an output where another output needs a
        folder of that name, an output that is an input, or a table that is an input or an output
        (nothing has been written).
    """
    output_dir = location(output_dir)
    items, owner, folded = [], {}, {}
    sources = {identity(location(f)): f for f in [*given, *files]}
    for source in files:
        relative = source.relative_to(root)
        output = output_dir / relative
        if file_format and source.suffix.lower() != "." + file_format:  # its own format keeps its name: A.PLY
            output = output.with_suffix("." + file_format)
        elif not file_format and source.suffix.lower() in WRITTEN_AS:  # model.gltf -> model.glb
            output = output.with_suffix(WRITTEN_AS[source.suffix.lower()])
        key = identity(output)
        if key in owner:
            raise UsageError(f"{owner[key]} and {source} would both be written to {output}; "
                             "give them separate runs or output folders")
        if key.casefold() in folded:  # A.PLY and A.ply: one file where names ignore case (macOS, Windows)
            other, written = folded[key.casefold()]
            raise UsageError(f"{other} and {source} would be written to {written} and {output}, one file "
                             "where file names ignore case; give them separate runs or output folders")
        folded[key.casefold()] = source, output
        if key in sources:
            raise UsageError(f"{output} would overwrite its input; choose an output folder apart "
                             "from the inputs")
        owner[key] = source
        items.append(Item(source, output))
    checked = set()  # each folder once
    for item in items:  # x.off -> OUT/x.ply and x.ply/y.off -> OUT/x.ply/y.ply: a file where a folder must be
        folder = item.output.parent
        while folder != output_dir and folder != folder.parent and folder not in checked:
            checked.add(folder)
            if identity(folder) in owner:
                raise UsageError(f"{owner[identity(folder)]} would be written to {folder}, a file where "
                                 f"{item.source} needs a folder ({item.output}); give them separate runs or "
                                 "output folders")
            folder = folder.parent
    if table is not None:
        key = identity(location(table))
        if key in sources or key in owner:
            raise UsageError(f"the table {table} would overwrite "
                             f"{'an input' if key in sources else 'an output'}; name another file")
    return items


def check_shard(shard):
    """`shard` as (index, count) of ints with 0 <= index < count; None stays None.

    Raises:
      InvalidInputError: anything else (with the expected form).
    """
    if shard is None:
        return None
    try:
        index, count = (_integer(v) for v in shard)  # the one int rule (config's): None for anything else
        if index is None or count is None:
            raise ValueError
    except (TypeError, ValueError):
        raise InvalidInputError(f"shard must be (index, count), such as (0, 4); got {shard!r}") from None
    if not 0 <= index < count:
        raise InvalidInputError(f"shard must have 0 <= index < count (the shards of 4 are 0/4 ... 3/4); "
                                f"got {index}/{count}")
    return index, count


def shard_index(relative, count) -> int:
    """The shard (0 ... count - 1) of an input, from its path relative to the inputs' root.

    A stable hash (the first 8 bytes of the SHA-256 of the path's bytes, ``/``-separated, as a
    big-endian integer, modulo `count`), the same on every machine and Python process (unlike
    ``hash``), so that N machines given the same INPUTs and ``--shard 0/N`` ... ``N-1/N`` take
    every input exactly once.

    Example::

        >>> shard_index("kid_01/pose_03.ply", 4)
        1
    """
    key = os.fsencode(Path(relative).as_posix())
    return int.from_bytes(hashlib.sha256(key).digest()[:8], "big") % int(count)
