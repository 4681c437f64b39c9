"""``jaxpose normalize``: one file (``-o out.ply``), or files, folders and manifests (``-o OUTDIR``).

Thin: arguments to :class:`jaxpose.batch.task.NormalizeOptions` (validated before any I/O), the checks
of what will be written (formats, aliasing names, folders, existing files) before any work, then
:func:`jaxpose.normalize_mesh` for one file or :func:`jaxpose.batch.batch.run_batch` for many.
"""
from __future__ import annotations

import os
import sys
from pathlib import Path

from ..config import OCSVM_ONLY
from .common import add_svm_options, checked, fail, json_text

__all__ = ["add_parser", "run", "transform_path", "EXAMPLE"]

EXAMPLE = "example"


def add_parser(sub):
    """Register ``normalize`` on the sub-command parsers `sub`; :func:`run` runs it."""
    from .._validate import check_int, check_real
    from ..batch.batch import CHECKS
    from ..pose.estimators import CENTERS, DEFAULT_METHOD, METHODS, SCALES
    from ..mesh import OUTPUT_FORMATS, SAMPLING
    from ..rotation.rotation import DEFAULT_ROTATION, ROTATIONS
    from ..config import GridConfig, RobustConfig

    p = sub.add_parser("normalize", help="normalize meshes or point clouds: one file, or folders and manifests")
    p.add_argument("inputs", nargs="*", metavar="INPUT",
                   help="a mesh file (OBJ, PLY, OFF, STL, GLB, XYZ, ...) or 'example'; or several files, folders "
                        "(searched recursively) and manifests (.txt/.csv lists of paths) with -o OUTDIR")
    p.add_argument("-o", "--output", help="the normalized mesh of one INPUT (format from the extension), or the "
                                          "output folder of many (outputs mirror the input tree)")
    p.add_argument("--example", action="store_true", help="use the built-in example shape as input")
    add_svm_options(p, seed="ocsvm: seed of the surface samples")
    p.add_argument("--method", choices=tuple(METHODS), default=None,
                   help=f"center/scale method (default {DEFAULT_METHOD}; ocsvm is the paper's)")
    p.add_argument("--center", choices=CENTERS, default=None, help="center estimator (overrides --method's)")
    p.add_argument("--scale", choices=SCALES, default=None, help="scale estimator (overrides --method's)")
    p.add_argument("--strict", action="store_true", help="closed-surface estimators refuse open meshes")
    p.add_argument("--sampling", choices=SAMPLING, default=None, help="surface sampling of the ocsvm method "
                                                                        "(default even)")
    p.add_argument("--resolution", type=int, default=None,
                   help=f"robust: voxels along the main body's largest extent (default {RobustConfig().resolution}); ocsvm: "
                        f"cells per axis of the volume integral's grid (default {GridConfig().resolution}); with a method that "
                        f"reads none, the --rotation frame's (head, core: the robust solid's; ocsvm: its grid); >= 8")
    p.add_argument("--transform", help="one INPUT: where to write the transform JSON (default: OUTPUT.transform.json)")
    p.add_argument("--rotation", nargs="?", const=DEFAULT_ROTATION, default=None, metavar="METHOD",
                   type=_rotation_method, help=f"also the canonical orientation (default method {DEFAULT_ROTATION}; "
                                               f"{', '.join(ROTATIONS)}); off by default")
    p.add_argument("--force", action="store_true", help="overwrite existing outputs (many: redo every input)")
    many = p.add_argument_group("many files (several INPUTs, folders or manifests, with -o OUTDIR)")
    many.add_argument("--glob", help="narrow folder searches: 'pose_*.ply', 'kid_*/pose_0?.ply', '**/pose_*.ply' "
                                     "('**/': any folders, none too; case ignored, as the suffixes are: '*.ply' "
                                     "takes SCAN.PLY)")
    many.add_argument("--format", choices=OUTPUT_FORMATS, help="output format (default: each input's; "
                      "a .gltf input is written as .glb)")
    many.add_argument("--table", help="the transforms table, .parquet or .csv (default OUTDIR/transforms.parquet; "
                                      ".csv without pyarrow)")
    many.add_argument("--workers", type=checked(int, lambda n: check_int(n, "workers", 1)), metavar="N",
                      help="local worker processes (default: the cores)")
    many.add_argument("--scheduler", metavar="ADDRESS", help="run on this dask.distributed scheduler "
                                                              "(pip install 'jaxpose[dask]')")
    many.add_argument("--dask-local", type=checked(int, lambda n: check_int(n, "dask_local", 1)), metavar="N",
                      help="run on a new local Dask cluster of N workers")
    many.add_argument("--check", choices=CHECKS, default=None,
                      help="how a rerun recognizes finished inputs: mtime (each file's size and modification "
                           "time, a .gltf's buffers too; default: a file replaced by one of the same size and "
                           "time is skipped) or hash (SHA-256 of the bytes)")
    many.add_argument("--fail-fast", action="store_true", help="stop at the first input that fails")
    many.add_argument("--shard", type=_shard, metavar="I/N",
                      help="only shard I of N (0 <= I < N), by a stable hash of each input's relative path: N "
                           "machines given the same arguments take every input once; the table is "
                           "transforms.shard-I-of-N.parquet")
    many.add_argument("--timeout", type=checked(float, lambda t: check_real(t, "timeout (seconds)", 0, strict=True)),
                      metavar="SECONDS",
                      help="an input taking longer (reading, normalizing) is recorded as failed and its worker "
                           "process replaced; local runs")
    # the OCSVM's options: None when not given, so that a method that ignores them can refuse them
    p.set_defaults(handler=run, **dict.fromkeys(OCSVM_ONLY))


