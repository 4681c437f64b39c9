"""``jaxpose evaluate``: consistency of centers and scales (or canonical frames) per class, per input variant.

Thin: the arguments checked before any work (names, values, options the run would ignore, where
the results go), then :func:`jaxpose.evaluation.evaluate` (or ``evaluate_rotation``) with progress
on stderr, the files written, and the table with its legend on stdout.
"""
from __future__ import annotations

import sys
from pathlib import Path

from ..config import DATASET_INSTANCES
from .common import (add_core_options, add_svm_options, check_core_options, check_creatable, check_dataset_choice,
                     check_output_file, comma_names, dataset_classes, fail, given_names, json_text,
                     variant_names)

__all__ = ["add_parser", "run"]


def add_parser(sub):
    """Register ``evaluate`` on the sub-command parsers `sub`."""
    p = sub.add_parser("evaluate", help="consistency of centers and scales per class, per input variant",
                       description="Within-class spread of each method's centers (sigma_tr) and scales (cv_scale) "
                                   "on the built-in procedural dataset or --data, in seeded input variants. Progress "
                                   "on stderr; a table per variant and a legend on stdout.")
    p.add_argument("--data", help="folder of classes (one subfolder of meshes per class); default: procedural dataset")
    p.add_argument("--classes", help="comma-separated subset of the classes: of --data's class folders, or of the "
                                      "built-in dataset's 12 (default all)")
    p.add_argument("--instances", type=int, default=None,
                   help=f"built-in dataset: objects per class (default 10, at most {DATASET_INSTANCES})")
    add_core_options(p)
    add_svm_options(p)
    p.set_defaults(**dict.fromkeys(("gamma", "nu", "count")))  # None when not given: refused where nothing uses them
    p.add_argument("--methods", help="comma-separated methods, name or name:power, or all (default: all: every "
                                      "estimator, depth_weighted_solid at powers 2 and 4)")
    p.add_argument("--variants", default="all",
                   help="comma-separated input variants: plain,outliers,big_outliers,points,holes, or all (default)")
    p.add_argument("--sweep", action="store_true",
                   help="also sweep gamma and nu of the ocsvm method (a table per parameter after the variants'; "
                        "the paper's Fig. 5 and 6 with --plots)")
    p.add_argument("--rotation", nargs="?", const="all", default=None, metavar="METHODS",
                   help="measure canonical frames instead: angle to each class's mean frame per rotation "
                        "method (comma-separated, default all: core,head,ocsvm,pca_vertices,pca_surface,inertia)")
    p.add_argument("--per-class", action="store_true",
                   help="also print a table per class, every method side by side (an average can hide a class that loses)")
    p.add_argument("--json", help="write the full result as JSON here")
    p.add_argument("--plots", help="write figures into this folder")
    p.add_argument("--force", action="store_true", help="overwrite an existing --json file")
    p.set_defaults(handler=run)


_OCSVM_OPTIONS = ("gamma", "nu", "count")


def _evaluate_usage(args):
    """The evaluation's arguments checked and resolved before any work: (methods, variants, ocsvm
    options), or a usage error (exit 2) naming what is wrong."""
    from .._validate import check_names
    from ..evaluation.consistency import _check_methods, _check_variants
    from ..rotation.rotation import ROTATIONS
    from ..batch.task import NormalizeOptions

    # ('' ran every method, minutes of work; --rotation '' and --variants '' were "unknown ... []")
    methods = given_names(args.methods, "--methods", "method") if args.methods is not None else None
    methods = None if methods == ["all"] else methods  # as --variants all, --rotation all (was "unknown method")
    variants = variant_names(args.variants)
    _check_variants(variants)
    rotation = args.rotation is not None  # '--rotation ""' names no method: refused, not the center/scale run
    if rotation:
        ignored = [flag for flag, given in (("--methods", args.methods is not None), ("--sweep", args.sweep)) if given]
        if ignored:  # the frames' run reads neither (it measured the frames without a word)
            raise _Usage(f"{' and '.join(ignored)} {'choose' if len(ignored) > 1 else 'chooses'} what the center "
                         "and scale run measures; --rotation measures canonical frames instead (name its methods "
                         f"there: --rotation {','.join(ROTATIONS[:2])}), so drop {'them' if len(ignored) > 1 else 'it'}")
        rotations = _rotation_names(args.rotation) or list(ROTATIONS)
        unknown = [m for m in rotations if m not in ROTATIONS]
        if unknown:  # the evaluation's own check, before the dataset is made or read
            raise _Usage(f"--rotation: unknown rotation methods {unknown}; valid: all, {', '.join(ROTATIONS)}")
        check_names(rotations, "--rotation")  # (each once)
        uses_ocsvm = "ocsvm" in rotations
    else:
        names = [str(m).partition(":")[0] for m in _check_methods(methods)]
        uses_ocsvm = "ocsvm" in names or args.sweep
        swept = [name for name in ("gamma", "nu") if getattr(args, name) is not None]
        if args.sweep and "ocsvm" not in names and swept:  # the sweep sets them itself
            flags = ", ".join(f"--{name}" for name in swept)
            raise _Usage(f"{flags} {'apply' if len(swept) > 1 else 'applies'} to the ocsvm method (the paper's), which "
                         f"this evaluation does not run, and --sweep sets gamma and nu itself (add ocsvm to --methods, "
                         f"or leave {'them' if len(swept) > 1 else 'it'} out)")
    given = {name: getattr(args, name) for name in _OCSVM_OPTIONS if getattr(args, name) is not None}
    if given and not uses_ocsvm:
        flags = ", ".join(f"--{name}" for name in given)
        raise _Usage(f"{flags} {'apply' if len(given) > 1 else 'applies'} to the ocsvm method (the paper's), which "
                     f"this evaluation does not run (add ocsvm to {'--rotation' if rotation else '--methods'}"
                     f"{'' if rotation or {'gamma', 'nu'} & set(given) else ' or --sweep'}, or leave "
                     f"{'them' if len(given) > 1 else 'it'} out)")
    check_dataset_choice(args.instances, args.classes, args.data)  # (tune's check)
    check_core_options(args.align_core, args.core_weight)
    checked = NormalizeOptions(method="ocsvm", seed=args.seed, **given)  # gamma > 0, nu in [0, 1], count >= 4, seed
    # what was given, checked (the library fills in the defaults, and refuses what nothing reads)
    return methods, variants, {name: getattr(checked, name) for name in ("gamma", "nu", "count") if name in given}


