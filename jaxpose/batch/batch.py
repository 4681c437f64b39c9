"""Normalize many files: inputs -> outputs that mirror their tree, plus a transforms table.

The work of one file is :func:`jaxpose.batch.task.normalize_file`, a pure function of (path, options,
format) that returns the pose and the encoded output; it runs in local worker processes (``workers``; one
worker runs in a thread of this process), or on a dask.distributed cluster (``scheduler`` or
``dask_local``; the optional extra ``pip install jaxpose[dask]``), with the same results. Results
stream back as they complete; only this process writes: each output atomically
(:mod:`jaxpose.io.atomic`), then one journal line (:mod:`jaxpose.batch.journal`). The transforms table
(:mod:`jaxpose.batch.transforms`) is rebuilt from the journal when the run ends, fails fast or is
interrupted. A rerun skips the inputs whose output exists and whose record matches the input's
size and modification time (or SHA-256 with ``check="hash"``) and the options; failed inputs are
tried again. A bad input is recorded (status ``failed``, its error) and logged, and the run goes
on. Worker processes (:mod:`jaxpose.batch.workers`) compile what JAX needs once each and reuse it for
every file, with the persistent compilation cache (:mod:`jaxpose.batch.cache`).

The table is the record of how to invert every output in the folder: besides this run's inputs,
it keeps the rows of earlier runs into the same folder whose outputs are still there. ``shard``
takes the inputs of one of N shards (:func:`jaxpose.batch.inputs.shard_index`), for N machines; their
tables together are the unsharded table (:func:`jaxpose.read_transforms` reads several).
"""
from __future__ import annotations

import functools
import hashlib
import logging
import os
import stat
import time
from pathlib import Path
from typing import NamedTuple

from .._validate import check_bool, check_int, check_real
from ..errors import InvalidInputError, JaxposeError, UsageError
from .task import FileResult, NormalizeOptions, input_key, normalize_file, one_line, recorded_settings, warm_up

__all__ = ["CHECKS", "NormalizeOptions", "BatchResult", "normalize_files", "run_batch"]

log = logging.getLogger(__name__)
CHECKS = ("mtime", "hash")
MAX_TRIES = 2  # workers an input may lose while running it (killed, out of memory) before it is recorded failed
MAX_LOST_BEFORE_START = 3  # workers it may lose before they start it (a crash or hang in start-up): not tries
PROGRESS_EVERY_S = 10.0  # progress="lines": at most one line this often


# --------------------------------------------------------------------------- many files
class BatchResult(NamedTuple):
    """What :func:`run_batch` did.

    Attributes:
      rows: the table (:class:`jaxpose.batch.transforms.Transform`), one row per input reached, in input order.
      table: where the table was written.
      written: inputs normalized by this run; skipped: inputs an earlier run had done; failed:
        inputs that failed in this run; stopped: True when ``fail_fast`` ended the run early.
      seconds: wall time of the run.
      peak_mb: {worker: its peak resident memory, MiB} over this run's inputs.
    """

    rows: list
    table: Path
    written: int
    skipped: int
    failed: int
    stopped: bool
    seconds: float
    peak_mb: dict