_MANY_ONLY = ("glob", "format", "table", "workers", "scheduler", "dask_local", "check", "fail_fast", "shard",
              "timeout")


def _rotation_method(text):
    """--rotation's optional METHOD; a file name in its place (``--rotation body.ply -o out.ply``:
    argparse gives the optional value the next word) is named as the INPUT it is."""
    import argparse

    from ..rotation.rotation import ROTATIONS

    if text in ROTATIONS:
        return text
    hint = ""
    if os.path.splitext(text)[1] or os.path.exists(text) or text == EXAMPLE:
        hint = (f"; {text!r} looks like the INPUT: --rotation takes the word after it as its METHOD, so put the "
                f"INPUT before --rotation, or name the method (--rotation head {text})")
    raise argparse.ArgumentTypeError(f"invalid choice: {text!r} (choose from {', '.join(ROTATIONS)}){hint}")


def _shard(text):
    import argparse

    from ..batch.inputs import check_shard
    from ..errors import InvalidInputError

    index, _, count = text.partition("/")
    try:
        return check_shard((int(index), int(count)))
    except InvalidInputError as exc:  # I >= N: a usage error, as a malformed one is (before ValueError: its base)
        raise argparse.ArgumentTypeError(str(exc)) from None
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected I/N such as 0/4, got {text!r}") from None


def transform_path(output) -> Path:
    """``out.ply`` -> ``out.transform.json``."""
    output = Path(output)
    return output.with_name(output.stem + ".transform.json")


def _transform_options(options) -> dict:
    """The options a transform JSON records of `options` (:class:`jaxpose.batch.task.NormalizeOptions`):
    ``method``, ``center_method``, ``scale_method``; the OCSVM's ``gamma``, ``nu``, ``count``,
    ``seed``, ``sampling`` only where it runs (as the center, the scale or the frame: no other
    estimator reads them); ``resolution`` where one was given (absent: the estimator's default)."""
    columns = options.columns()
    names = ("method", "center_method", "scale_method", *(OCSVM_ONLY if options.uses_jax else ()))
    out = {k: columns[k] for k in names}
    if options.resolution is not None:
        out["resolution"] = options.resolution
    return out


def ignored_options(args) -> str | None:
    """Why options given on the command line do nothing with the chosen method, or None.

    ``--gamma``, ``--nu``, ``--count``, ``--seed`` and ``--sampling`` are read only by the OCSVM
    (``--method ocsvm``, ``--center/--scale ocsvm`` or ``--rotation ocsvm``); ``--strict`` only by
    the closed-surface estimators.
    """
    from ..pose.estimators import CLOSED_FORMS, DEFAULT_METHOD, resolve, strict_unread

    c_name, s_name = resolve(args.method, args.center, args.scale)
    chosen = f"--method {args.method or DEFAULT_METHOD} (center {c_name}, scale {s_name})"
    if "ocsvm" not in (c_name, s_name) and args.rotation != "ocsvm":
        given = [f"--{name}" for name in OCSVM_ONLY if getattr(args, name, None) is not None]
        if given:
            return (f"{', '.join(given)} {'apply' if len(given) > 1 else 'applies'} to the ocsvm method "
                    f"(--method ocsvm), which {chosen} does not use; leave {'them' if len(given) > 1 else 'it'} out")
    if args.strict and not set(CLOSED_FORMS) & {c_name, s_name}:
        return strict_unread([(c_name, s_name)], name="--strict")  # the library's wording
    return None