class _Usage(Exception):
    """A usage error found by a command's own checks (exit 2)."""


def _check_result_paths(args):
    """--json and --plots: refused before the work (an existing file without --force, a folder
    that cannot be made or written: UsageError, exit 2; plots without matplotlib: exit 1)."""
    from ..errors import InvalidInputError, UsageError

    if args.json:
        check_output_file(args.json, args.force, "--json")
    if args.plots:
        folder = Path(args.plots)
        if folder.exists() and not folder.is_dir():
            raise UsageError(f"--plots {folder} is a file; name a folder")
        check_creatable(folder, f"--plots {folder}")
        try:
            import matplotlib  # noqa: F401
        except ImportError:
            raise InvalidInputError("--plots needs matplotlib (pip install matplotlib): plots not available") from None


def run(args):
    """Run ``jaxpose evaluate`` with parsed `args`. Returns the exit code."""
    from .. import evaluation
    from ..errors import InvalidInputError

    try:
        methods, variants, ocsvm = _evaluate_usage(args)
    except (_Usage, InvalidInputError) as exc:
        return fail(str(exc), code=2)
    _check_result_paths(args)
    names = comma_names(args.classes) if args.classes is not None else None
    classes = dataset_classes(args.data, names, args.seed, 10 if args.instances is None else args.instances)
    if args.rotation is not None:
        return _evaluate_rotation(args, classes, variants, ocsvm)
    with _ProgressBar() as progress:
        result = evaluation.evaluate(classes, seed=args.seed, align_core=args.align_core, core_weight=args.core_weight,
                                     progress=progress, sweep=args.sweep, methods=methods, variants=variants, **ocsvm)
    _write_result(args, result, "evaluation_figures")  # the files first: a reader that leaves early loses nothing
    print(evaluation.format_table(result))
    if args.per_class:
        print(evaluation.format_per_class(result))
    _say_written(args)
    return 0


def _rotation_names(text):
    """``--rotation``'s comma list: its names (:func:`given_names`: one that names none refused), or
    None for ``all`` alone (spaces and a trailing comma aside, as ``--variants`` and ``--methods``
    read it: ``'all,'`` was "unknown rotation methods ['all']")."""
    names = given_names(text, "--rotation", "rotation method")
    return None if names == ["all"] else names


def _evaluate_rotation(args, classes, variants, ocsvm):
    from .. import evaluation

    methods = _rotation_names(args.rotation)
    with _ProgressBar() as progress:
        result = evaluation.evaluate_rotation(classes, methods=methods, variants=variants, align_core=args.align_core,
                                              core_weight=args.core_weight, seed=args.seed, progress=progress,
                                              frames=True, ocsvm=ocsvm)
    _write_result(args, result, "rotation_figures")
    print(evaluation.format_rotation_table(result))
    if args.per_class:
        print(evaluation.format_rotation_per_class(result))
    _say_written(args)
    return 0


def _write_result(args, result, figures):
    """--json (atomic) and --plots (``jaxpose.plot.<figures>``) of an evaluation."""
    if args.json:
        from ..io.atomic import write_atomic

        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        write_atomic(args.json, json_text(result), force=args.force)
    if args.plots:
        from .. import plot

        getattr(plot, figures)(result, args.plots)


def _say_written(args):
    if args.json:
        print(f"wrote {args.json}")
    if args.plots:
        print(f"wrote figures to {args.plots}")


class _ProgressBar:
    """progress(done, total, message) on stderr: a tqdm bar on a terminal (rate and ETA), one line
    per step otherwise (a log, a pipe), so that a long run never looks stalled."""

    def __enter__(self):
        self.bar = None
        self.lines = not sys.stderr.isatty()
        return self

    def __call__(self, done, total, message):
        if self.lines:
            count = "" if total is None else f"[{done}/{total}] "
            print(f"jaxpose evaluate: {count}{message}", file=sys.stderr, flush=True)
            return
        from tqdm import tqdm

        if total is None:
            return
        if self.bar is None:
            self.bar = tqdm(total=total, unit="class", file=sys.stderr, disable=None, dynamic_ncols=True)
        self.bar.set_description_str(message)
        self.bar.update(done - self.bar.n)

    def __exit__(self, *exc):
        if self.bar is not None:
            self.bar.close()
        return False