def run_batch(inputs, output_dir, options=None, *, glob=None, file_format=None, table=None, workers=None,
              scheduler=None, dask_local=None, check="mtime", fail_fast=False, force=False,
              progress=None, shard=None, timeout=None) -> BatchResult:
    """Normalize files, folders and manifests into `output_dir`; see :func:`normalize_files`."""
    from . import transforms
    from ..io.atomic import check_folder_writable, remove_temporaries
    from .inputs import check_shard, find_inputs, plan_outputs, shard_index
    from .journal import open_output_folder, shard_name
    from ..mesh import OUTPUT_FORMATS
    from ..io.remote import RemotePath, location

    start = time.perf_counter()
    options = NormalizeOptions() if options is None else options
    if not isinstance(options, NormalizeOptions):
        raise InvalidInputError(f"options must be a NormalizeOptions, got {type(options).__name__}")
    executor_args = _check_run(workers, scheduler, dask_local, timeout)
    if check not in CHECKS:
        raise InvalidInputError(f"check must be one of {', '.join(CHECKS)}; got {check!r}")
    fail_fast, force = check_bool(fail_fast, "fail_fast"), check_bool(force, "force")  # force="no" is truthy
    if file_format is not None:
        file_format = str(file_format).lower().lstrip(".")
        if file_format not in OUTPUT_FORMATS:
            raise InvalidInputError(f"format must be one of {', '.join(OUTPUT_FORMATS)}; got {file_format!r}")
    shard = check_shard(shard)
    output_dir = location(output_dir)
    if not isinstance(output_dir, RemotePath):  # through a link or "..": one folder, one name for its outputs
        output_dir = Path(os.path.realpath(output_dir))
    default_table = table is None
    if table is None:
        name = transforms.default_table_name()
        if shard is not None:
            stem, _, suffix = name.rpartition(".")
            name = f"{stem}.{shard_name(shard)}.{suffix}"
        table = output_dir / name
    table = location(table)
    transforms.table_format(table)
    found = find_inputs(inputs, glob=glob, exclude=[output_dir])
    given = [inputs] if isinstance(inputs, (str, os.PathLike)) else list(inputs)
    items = plan_outputs(found.files, found.root, output_dir, file_format=file_format, table=table, given=given)
    transforms.check_replaceable(table, force)
    if shard is not None:  # after the checks of the whole plan: every shard refuses alike
        items = [item for item in items if shard_index(item.source.relative_to(found.root), shard[1]) == shard[0]]
    # each input by its folder's real path (its own name kept): a folder named through a link, or
    # through "..", is one folder, as OUTDIR is; the journal and the table name inputs so
    folders = {}
    items = [item._replace(source=_real_folder(item.source, folders)) for item in items]
    irregular = {_real_folder(path, folders): kind for path, kind in found.irregular.items()}
    unsearchable = {_real_folder(path, folders): why for path, why in found.unsearchable.items()}
    fingerprint, settings = options.fingerprint(file_format), options.settings(file_format)
    fixed = options.columns()
    with open_output_folder(output_dir, force=force, shard=shard) as folder:
        run = None
        try:
            if not isinstance(table, RemotePath):
                check_folder_writable(table.parent, what="table")
            entries = _resolved(folder.entries(), output_dir)
            others = _resolved(folder.other_entries(), output_dir)
            if file_format:
                items = _recorded_names(items, entries + others, file_format)
            _refuse_mixing(items, entries, others, settings, force, folder.exists, output_dir)
            adopted, keys = _moved_inputs(items, entries, check, output_dir)
            entries = entries + adopted  # (each the latest record of its pair)
            if not force:
                _refuse_overwriting_others(items, entries)
            for record in adopted:  # for good: a later run (over part of the inputs) reads them so
                folder.append(record)
            pairs = {(r["input"], r.get("output") or ""): r for r in entries}
            todo, skipped = [], 0
            for item in items:
                key = keys.get(item.source) or _input_key(item.source, check)
                record = pairs.get((str(item.source), str(item.output)))
                if not force and _is_done(record, key, fingerprint, settings, item):
                    skipped += 1
                else:
                    todo.append((item, key))

            def tidy():  # the temporaries killed runs left, once this run starts (one that cannot leaves them)
                if not isinstance(table, RemotePath):
                    remove_temporaries(table)
                folder.remove_temporaries([item.output for item in items], everywhere=shard is None)

            run = _Run(folder, fixed, fingerprint, fail_fast, progress, len(todo), tidy, skipped)
            work = []
            for item, key in todo:  # what a folder search met that is not a file: failed unread
                if item.source in irregular:
                    run.finish(item, key, _not_regular(item.source, irregular[item.source]))
                elif item.source in unsearchable:  # a sub-folder that cannot be listed: its files are not read
                    run.finish(item, key, _failed(f"{item.source}: cannot search this folder: "
                                                  f"{unsearchable[item.source]}; its files were not read"))
                elif (refused := _unwritable(item.output)) is not None:  # failed before its work, as when written
                    run.finish(item, key, refused)
                else:
                    work.append((item, key))
            if work and not run.stopped:
                run.execute(work, executor_args, file_format, options, check, resumed=bool(entries))
            run.begin()  # nothing to do: the run has started all the same
        except BaseException:
            # refused (the table's folder, other options' outputs) or unable to start (the Dask scheduler
            # unreachable) before recording anything: the run leaves nothing it made, and no table
            if run is None or not (run.started or run.written or run.failed):
                folder.discard()
            raise
        finally:  # also on KeyboardInterrupt: the table holds every finished input
            if run is not None and not folder.discarded:
                rows = table_rows(items, _named_where_they_are(_resolved(folder.entries(), output_dir), output_dir),
                                  folder.exists)
                data = transforms.write_transforms(rows, table, rotation=bool(options.rotation_method) or None)
                try:
                    write_file(table, data)
                except OSError as exc:  # a full disk: it said "OSError: [Errno 28] No space left on device"
                    raise JaxposeError(f"cannot write the table {table}: {exc.strerror or one_line(exc)}; the outputs "
                                       "written are kept with their records: a rerun writes it") from None
                if default_table:
                    _remove_superseded_table(table)
    return BatchResult([transforms.Transform.from_record(r) for r in rows], table, run.written, skipped, run.failed, run.stopped,
                       time.perf_counter() - start, run.peak_mb)