def run(args):
    """Run ``jaxpose normalize`` with parsed `args`. Returns the exit code."""
    from ..batch.task import NormalizeOptions
    from ..batch.inputs import MESH_SUFFIXES, is_batch_input

    ignored = ignored_options(args)
    if ignored:
        return fail(ignored, code=2)
    from ..errors import InvalidInputError

    given = {name: getattr(args, name) for name in OCSVM_ONLY if getattr(args, name, None) is not None}
    try:  # a value out of range is a usage error (exit 2), found before any file is read
        options = NormalizeOptions(method=args.method, center=args.center, scale=args.scale,
                                   resolution=args.resolution, rotation=args.rotation or False, strict=args.strict,
                                   **given)
    except InvalidInputError as exc:
        return fail(str(exc), code=2)
    inputs = list(args.inputs)
    many = len(inputs) > 1 or any(p != EXAMPLE and is_batch_input(p) for p in inputs) or bool(
        args.output and (os.path.isdir(args.output) or args.output.endswith(("/", os.sep))))
    expanded = _expanded_glob(args.glob, inputs)
    if expanded:
        return fail(expanded, code=2)
    if many:
        if args.output and Path(args.output).suffix.lower() in MESH_SUFFIXES and not os.path.isdir(args.output):
            given = "these INPUTs give" if len(inputs) > 1 else \
                f"{inputs[0]} is a {'folder' if os.path.isdir(inputs[0]) else 'manifest (a list of mesh paths)'}: it gives"
            return fail(f"-o {args.output} names a mesh file, but {given} many files: -o OUTDIR (a folder, created if "
                        "missing)", code=2)
        return _normalize_many(args, options, fail)
    given = [f"--{name.replace('_', '-')}" for name in _MANY_ONLY if getattr(args, name) not in (None, False)]
    if given:
        return fail(f"{', '.join(given)} {'apply' if len(given) > 1 else 'applies'} to many files: several INPUTs, "
                     "folders or manifests, with -o OUTDIR", code=2)
    return _normalize_one(args, options, inputs[0] if inputs else None, fail)


def _expanded_glob(glob, inputs):
    """Why ``--glob`` looks expanded by the shell (``--glob *.ply`` unquoted: ``--glob a.ply b.ply
    c.ply``, the other names taken as INPUTs, and the run normalizing b.ply, c.ply and what matches
    a.ply in the folders, without a word), or None: a pattern without wildcards that names a file
    here, beside INPUTs that are files of its suffix in its folder. A pattern without wildcards
    that only names a file here is warned about (a name to look for is a pattern too)."""
    if not glob or any(c in glob for c in "*?[") or not os.path.isfile(glob):
        return None
    siblings = expanded_glob_names(glob, inputs)
    hint = f"quote the pattern: --glob '*{os.path.splitext(glob)[1].lower()}'"
    if siblings:
        return (f"--glob {glob} and the INPUTs {', '.join(siblings[:3])}{' ...' if len(siblings) > 3 else ''} are "
                f"files here: the shell expanded --glob's pattern into their names; {hint}")
    print(f"jaxpose: warning: --glob {glob} has no wildcard and names a file here: if the shell expanded a pattern, "
          f"{hint}", file=sys.stderr)
    return None


def expanded_glob_names(glob, names):
    """Those of `names` (INPUTs, or arguments argparse did not recognize) that look like the rest of
    ``--glob``'s pattern expanded by the shell: files here of the suffix and folder of a `glob`
    without wildcards that is itself a file here. Empty where the pattern has a wildcard (the shell
    left it alone) or is not a file. The one rule of :func:`_expanded_glob` and of the command line's
    hint on unrecognized arguments."""
    if not glob or any(c in glob for c in "*?[") or not os.path.isfile(glob):
        return []
    folder, suffix = os.path.dirname(os.path.abspath(glob)), os.path.splitext(glob)[1].lower()
    return [p for p in names if os.path.isfile(p) and os.path.dirname(os.path.abspath(p)) == folder
            and os.path.splitext(p)[1].lower() == suffix]


