"""Normalize many files: inputs -> outputs that mirror their tree, plus a transforms table.

The work of one file is :func:`jaxpose.task.normalize_file`, a pure function of (path, options,
format) that returns the pose and the encoded output; it runs in local worker processes (``workers``; one
worker runs in a thread of this process), or on a dask.distributed cluster (``scheduler`` or
``dask_local``; the optional extra ``pip install jaxpose[dask]``), with the same results. Results
stream back as they complete; only this process writes: each output atomically
(:mod:`jaxpose.atomic`), then one journal line (:mod:`jaxpose.journal`). The transforms table
(:mod:`jaxpose.transforms`) is rebuilt from the journal when the run ends, fails fast or is
interrupted. A rerun skips the inputs whose output exists and whose record matches the input's
size and modification time (or SHA-256 with ``check="hash"``) and the options; failed inputs are
tried again. A bad input is recorded (status ``failed``, its error) and logged, and the run goes
on. Worker processes (:mod:`jaxpose.workers`) compile what JAX needs once each and reuse it for
every file, with the persistent compilation cache (:mod:`jaxpose.cache`).
"""
from __future__ import annotations

import hashlib
import logging
import numbers
import os
import time
from pathlib import Path
from typing import NamedTuple

from .errors import InvalidInputError
from .task import FileResult, NormalizeOptions, normalize_file, one_line

__all__ = ["CHECKS", "NormalizeOptions", "BatchResult", "normalize_files", "run_batch"]

log = logging.getLogger(__name__)
CHECKS = ("mtime", "hash")