def normalize_files(inputs, output_dir, options=None, **kwargs) -> list:
    """Normalize every mesh of files, folders and manifests; outputs mirror the inputs' tree.

    Options of :class:`NormalizeOptions` may also be given by name (``method="ocsvm"``), the
    run's below; an unknown name raises :class:`InvalidInputError`, and so does an OCSVM option
    (``gamma``, ``nu``, ``count``, ``seed``, ``sampling``) given by name where no OCSVM runs, in
    :func:`jaxpose.normalize_mesh`'s words (``gamma=47`` with the robust default; a
    :class:`NormalizeOptions` holds values, so its defaults written out are taken).

    Args:
      inputs: a path or paths: mesh files, folders (searched recursively for
        :data:`jaxpose.batch.inputs.MESH_SUFFIXES`) and manifests (``.txt`` / ``.csv`` lists of paths);
        fsspec URLs too (``"s3://bucket/scans/"``; :mod:`jaxpose.io.remote`, ``jaxpose[remote]``).
      output_dir: the output folder, a path or an fsspec URL (made when missing; refused when
        another run holds it, or when it holds files jaxpose did not write, unless ``force``).
      options: :class:`NormalizeOptions` (method, gamma, ..., rotation); default the defaults.
      glob: narrows folder searches (``"pose_*.ply"``, ``"kid_*/pose_0?.ply"``).
      file_format: output format for all (``"ply"``); default each input's, except a format
        jaxpose reads but does not write: a ``.gltf`` is written as ``.glb`` (``model.glb``).
      table: the transforms table's path or URL (``.parquet`` or ``.csv``); default
        ``output_dir/transforms.parquet`` (``.csv`` without pyarrow).
      workers: local worker processes (default: the cores available; 1 runs in this process).
      scheduler: a dask.distributed scheduler address (``"tcp://host:8786"``) to run on instead; its
        workers must see the input and the output paths' parent folders are only used here. One
        Dask cannot read (no port, an unknown scheme) is refused before any work; not reached
        within Dask's ``distributed.comm.timeouts.connect`` (30 s by default), the run stops with
        an error.
      dask_local: run on a new dask ``LocalCluster`` of this many worker processes instead.
      check: how a rerun recognizes an unchanged input: ``"mtime"`` (default: the size and
        modification time of each of its files, the input and a .gltf's buffer files,
        :func:`jaxpose.batch.task.input_key`; not their inode or status-change time, which a
        ``chmod``, a hard link or a restored copy change; a file replaced by one of the same size
        and modification time is skipped as done) or ``"hash"`` (SHA-256 of its bytes).
      fail_fast: stop at the first failed input.
      force: redo every input, write into a folder jaxpose did not make, and replace a `table`
        file that is not a transforms table.
      progress: a progress bar on stderr (rate, ETA): True, False, or None (only on a terminal);
        or ``"lines"``: plain lines on stderr for a log or a pipe (``jaxpose normalize: [120/1000]
        4.1 files/s, about 3 min left``), at the start and then at most every
        :data:`PROGRESS_EVERY_S` seconds (the command line's choice off a terminal).
      shard: (index, count): only the inputs of shard `index` of `count` (0 <= index < count), by
        a stable hash of each input's path relative to the inputs' root, so that `count` machines
        given the same arguments take every input once. The table defaults to
        ``transforms.shard-I-of-N.parquet``; the shards' tables together are the whole table
        (``jaxpose.read_transforms([...])`` or ``read_transforms(output_dir)``).
      timeout: seconds an input may take in its worker (reading, normalizing, encoding); past
        them the worker process is killed and replaced, and the input recorded as failed. The
        work then runs in worker processes even with ``workers=1``; local runs only. A worker's
        start-up is not counted; compiling for a grid size it has not met yet is (seconds for
        ``ocsvm`` without the compilation cache): leave room for it.

    Returns:
      The transforms table: a list of :class:`jaxpose.batch.transforms.Transform`, one per input, in order
      (also written to ``table``; failed inputs have ``status == "failed"`` and their ``error``),
      then the rows of earlier runs into `output_dir` whose outputs are still there.

    Raises:
      InvalidInputError: bad arguments, missing INPUTs, aliasing outputs (``model.gltf`` and
        ``model.glb`` in one folder, without `file_format`: both written ``model.glb``), an unusable
        output folder,
        an output that an earlier run wrote from another input or a `table` that is a folder or a
        file other than a transforms table (unless `force`) (all before any work). Those of the
        output paths and of conflicting run options are its subclass
        :class:`jaxpose.errors.UsageError` (the command line exits 2). A run refused, or that could
        not start (a `scheduler` not reached), before recording anything leaves nothing it made
        (neither `output_dir`, had it to make it, nor the table).
      jaxpose.batch.journal.FolderBusyError: another run is writing to `output_dir`.
      JaxposeError: the table could not be written at the end (a full disk), naming it and why; the
        outputs written are kept with their journal records, and a rerun writes it.

    Example::

        rows = jaxpose.normalize_files("scans/", "normalized/", workers=4)
        [r.input for r in rows if not r.ok]                  # what failed, with r.error
    """
    import dataclasses
    import inspect

    fields = {f.name for f in dataclasses.fields(NormalizeOptions)}
    runs = set(inspect.signature(run_batch).parameters) - {"inputs", "output_dir", "options"}
    unknown = sorted(set(kwargs) - fields - runs)
    if unknown:
        raise InvalidInputError(f"unknown argument{'s' if len(unknown) > 1 else ''} {', '.join(unknown)}; "
                                f"valid: {', '.join(sorted(fields | runs))}")
    named = {k: kwargs.pop(k) for k in list(kwargs) if k in fields}
    if named and options is not None:
        raise InvalidInputError(f"give options either as NormalizeOptions or by name ({', '.join(named)}), not both")
    if named:  # normalize_mesh's rule on what was given: gamma=47 with method="robust" is refused, not ignored
        from ..mesh import check_arguments

        check_arguments(**named)
    return run_batch(inputs, output_dir, NormalizeOptions(**named) if named else options, **kwargs).rows