def _normalize_one(args, options, source, fail):
    from ..batch import interrupts
    from .. import mesh

    if args.example:
        if source is not None:
            return fail("give either INPUT or --example, not both", code=2)
        source = EXAMPLE
    if source is None:
        return fail("normalize needs an INPUT file (or --example)", code=2)
    from ..io.remote import is_url, location

    if any(is_url(p) and not p.lower().startswith("file://") for p in (source, args.output) if p):
        return fail("remote paths (URLs) are for datasets: a folder or manifest INPUT, or -o OUTDIR/ "
                    "(a folder, ending in /)", code=2)
    if is_url(source):  # file://: a local path
        source = str(location(source))
    if is_url(args.output):
        args.output = str(location(args.output))
    use_example = source == EXAMPLE and not Path(source).exists()
    output = Path(args.output) if args.output else None
    json_path = Path(args.transform) if args.transform else (transform_path(output) if output else None)
    if not use_example:  # a missing input named first, before -o's problems (exit 1, as it is alone)
        from ..io.mesh import check_input

        check_input(source)
    _check_outputs(None if use_example else Path(source), output, json_path, args.force)
    geometry = mesh.example_shape() if use_example else mesh.load(source)
    if output is not None:
        mesh.output_format(output, geometry)  # a point cloud for STL/OFF: refused before the work
    normalized, pose = mesh.normalize_mesh(geometry, **options.mesh_arguments())
    interrupts.check()  # a swallowed Ctrl-C stops here, before anything is written
    record = {"input": EXAMPLE if use_example else str(Path(source).resolve()), **_transform_options(options),
        "center": [float(v) for v in _flat(pose.center)],
        "scale": float(_flat(pose.scale)[0]),
        "matrix": mesh.pose_matrix(pose).tolist(),
        "converged": bool(getattr(pose, "converged", True)),
    }
    if args.rotation:
        record.update(rotation_method=args.rotation, rotation=_flat(pose.rotation).reshape(3, 3).tolist(),
                      ambiguity=float(_flat(pose.ambiguity)[0]), rotation_flagged=bool(_flat(pose.ambiguity)[0] > 0))
    for path in (output, json_path):  # folders checked creatable before the work, made now (as OUTDIRs are)
        if path is not None:
            path.parent.mkdir(parents=True, exist_ok=True)
    _write_both(normalized, output, json_path, json_text(record), args.force)
    _print_transform(record, args.output, json_path)
    if not record["converged"]:
        print("jaxpose: warning: the solver stopped at its iteration cap", file=sys.stderr)
    return 0


def _write_both(normalized, output, json_path, record_text, force):
    """The normalized mesh and its transform JSON, both or neither where it can be: a signal that
    comes between the two writes is held until both are done (it left the mesh without its
    transform, under "nothing partial was left"), and a mesh this run created is removed when the
    JSON cannot be written (a rerun then refused the mesh as existing). A mesh that ``--force``
    replaced stays replaced."""
    from ..batch import interrupts
    from .. import mesh

    created = output is not None and not output.exists()
    with interrupts.deferred():
        if output is not None:
            mesh.export(normalized, output, force=force)
        if json_path is not None:
            try:
                mesh.write_atomic(json_path, record_text, force=force)
            except BaseException:
                if created:
                    output.unlink(missing_ok=True)
                raise


def _check_outputs(source, output, json_path, force):
    """Refuse, before any work: unknown output formats, aliasing files, unusable folders, existing files
    (UsageError: exit 2)."""
    from ..io.atomic import check_creatable, check_replaceable
    from ..errors import InvalidInputError, UsageError
    from ..mesh import output_format

    if output is not None:
        try:
            output_format(output)
        except InvalidInputError as exc:  # -o out.vtk: a bad value of -o
            raise UsageError(str(exc)) from None
    named = [(p, what) for p, what in ((output, "-o"), (json_path, "--transform")) if p is not None]
    if len(named) == 2 and os.path.realpath(output) == os.path.realpath(json_path):
        raise UsageError(f"-o and --transform name the same file {output}; give them different names")
    for path, what in named:
        if source is not None and os.path.realpath(path) == os.path.realpath(source):
            raise UsageError(f"{what} {path} is the input file; write the output elsewhere")
        check_creatable(path.parent, f"{what} {path}")  # a missing folder is made after the work
        check_replaceable(path, what)
        if path.exists() and not force:
            raise UsageError(f"{path} exists (use --force to overwrite)")


