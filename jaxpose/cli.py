"""Command line: ``jaxpose normalize | evaluate | tune | bench`` (also ``python -m jaxpose``).

Thin: parse arguments, call the library, print and write results. No math here.
Exit codes: 0 success, 1 failure (one line on stderr, no traceback), 2 usage error, 130 Ctrl-C,
143 SIGTERM (:mod:`jaxpose.interrupts`; nothing partial or temporary is left).
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from .errors import JaxposeError

__all__ = ["main", "console", "build_parser"]


# --------------------------------------------------------------------------- parser
def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="jaxpose",
        description="Consistent translation and scale (and orientation) normalization of 3D shapes with one-class SVMs.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    _add_normalize(sub)
    _add_evaluate(sub)
    _add_tune(sub)
    _add_bench(sub)
    return parser


def _add_svm_options(p, count=2000):
    p.add_argument("--gamma", type=float, default=47.0, help="Gaussian kernel width (dimensionless, default 47)")
    p.add_argument("--nu", type=float, default=0.5, help="OCSVM slack in [0, 1] (default 0.5)")
    p.add_argument("--count", type=int, default=count, help=f"surface samples per object (default {count})")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")


def _add_evaluate(sub):
    p = sub.add_parser("evaluate", help="consistency of centers and scales per class, per input variant")
    p.add_argument("--data", help="folder of classes (one subfolder of meshes per class); default: procedural dataset")
    p.add_argument("--align-core", action="store_true", help="align the rigid core of each class before measuring")
    _add_svm_options(p, count=2000)
    p.add_argument("--methods", help="comma-separated methods, name or name:power (default: all)")
    p.add_argument("--variants", default="plain",
                   help="comma-separated input variants: plain,outliers,big_outliers,points,holes (default plain)")
    p.add_argument("--sweep", action="store_true", help="also sweep gamma and nu of the ocsvm method")
    p.add_argument("--rotation", nargs="?", const="all", default=None, metavar="METHODS",
                   help="measure canonical frames instead: angle to each class's mean frame per rotation "
                        "method (comma-separated, default all: core,head,ocsvm,pca_vertices,pca_surface,inertia)")
    p.add_argument("--per-class", action="store_true",
                   help="also print a table per class, every method side by side (an average can hide a class that loses)")
    p.add_argument("--json", help="write the full result as JSON here")
    p.add_argument("--plots", help="write figures into this folder")
    p.add_argument("--force", action="store_true", help="overwrite an existing --json file")
    p.set_defaults(handler=_cmd_evaluate)


# ---- tune and bench: registered here, implemented in jaxpose.tuning_cli / benchmarks/,
# which receive every argument after the command name (see _cmd_tune, _cmd_bench).
_DELEGATED = ("tune", "bench")


def _add_tune(sub):
    p = sub.add_parser("tune", add_help=False, help="gradient-based tuning of gamma and nu (arguments go to jaxpose.tuning_cli)")
    p.set_defaults(handler=_cmd_tune)


def _add_bench(sub):
    p = sub.add_parser("bench", add_help=False, help="timings against scikit-learn, from a source checkout (arguments go to benchmarks/)")
    p.set_defaults(handler=_cmd_bench)


# --------------------------------------------------------------------------- main
def main(argv=None) -> int:
    """Run the command line; returns the exit code (argparse usage errors exit with 2)."""
    parser = build_parser()
    args, extra = parser.parse_known_args(argv)
    if extra and args.command not in _DELEGATED:
        parser.error(f"unrecognized arguments: {' '.join(extra)}")
    args.extra = extra
    try:
        return int(args.handler(args) or 0)
    except JaxposeError as exc:
        return _fail(str(exc))
    except (OSError, ValueError) as exc:  # file system and number trouble outside the library
        return _fail(f"{type(exc).__name__}: {exc}")
    except KeyboardInterrupt as exc:
        return _interrupted(exc)


def _interrupted(exc):
    from .interrupts import Terminated

    if isinstance(exc, Terminated):
        return _fail("terminated (SIGTERM); nothing partial was left", code=143)
    return _fail("interrupted; nothing partial was left", code=130)


def console():
    """The ``jaxpose`` command (and ``python -m jaxpose``): :func:`main` under a signal guard.

    Ends the process with ``os._exit`` (:func:`jaxpose.interrupts.leave`): the exit code of
    :func:`main`, or 128 + the signal when Ctrl-C or SIGTERM came at any moment of the run.
    """
    from . import interrupts, workers

    code = 1
    with interrupts.SignalGuard() as guard:
        try:
            # before anything imports NumPy or JAX: the compilation cache; for normalize also one
            # BLAS thread, as in its worker processes (the same bits whichever process computes)
            workers.configure_process(one_thread=sys.argv[1:2] == ["normalize"])
            code = main()
        except SystemExit as exc:  # argparse: --help (0), usage errors (2)
            code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else _fail(exc.code))
        except KeyboardInterrupt as exc:  # landed outside main's own handling
            code = _interrupted(exc)
        if guard.received is not None and code != guard.exit_code:
            code = _fail("interrupted after the work was done", code=guard.exit_code)
        interrupts.leave(code)


def _fail(message, code=1):
    text = " ".join(str(message).split()) or "failed"
    print(f"jaxpose: error: {text}", file=sys.stderr)
    return code


# --------------------------------------------------------------------------- normalize
def _add_normalize(sub):
    from .cli_normalize import add_parser

    add_parser(sub, _add_svm_options, _cmd_normalize)


def _cmd_normalize(args):
    from .cli_normalize import run

    return run(args, _fail)


# --------------------------------------------------------------------------- evaluate
def _cmd_evaluate(args):
    from . import datasets, evaluation

    if args.json and Path(args.json).exists() and not args.force:
        return _fail(f"{args.json} exists (use --force to overwrite)")
    methods = [m for m in args.methods.split(",") if m] if args.methods else None
    variants = [v for v in args.variants.split(",") if v]
    if args.data:
        classes = datasets.load_folder(args.data)
    else:
        classes = datasets.make_dataset(seed=args.seed)
    if args.rotation:
        return _evaluate_rotation(args, classes, variants)
    with _ProgressBar() as progress:
        result = evaluation.evaluate(
            classes,
            gamma=args.gamma,
            nu=args.nu,
            count=args.count,
            seed=args.seed,
            align_core=args.align_core,
            progress=progress,
            sweep=args.sweep,
            methods=methods,
            variants=variants,
        )
    print(evaluation.format_table(result))
    if args.per_class:
        print(evaluation.format_per_class(result))
    return _write_result(args, result, "evaluation_figures")


def _evaluate_rotation(args, classes, variants):
    from . import evaluation

    methods = None if args.rotation == "all" else [m for m in args.rotation.split(",") if m]
    with _ProgressBar() as progress:
        result = evaluation.evaluate_rotation(classes, methods=methods, variants=variants, align_core=args.align_core,
                                              seed=args.seed, progress=progress, frames=True,
                                              ocsvm={"gamma": args.gamma, "nu": args.nu, "count": args.count})
    print(evaluation.format_rotation_table(result))
    if args.per_class:
        print(evaluation.format_rotation_per_class(result))
    return _write_result(args, result, "rotation_figures")


def _write_result(args, result, figures):
    """--json (atomic) and --plots (``jaxpose.plot.<figures>``) of an evaluation."""
    if args.json:
        from .atomic import write_atomic

        write_atomic(args.json, json.dumps(result, indent=2) + "\n", force=args.force)
        print(f"wrote {args.json}")
    if args.plots:
        from . import plot

        getattr(plot, figures)(result, args.plots)
        print(f"wrote figures to {args.plots}")
    return 0


class _ProgressBar:
    """progress(done, total, message) as a tqdm bar on a terminal (rate and ETA), silent otherwise."""

    def __enter__(self):
        self.bar = None
        return self

    def __call__(self, done, total, message):
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


# --------------------------------------------------------------------------- tune / bench
def _cmd_tune(args):
    from .tuning_cli import run

    return run(list(args.extra))


def _cmd_bench(args):
    """The benchmarks live beside the package in a source checkout (``benchmarks/``)."""
    import importlib
    import sys as _sys

    root = Path(__file__).resolve().parents[1]
    if not (root / "benchmarks" / "__init__.py").is_file():
        return _fail(f"the benchmarks are not installed with the package; run them from a source checkout "
                     f"(no {root / 'benchmarks'})")
    if str(root) not in _sys.path:
        _sys.path.insert(0, str(root))
    return importlib.import_module("benchmarks").cli(list(args.extra))