def _check_run(workers, scheduler, dask_local, timeout=None):
    from .workers import default_workers

    if timeout is not None:
        timeout = check_real(timeout, "timeout (seconds)", 0, strict=True)
        if scheduler is not None or dask_local is not None:
            raise UsageError("timeout (--timeout) is for local runs: Dask cannot stop a running task")
    if scheduler is not None and dask_local is not None:
        raise UsageError("give either scheduler (--scheduler) or dask_local (--dask-local), not both")
    if scheduler is not None or dask_local is not None:
        from .workers import _distributed

        _distributed()  # not installed: refused here, before OUTDIR, its journal or its table is touched
    if dask_local is not None:
        dask_local = check_int(dask_local, "dask_local", 1)
    if scheduler is not None and not (isinstance(scheduler, str) and scheduler):
        raise UsageError(f"scheduler must be an address such as 'tcp://host:8786', got {scheduler!r}")
    if scheduler is not None:
        from .workers import check_scheduler

        check_scheduler(scheduler)  # Dask's own reading of it (its raw ValueError came after the folder was opened)
    if workers is not None:
        if scheduler is not None or dask_local is not None:
            raise UsageError("workers (--workers) is for local runs; a Dask cluster brings its own")
        workers = check_int(workers, "workers", 1)
    return {"workers": workers or default_workers(), "scheduler": scheduler, "dask_local": dask_local,
            "timeout": timeout}


def write_file(path, data):
    """Write bytes to a local path atomically (:func:`jaxpose.io.atomic.write_atomic`), or to a
    remote one in one PUT; replaces what is there."""
    from ..io.atomic import write_atomic
    from ..io.remote import RemotePath

    if isinstance(path, RemotePath):
        return path.write_bytes(data)
    return write_atomic(path, data, force=True)


def _remove_superseded_table(table):
    """Remove the default table of the other format beside `table` (``transforms.csv`` beside
    ``transforms.parquet``: an earlier run without pyarrow, or the reverse). The table just
    written holds the row of every output still in the folder, as a rerun's table of the same
    format replaces the earlier one; the other one, left, would give ``read_transforms(OUTDIR)``
    rows of outputs since deleted."""
    from ..io.remote import RemotePath

    other = table.with_suffix(".csv" if table.suffix == ".parquet" else ".parquet")
    try:
        if other.is_file():
            other.fs.rm_file(other.path) if isinstance(other, RemotePath) else other.unlink()
    except Exception:  # not ours to fail the run over; read_transforms merges it as before
        log.debug("could not remove %s", other, exc_info=True)


def _input_key(path, check):
    """Size, modification time (and SHA-256) of a regular file now (a local one's:
    :func:`jaxpose.batch.task.input_key`, a .gltf's with its buffer files); None for others (never
    opened here: a FIFO would block)."""
    from ..io.remote import RemotePath, modified_ns

    key = {"input_size": None, "input_mtime_ns": None, "input_sha256": "", "input_stat": None}
    if isinstance(path, RemotePath):
        try:
            info = path.info()
            key.update(input_size=info["size"], input_mtime_ns=modified_ns(info))
            if check == "hash":
                key["input_sha256"] = hashlib.sha256(path.read_bytes()).hexdigest()
        except Exception:  # missing or unreadable: not done; its read says why
            key["input_size"] = None
        return key
    try:
        return input_key(path, check)
    except OSError:  # unreadable: not done; its read says why
        return key


def _not_regular(path, kind):
    hint = " (name it as an INPUT to read it)" if kind == "a FIFO" else ""  # other kinds: 'not a file' there too
    return _failed(f"{path}: {kind}, not a regular file: a folder search reads regular files only{hint}")


def _unwritable(output):
    """The failed result of an input whose output path the write would refuse, told before the
    input's work: something there that :func:`jaxpose.io.atomic.write_atomic` does not replace (a
    symbolic link whose target's folder is missing or not writable, a loop of links, a folder, a
    FIFO: :func:`jaxpose.io.atomic.check_replaceable`), or a folder it needs that cannot be made or
    written in (``OUTDIR/a`` a regular file where ``OUTDIR/a/x.ply`` is written:
    :func:`jaxpose.io.atomic.check_creatable`), in the words of that write's failure ("cannot write
    OUTDIR/a/x.ply: OUTDIR/a is a file, not a folder"); None for a remote output, or a path whose
    folders are there or can be made, with nothing there, a regular file or a link to one."""
    from ..io.atomic import check_creatable, check_replaceable
    from ..io.remote import RemotePath

    if isinstance(output, RemotePath):
        return None
    try:
        if os.path.lexists(output):
            check_replaceable(output)
        else:
            check_creatable(Path(output).parent, f"cannot write {output}")
    except InvalidInputError as exc:
        message = one_line(exc)
        return _failed(message if message.startswith("cannot write ") else f"cannot write {output}: {message}")
    return None