def _normalize_many(args, options, fail):
    from ..batch import batch

    if args.example or EXAMPLE in args.inputs:
        if len(args.inputs) + bool(args.example) == 1:  # the example alone, -o a folder ("said: normalize it alone")
            return fail(f"'example' is one mesh: -o names its output file (-o example.ply), not a folder "
                        f"({args.output})", code=2)
        return fail("'example' is one input: normalize it alone", code=2)
    if not args.output:
        return fail("several INPUTs, folders and manifests need -o OUTDIR", code=2)
    if args.transform:
        return fail("--transform is for one INPUT; many write the transforms table (--table)", code=2)
    with _FailureLog():
        result = batch.run_batch(args.inputs, args.output, options, glob=args.glob, file_format=args.format,
                                 table=args.table, workers=args.workers, scheduler=args.scheduler,
                                 dask_local=args.dask_local, check=args.check or "mtime",
                                 fail_fast=args.fail_fast, force=args.force, shard=args.shard, timeout=args.timeout,
                                 progress=None if sys.stderr.isatty() else "lines")  # a bar; off a terminal, lines
    done = result.written + result.skipped
    rate = result.written / result.seconds if result.seconds > 0 else 0.0
    peaks = sorted(result.peak_mb.values())
    memory = f"; peak memory per worker {peaks[0]:.0f}-{peaks[-1]:.0f} MiB" if peaks else ""
    from ..evaluation.tables import counted  # (the one plural rule: "normalized 1 file")

    print(f"normalized {counted(result.written, 'file')} in {result.seconds:.1f} s ({rate:.1f}/s), "
          f"{result.skipped} already done{memory}; table {result.table}")
    if result.failed:
        first = next(r for r in result.rows if not r.ok)
        stop = "stopped at the first failure (--fail-fast)" if result.stopped else \
            f"{result.failed} of {result.failed + done} inputs failed"
        # named as its "jaxpose: failed:" line names it (a time limit's, a format's error names no file)
        error = first.error if first.error.startswith(first.input) else f"{first.input}: {first.error}"
        return fail(f"{stop}: {error} (all in {result.table})")
    return 0


class _FailureLog:
    """Failed inputs as lines on stderr ("jaxpose: failed: ..."), above the progress bar."""

    def __enter__(self):
        import logging

        from tqdm import tqdm

        class Handler(logging.Handler):
            def emit(self, record):
                tqdm.write(f"jaxpose: failed: {record.getMessage()}", file=sys.stderr)

        self.logger = logging.getLogger("jaxpose.batch")
        self.handler, self.propagate = Handler(logging.WARNING), self.logger.propagate
        self.logger.addHandler(self.handler)
        self.logger.propagate = False
        return self

    def __exit__(self, *exc):
        self.logger.removeHandler(self.handler)
        self.logger.propagate = self.propagate
        return False


def _flat(x):
    import numpy as np

    return np.asarray(x, dtype=float).reshape(-1)


def _print_transform(record, output, json_path):
    c = record["center"]
    uses_ocsvm = "ocsvm" in (record["center_method"], record["scale_method"])
    detail = f"  (gamma={record['gamma']:g}, nu={record['nu']:g})" if uses_ocsvm else ""
    print(f"method  center {record['center_method']}, scale {record['scale_method']}{detail}")
    print(f"center  [{c[0]: .6f} {c[1]: .6f} {c[2]: .6f}]")
    print(f"scale   {record['scale']:.6f}")
    if "rotation" in record:
        flag = "  FLAGGED: not well determined" if record["rotation_flagged"] else ""
        print(f"rotation {record['rotation_method']}, ambiguity {record['ambiguity']:.2f}{flag}")
        for row in record["rotation"]:
            print("  " + " ".join(f"{v: .6f}" for v in row))
    print("matrix")
    for row in record["matrix"]:
        print("  " + " ".join(f"{v: .6f}" for v in row))
    if output:
        print(f"wrote   {output}")
    if json_path is not None:
        print(f"wrote   {json_path}")