# --------------------------------------------------------------------------- many files
class BatchResult(NamedTuple):
    """What :func:`run_batch` did.

    Attributes:
      rows: the table (:class:`jaxpose.transforms.Transform`), one row per input reached, in input order.
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
              progress=None) -> BatchResult:
    """Normalize files, folders and manifests into `output_dir`; see :func:`normalize_files`."""
    from . import transforms
    from .atomic import check_folder_writable, remove_temporaries, write_atomic
    from .inputs import find_inputs, plan_outputs
    from .journal import OutputFolder
    from .mesh import OUTPUT_FORMATS

    start = time.perf_counter()
    options = NormalizeOptions() if options is None else options
    if not isinstance(options, NormalizeOptions):
        raise InvalidInputError(f"options must be a NormalizeOptions, got {type(options).__name__}")
    executor_args = _check_run(workers, scheduler, dask_local)
    if check not in CHECKS:
        raise InvalidInputError(f"check must be one of {', '.join(CHECKS)}; got {check!r}")
    if file_format is not None:
        file_format = str(file_format).lower().lstrip(".")
        if file_format not in OUTPUT_FORMATS:
            raise InvalidInputError(f"format must be one of {', '.join(OUTPUT_FORMATS)}; got {file_format!r}")
    output_dir = Path(os.path.abspath(output_dir))
    table = Path(os.path.abspath(table)) if table is not None else output_dir / transforms.default_table_name()
    transforms.table_format(table)
    files, root = find_inputs(inputs, glob=glob, exclude=[output_dir])
    given = [inputs] if isinstance(inputs, (str, os.PathLike)) else list(inputs)
    items = plan_outputs(files, root, output_dir, file_format=file_format, table=table, given=given)
    fingerprint = options.fingerprint(file_format)
    fixed = options.columns()
    with OutputFolder(output_dir, force=force) as folder:
        check_folder_writable(table.parent, what="table")
        folder.remove_temporaries()
        remove_temporaries(table)
        records = folder.records()
        todo, skipped = [], 0
        for item in items:
            key = _input_key(item.source, check)
            record = records.get(str(item.source))
            if not force and _is_done(record, key, fingerprint, item.output):
                skipped += 1
            else:
                todo.append((item, key))
        run = _Run(folder, fixed, fingerprint, fail_fast, progress, len(todo))
        try:
            if todo:
                run.execute(todo, executor_args, file_format, options)
        finally:  # also on KeyboardInterrupt: the table holds every finished input
            rows = _rows(items, folder.records(), fingerprint)
            write_atomic(table, transforms.write_transforms(rows, table, rotation=bool(options.rotation_method)),
                         force=True)
    return BatchResult([transforms.Transform.from_record(r) for r in rows], table, run.written, skipped, run.failed, run.stopped,
                       time.perf_counter() - start, run.peak_mb)


def normalize_files(inputs, output_dir, options=None, **kwargs) -> list:
    """Normalize every mesh of files, folders and manifests; outputs mirror the inputs' tree.

    Options of :class:`NormalizeOptions` may also be given by name (``method="ocsvm"``), the
    run's below; an unknown name raises :class:`InvalidInputError`.

    Args:
      inputs: a path or paths: mesh files, folders (searched recursively for
        :data:`jaxpose.inputs.MESH_SUFFIXES`) and manifests (``.txt`` / ``.csv`` lists of paths).
      output_dir: the output folder (made when missing; refused when another run holds it, or when
        it holds files jaxpose did not write, unless ``force``).
      options: :class:`NormalizeOptions` (method, gamma, ..., rotation); default the defaults.
      glob: narrows folder searches (``"pose_*.ply"``, ``"kid_*/pose_0?.ply"``).
      file_format: output format for all (``"ply"``); default each input's.
      table: the transforms table's path (``.parquet`` or ``.csv``); default
        ``output_dir/transforms.parquet`` (``.csv`` without pyarrow).
      workers: local worker processes (default: the cores available; 1 runs in this process).
      scheduler: a dask.distributed scheduler address (``"tcp://host:8786"``) to run on instead; its
        workers must see the input and the output paths' parent folders are only used here.
      dask_local: run on a new dask ``LocalCluster`` of this many worker processes instead.
      check: how a rerun recognizes an unchanged input: ``"mtime"`` (size and modification time,
        default) or ``"hash"`` (SHA-256 of its bytes).
      fail_fast: stop at the first failed input.
      force: redo every input, and write into a folder jaxpose did not make.
      progress: a progress bar on stderr (rate, ETA): True, False, or None (only on a terminal).

    Returns:
      The transforms table: a list of :class:`jaxpose.transforms.Transform`, one per input, in order
      (also written to ``table``; failed inputs have ``status == "failed"`` and their ``error``).

    Raises:
      InvalidInputError: bad arguments, missing INPUTs, aliasing outputs, an unusable output folder
        (all before any work).
      jaxpose.journal.FolderBusyError: another run is writing to `output_dir`.

    Example::

        >>> rows = jaxpose.normalize_files("scans/", "normalized/", workers=4)
        >>> [r.input for r in rows if not r.ok]                  # what failed, with r.error
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
    return run_batch(inputs, output_dir, NormalizeOptions(**named) if named else options, **kwargs).rows


def _count(value, name, minimum):
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < minimum:
        raise InvalidInputError(f"{name} must be an int >= {minimum}, got {value!r}")
    return int(value)


def _check_run(workers, scheduler, dask_local):
    from .workers import default_workers

    if scheduler is not None and dask_local is not None:
        raise InvalidInputError("give either scheduler (--scheduler) or dask_local (--dask-local), not both")
    if dask_local is not None:
        dask_local = _count(dask_local, "dask_local", 1)
    if scheduler is not None and not (isinstance(scheduler, str) and scheduler):
        raise InvalidInputError(f"scheduler must be an address such as 'tcp://host:8786', got {scheduler!r}")
    if workers is not None:
        if scheduler is not None or dask_local is not None:
            raise InvalidInputError("workers (--workers) is for local runs; a Dask cluster brings its own")
        workers = _count(workers, "workers", 1)
    return {"workers": workers or default_workers(), "scheduler": scheduler, "dask_local": dask_local}