_OPTION_NAMES = {"method": "--method", "center": "--center", "scale": "--scale", "gamma": "--gamma", "nu": "--nu",
                 "count": "--count", "seed": "--seed", "sampling": "--sampling", "resolution": "--resolution",
                 "rotation": "--rotation", "strict": "--strict"}


def _refuse_mixing(items, entries, other_entries, settings, force, exists, output_dir):
    """Refuse (before any work) a run that would leave outputs of two option sets in one folder.

    An output in the folder made with other settings (:meth:`NormalizeOptions.settings`, the
    output format aside) is refused, naming the differing options: without `force` (which redoes
    this run's inputs with its options); with it too when this run does not redo that output (an
    input of an earlier run into the folder, another shard's): it would stay beside this run's.
    Not refused: resuming a forced run that was stopped, with its options (the folder's latest
    record has them)."""
    mine = _without_format(settings)
    differing = []  # (output, its settings or None) of every output there made with other options
    for journal in (entries, other_entries):
        for output, i in _owners(journal).items():
            theirs = _without_format(recorded_settings(journal[i].get("options")))
            if theirs != mine and exists(output):
                differing.append((output, theirs))
    if not differing:
        return
    redone = {str(item.output) for item in items}
    staying = [(output, theirs) for output, theirs in differing if output not in redone]
    resuming = bool(entries) and _without_format(recorded_settings(entries[-1].get("options"))) == mine
    if not staying and (force or resuming):
        return
    output, theirs = (staying or differing)[0]
    if theirs is None:
        how = "options this version cannot read (an earlier jaxpose's)"
    else:
        how = "; ".join(f"{_OPTION_NAMES.get(k, k)} {_shown(theirs[k], k)} there, {_shown(mine[k], k)} here"
                        for k in mine if k in theirs and theirs[k] != mine[k]
                        and (k not in ("center", "scale") or theirs["method"] == mine["method"])) or "other options"
    count = len(staying or differing)
    outputs = f"{count} output{'s' if count > 1 else ''} (such as {output})"
    if staying:
        raise UsageError(f"{output_dir} holds {outputs} made with other options ({how}) that this run would not "
                         "redo: the folder would hold results of two option sets; write to another output folder "
                         "(or remove those outputs)")
    raise UsageError(f"{output_dir} holds {outputs} made with other options ({how}); use --force / force=True to "
                     "redo them with these options, or write to another output folder")


def _same_settings(theirs, mine, source):
    """Whether a record's settings are this run's for `source`, the output format compared resolved:
    None (the input's own) is the format of the input's suffix, as :func:`normalize_file` writes it
    (``format="ply"`` for a ``.ply`` input is no format given)."""
    if theirs is None:
        return False
    own = Path(str(source)).suffix.lower().lstrip(".")
    return {**theirs, "format": theirs["format"] or own} == {**mine, "format": mine["format"] or own}


def _without_format(settings):
    """Settings without the output format: outputs in two formats of one input are not two option sets."""
    return None if settings is None else {k: v for k, v in settings.items() if k != "format"}


def _shown(value, key=None):
    """A setting as the refusal names it; None is no rotation ("off") and no resolution ("none": the
    estimators read none, as bbox's), not the default (a robust run's default resolution is 96)."""
    if value is None:
        return {"rotation": "off", "resolution": "none"}.get(key, "default")
    return str(value).lower() if isinstance(value, bool) else f"{value:g}" if isinstance(value, float) else str(value)


def _real_folder(path, folders):
    """A local path with its folder's real path (links and ".." taken out) and its own name (a link
    to a file stays that link); a remote path as it is. `folders` caches the folders' real paths
    (one ``realpath`` per folder: thousands of paths share a few)."""
    from ..io.remote import RemotePath, is_url

    if isinstance(path, RemotePath) or is_url(str(path)):
        return path
    head, name = os.path.split(str(path))
    if head not in folders:
        folders[head] = os.path.realpath(head)
    real = os.path.join(folders[head], name)
    return path if real == str(path) else Path(real) if isinstance(path, Path) else real


def _resolved(entries, output_dir):
    """The records with each output's and each local input's folder resolved (links and ".." taken
    out, as `output_dir`'s is, and as a run names its inputs), so that a file recorded under another
    name of its folder (an earlier run given a link to it, or a version that kept the name as given)
    is recognized as the same file; remote paths as they are."""
    from ..io.remote import RemotePath

    folders, out = {}, []
    for record in entries:
        changed = {key: _real_folder(record[key], folders) for key in ("input", "output")
                   if record.get(key) and not (key == "output" and isinstance(output_dir, RemotePath))}
        changed = {key: value for key, value in changed.items() if value != record[key]}
        out.append({**record, **changed} if changed else record)
    return out