def _input_key(path, check):
    try:
        stat = os.stat(path)
    except OSError:
        return {"input_size": None, "input_mtime_ns": None, "input_sha256": ""}
    key = {"input_size": stat.st_size, "input_mtime_ns": stat.st_mtime_ns, "input_sha256": ""}
    if check == "hash":
        digest = hashlib.sha256()
        with open(path, "rb") as handle:
            for block in iter(lambda: handle.read(1 << 20), b""):
                digest.update(block)
        key["input_sha256"] = digest.hexdigest()
    return key


def _is_done(record, key, fingerprint, output):
    if not record or record.get("status") != "ok" or record.get("options") != fingerprint:
        return False
    if record.get("output") != str(output) or not output.exists() or key["input_size"] is None:
        return False
    fields = ("input_size", "input_sha256") if key["input_sha256"] else ("input_size", "input_mtime_ns")
    return all(record.get(f) == key[f] for f in fields)


def _rows(items, records, fingerprint):
    rows = []
    for item in items:
        record = records.get(str(item.source))
        if record and record.get("options") == fingerprint:
            rows.append(record)
    return rows


class _Run:
    """The waiting loop of one run: submit a window of tasks, write each result as it arrives."""

    def __init__(self, folder, fixed, fingerprint, fail_fast, progress, total):
        self.folder, self.fixed, self.fingerprint, self.fail_fast = folder, fixed, fingerprint, fail_fast
        self.progress, self.total = progress, total
        self.written = self.failed = 0
        self.stopped = False
        self.peak_mb = {}

    def execute(self, todo, executor_args, file_format, options):
        from tqdm import tqdm

        from .workers import DaskExecutor, LocalExecutor

        if executor_args["scheduler"] is not None or executor_args["dask_local"] is not None:
            executor = DaskExecutor(executor_args["scheduler"], executor_args["dask_local"])
        else:
            executor = LocalExecutor(min(executor_args["workers"], len(todo)))
        bar = tqdm(total=len(todo), unit="file", desc="normalize", dynamic_ncols=True, smoothing=0.05,
                   disable=None if self.progress is None else not self.progress)
        queue, pending, retried = list(reversed(todo)), {}, set()
        window = 2 * executor.workers
        try:
            while queue or pending:
                while queue and len(pending) < window and not self.stopped:
                    item, key = queue.pop()
                    pending[executor.submit(normalize_file, str(item.source), options, file_format)] = (item, key)
                if not pending:
                    break
                lost = False
                for future in executor.wait(pending):
                    item, key = pending.pop(future)
                    try:
                        result = executor.result(future)
                    except Exception as exc:  # WorkerLost: retry once in a fresh pool, then record
                        if item.source not in retried:
                            retried.add(item.source)
                            queue.append((item, key))
                            lost = True
                            continue
                        result = FileResult({"status": "failed", "error": str(exc)}, None)
                    self._finish(item, key, result)
                    bar.update(1)
                    if self.failed:
                        bar.set_postfix_str(f"{self.failed} failed", refresh=False)
                if lost:
                    for future, entry in pending.items():  # they share the dead pool's fate
                        queue.append(entry)
                    pending.clear()
                    executor.restart()
                if self.stopped:
                    break
            executor.close(kill=self.stopped)
        except BaseException:
            executor.close(kill=True)
            raise
        finally:
            bar.close()

    def _finish(self, item, key, result):
        from .interrupts import deferred

        with deferred():  # an output and its journal line, both or (on a signal before) neither
            self._write_and_record(item, key, result)

    def _write_and_record(self, item, key, result):
        from .atomic import write_atomic

        record = {k: v for k, v in result.record.items() if k != "matrix"}
        record.update(self.fixed, input=str(item.source), output="", options=self.fingerprint, **key)
        if record["status"] == "ok":
            try:
                item.output.parent.mkdir(parents=True, exist_ok=True)
                write_atomic(item.output, result.data, force=True)
                record["output"] = str(item.output)
            except OSError as exc:
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