def _recorded_names(items, entries, file_format):
    """The items whose output an earlier version recorded with ``file_format``'s lower-case suffix,
    where this one keeps the input's name (``--format ply`` wrote ``A.PLY`` as ``A.ply``), under
    that recorded name: a rerun skips them instead of writing the same output twice. ``entries``:
    the records of every journal in the folder (a shard's run over a whole run's folder, which it
    does not skip, writes the output under the name the folder holds, not a second file beside it)."""
    recorded = {(r["input"], r.get("output")) for r in entries if r.get("output")}
    out = []
    for item in items:
        earlier = item.output.with_suffix("." + file_format)
        if earlier != item.output and (str(item.source), str(item.output)) not in recorded and \
                (str(item.source), str(earlier)) in recorded:
            item = item._replace(output=earlier)
        out.append(item)
    return out


def _refuse_overwriting_others(items, entries):
    """Refuse (before any work) to replace an output that an earlier run wrote from another input."""
    from ..io.remote import is_url

    owners = _owners(entries)
    for item in items:
        owner = entries[owners[str(item.output)]]["input"] if str(item.output) in owners else None
        if owner is not None and owner != str(item.source) and item.output.exists():
            if not is_url(owner) and not os.path.lexists(owner):  # moved, renamed or removed since
                raise UsageError(
                    f"{item.output} holds the output of {owner} (an earlier run into this folder), which is no "
                    f"longer there; {item.source}, this run's input for that output, is not that file moved (it "
                    "differs from the record: size and modification time, or SHA-256 under --check hash); use "
                    "--force / force=True to redo it, or another output folder")
            raise UsageError(f"{item.output} holds the output of {owner} (an earlier run into this folder), "
                             f"not of {item.source}; use another output folder, or --force / force=True "
                             "to replace it")


def _owners(entries) -> dict:
    """{output: the index in `entries` of the latest ok record naming it}: the record that owns an
    output (its table row; the input an earlier run wrote it from; its options)."""
    owners = {}
    for i, record in enumerate(entries):
        if record.get("status") == "ok" and record.get("output"):
            owners[record["output"]] = i
    return owners


def _moved_inputs(items, entries, check, output_dir):
    """The records of this run's outputs whose input moved: -> (adopted, keys).

    An output belongs to this run's input for it (the same path relative to the inputs' root) when
    its latest ok record names another input, that input is no longer there (moved, or its folder
    renamed: ``mv scans scans2``) or this run's input is where it would be had it moved with the
    output folder (:func:`jaxpose.batch.journal.moved_input`: ``mv data data2``), and this run's
    input is the same file by the rerun's rule (:func:`_same_input`: size and modification time,
    or SHA-256 with ``check="hash"``; a record without a SHA-256 is compared by size and time, and
    is then done again under "hash", as where nothing moved), or this run's input is where it would
    be had it moved with the output folder and the recorded input is gone (a dataset moved whole) or
    the folder the record was written in is still there (a dataset copied whole, ``cp -r data
    data2``): its path tells it is that input, as where nothing moved, and a file changed since is
    done again. An OUTDIR moved alone beside another
    folder of the same layout keeps its records' inputs, which are still there. `adopted`: a copy
    of each such record naming this run's input. `keys`: the :func:`_input_key` of each input
    looked at (not taken again)."""
    from ..io.remote import is_url
    from .journal import moved_input

    owners = _owners(entries)
    adopted, keys = [], {}
    for item in items:
        i = owners.get(str(item.output))
        if i is None:
            continue
        record, source = entries[i], str(item.source)
        along, gone = moved_input(record, output_dir) == source, not os.path.lexists(record["input"])
        if record["input"] == source or is_url(record["input"]) or not (gone or along):
            continue
        keys[item.source] = key = _input_key(item.source, check)
        recorded = key if record.get("input_sha256") else {**key, "input_sha256": ""}  # no hash recorded: size, time
        # moved whole (the recorded input gone) or copied whole (the folder it was written in still
        # there): its path says it is that input; else (OUTDIR moved alone) only the same file is
        copied = os.path.isdir(record.get("outdir") or "")
        if (along and (gone or copied)) or _same_input(record, recorded):
            adopted.append({**record, "input": source})
    return adopted, keys


def _named_where_they_are(entries, output_dir):
    """The records for the table: one whose input is no longer where it was recorded, named where it
    would be had it moved with the output folder (:func:`jaxpose.batch.journal.moved_input`) where
    a file is there (an input of an earlier run, moved with the folder, that this run did not
    take); the others as recorded."""
    from ..io.remote import is_url
    from .journal import moved_input

    out = []
    for record in entries:
        there = moved_input(record, output_dir)
        if there is not None and not is_url(record["input"]) and not os.path.lexists(record["input"]) \
                and os.path.lexists(there):
            record = {**record, "input": there}
        out.append(record)
    return out


def _is_done(record, key, fingerprint, settings, item):
    if not record or record.get("status") != "ok":
        return False
    if record.get("options") != fingerprint and not _same_settings(recorded_settings(record.get("options")), settings,
                                                                   item.source):
        return False
    output = item.output
    if record.get("output") != str(output) or not output.exists():
        return False
    return _same_input(record, key)


def _same_input(record, key):
    """Whether a record's input is the file of `key` (:func:`_input_key`) by the rerun's rule: the
    same size and modification time (and each file's, a .gltf's buffers too, where the record has
    them), or the same SHA-256 where `key` has one (``check="hash"``)."""
    if key["input_size"] is None:
        return False
    fields = ("input_size", "input_sha256") if key["input_sha256"] else ("input_size", "input_mtime_ns")
    if not key["input_sha256"] and "input_stat" in record:  # (an earlier version's record: size and time alone)
        fields += ("input_stat",)  # each file's size and time: a .gltf's buffer replaced by an older one
    return all(record.get(f) == key[f] for f in fields)


def table_rows(items, entries, exists=os.path.exists) -> list:
    """The table of a run: a row for every output in the folder, and one for each failed input.

    Args:
      items: this run's inputs and outputs (:class:`jaxpose.batch.inputs.Item`), in order.
      entries: the journal's last record of each (input, output) pair, in the order written
        (:meth:`jaxpose.batch.journal.OutputFolder.entries`).
      exists: whether an output (a record's path) is there.

    Returns:
      The records: first, for each input of this run, the row of its output (when that is there)
      and its failed row (when its latest attempt failed); then the rows of every other output
      still there that earlier runs wrote, in the order written. An output's row is the latest
      ok record that names it, so every output in the folder has the row that inverts it, even
      when its input has since been written elsewhere, changed, or failed.
    """
    live = {i for output, i in _owners(entries).items() if exists(output)}
    latest = {record["input"]: i for i, record in enumerate(entries)}
    pairs = {(record["input"], record.get("output") or ""): i for i, record in enumerate(entries)}
    chosen = []
    for item in items:
        name = str(item.source)
        mine = pairs.get((name, str(item.output)))
        if mine in live:
            chosen.append(mine)
        last = latest.get(name)
        if last is not None and entries[last].get("status") != "ok":
            chosen.append(last)
    taken = set(chosen)
    chosen += [i for i in sorted(live) if i not in taken]
    return [entries[i] for i in chosen]


def _is_regular(path):
    try:
        return stat.S_ISREG(os.stat(path).st_mode)
    except OSError:
        return False


def read_ahead(path) -> bool:
    """Ask the kernel to start reading a local regular file into its cache now (``posix_fadvise``
    WILLNEED; it returns at once), so that the worker that takes it parses bytes already read.
    Returns whether it asked: not for other files (a FIFO is never opened), remote paths, or where
    the call does not exist."""
    if not hasattr(os, "posix_fadvise") or not isinstance(path, (str, os.PathLike)) or not _is_regular(path):
        return False
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    except OSError:
        return False
    try:
        os.posix_fadvise(fd, 0, 0, os.POSIX_FADV_WILLNEED)
        return True
    except OSError:
        return False
    finally:
        os.close(fd)


def _lost_workers(tries, before):
    """How many workers an input cost, in words: "tried twice", or the count of each kind."""
    workers = f"{before} worker{'s' if before != 1 else ''} lost before starting it"
    if not tries:
        return f"never run: {workers}"
    said = f"tried {({1: 'once', 2: 'twice'}).get(tries, f'{tries} times')}"
    return f"{said}, and {workers}" if before else said


def _failed(error):
    from .. import __version__

    return FileResult({"status": "failed", "error": error, "version": __version__}, None)


class _Lines:
    """progress="lines": the part of tqdm's interface a run uses (``update``, ``set_postfix_str``,
    ``close``), as plain lines on stderr: ``[k/N] started`` (N: the inputs this run handles, the
    summary's "of N inputs" less those already done; k of them failed before any work: a FIFO in a
    folder, an output that cannot be written), then at most one line every
    :data:`PROGRESS_EVERY_S` seconds with the rate, the time left and the failures so far."""

    def __init__(self, total, initial=0, postfix="", skipped=0):
        self.total, self.n, self.initial, self.postfix = total, initial, initial, postfix
        self.start = self.last = time.monotonic()
        self._say("started" + (f" ({skipped} more already done)" if skipped else ""))

    def update(self, n=1):
        self.n += n
        now = time.monotonic()
        if self.n < self.total and now - self.last >= PROGRESS_EVERY_S:
            self.last = now
            rate = (self.n - self.initial) / max(now - self.start, 1e-9)
            self._say(f"{rate:.1f} files/s, about {_duration((self.total - self.n) / rate)} left")

    def set_postfix_str(self, text, refresh=True):
        self.postfix = text

    def close(self):
        pass

    def _say(self, text):
        import sys

        extra = f", {self.postfix}" if self.postfix else ""
        print(f"jaxpose normalize: [{self.n}/{self.total}] {text}{extra}", file=sys.stderr, flush=True)


def _duration(seconds):
    """``"40 s"``, ``"3 min"``, ``"2.5 h"``."""
    if seconds < 90:
        return f"{seconds:.0f} s"
    return f"{seconds / 60:.0f} min" if seconds < 5400 else f"{seconds / 3600:.1f} h"


class _Run:
    """The waiting loop of one run: submit a window of tasks, write each result as it arrives."""

    def __init__(self, folder, fixed, fingerprint, fail_fast, progress, total, tidy=None, skipped=0):
        self.folder, self.fixed, self.fingerprint, self.fail_fast = folder, fixed, fingerprint, fail_fast
        self.progress, self.total, self._tidy, self.skipped = progress, total, tidy, skipped
        self.written = self.failed = 0
        self.stopped = False
        self.started = False  # whether the executor started (Dask: connected to its scheduler)
        self.peak_mb = {}

    def execute(self, todo, executor_args, file_format, options, check, resumed=False):
        from tqdm import tqdm

        from .workers import DaskExecutor, LocalExecutor, TaskTimeout, WorkerLost, runs_like_a_worker

        if executor_args["scheduler"] is not None or executor_args["dask_local"] is not None:
            executor = DaskExecutor(executor_args["scheduler"], executor_args["dask_local"])
        else:
            # the first input in this process while the workers start, where that is safe: a regular
            # file (it cannot block), the workers' numerics, and a fresh folder (an input that crashed
            # the run takes a worker process on the rerun)
            head_start = not resumed and runs_like_a_worker() and _is_regular(todo[0][0].source)
            # workers forked from this process (no interpreter start, no imports) where it computes as
            # they would and runs no JAX (the host estimators; jaxpose.batch.pool)
            fork = runs_like_a_worker() and not options.uses_jax
            executor = LocalExecutor(min(executor_args["workers"], len(todo)), timeout=executor_args["timeout"],
                                     head_start=head_start, warm_up=functools.partial(warm_up, options), fork=fork)
        self.started = True
        try:
            self.begin()
        except BaseException:
            executor.close(kill=True)
            raise
        # the bar counts what the summary counts: every input this run handles, those that failed
        # before any work (recorded already) counted done from the start ("[0/3]" of "1 of 4 failed")
        done = self.total - len(todo)
        postfix = f"{self.failed} failed" if self.failed else ""
        if self.progress == "lines":
            bar = _Lines(self.total, done, postfix, self.skipped)
        else:
            bar = tqdm(total=self.total, initial=done, unit="file", desc="normalize", dynamic_ncols=True,
                       smoothing=0.05, disable=None if self.progress is None else not self.progress,
                       postfix=postfix or None)  # (in its first frame: set after, it waited for the next)
        queue, pending, lost = list(reversed(todo)), {}, {}  # source -> (workers lost after / before starting it)
        window = 2 * executor.workers
        try:
            while queue or pending:
                while queue and len(pending) < window and not self.stopped:
                    item, key = queue.pop()
                    read_ahead(item.source)  # the disk works while the workers compute
                    future = executor.submit(normalize_file, str(item.source), options, file_format, check)
                    pending[future] = (item, key)
                if not pending:
                    break
                for future in executor.wait(pending):
                    item, key = pending.pop(future)
                    try:
                        result = executor.result(future)
                    except WorkerLost as exc:  # its worker died (the others go on): once more, then record
                        tries, before = lost.get(item.source, (0, 0))
                        tries, before = (tries + 1, before) if exc.started else (tries, before + 1)
                        lost[item.source] = (tries, before)
                        if tries < MAX_TRIES and before < MAX_LOST_BEFORE_START:
                            queue.append((item, key))
                            continue
                        result = _failed(f"{exc}; {_lost_workers(tries, before)}")
                    except TaskTimeout as exc:
                        result = _failed(str(exc))
                    except Exception as exc:  # the task itself broke (not the input): recorded as well
                        result = _failed(one_line(exc))
                    self.finish(item, key, result)
                    if self.failed:  # (before the update: the line or frame it draws counts this input's failure)
                        bar.set_postfix_str(f"{self.failed} failed", refresh=False)
                    bar.update(1)
                if self.stopped:
                    break
            executor.close(kill=self.stopped)
        except BaseException:
            executor.close(kill=True)
            raise
        finally:
            bar.close()

    def begin(self):
        """What the run does to the folder once it starts (its first record, or its executor
        started), once: ``tidy`` (the temporaries killed runs left)."""
        tidy, self._tidy = self._tidy, None
        if tidy is not None:
            tidy()

    def finish(self, item, key, result):
        """Write one input's output (when it has one) and append its record."""
        from .interrupts import deferred

        self.begin()
        with deferred():  # an output and its journal line, both or (on a signal before) neither
            self._write_and_record(item, key, result)

    def _write_and_record(self, item, key, result):
        record = {**key, **{k: v for k, v in result.record.items() if k != "matrix"}}  # the worker's read wins
        record.update(self.fixed, input=str(item.source), output="", options=self.fingerprint)
        if record["status"] == "ok":
            try:
                item.output.parent.mkdir(parents=True, exist_ok=True)
                write_file(item.output, result.data)
                record["output"] = str(item.output)
            except Exception as exc:  # OSError here; a remote store has errors of its own
                record.update(status="failed", error=f"cannot write {item.output}: {one_line(exc)}")
        if record["status"] == "ok":
            self.written += 1
        else:
            self.failed += 1
            error = record["error"]
            log.warning("%s", error if error.startswith(str(item.source)) else f"{item.source}: {error}")
            self.stopped = self.fail_fast
        if record.get("worker") and record.get("worker_peak_mb") is not None:
            self.peak_mb[record["worker"]] = max(self.peak_mb.get(record["worker"], 0.0), record["worker_peak_mb"])
        self.folder.append(record)
