"""``jaxpose evaluate``: consistency of centers and scales (or canonical frames) per class, per input variant.

Thin: arguments to :func:`jaxpose.evaluation.evaluate` (or ``evaluate_rotation``), the table to
stdout, the result to ``--json`` and figures to ``--plots``.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

from .common import add_svm_options, fail

__all__ = ["add_parser", "run"]


def add_parser(sub):
    """Register ``evaluate`` on the sub-command parsers `sub`."""
    p = sub.add_parser("evaluate", help="consistency of centers and scales per class, per input variant")
    p.add_argument("--data", help="folder of classes (one subfolder of meshes per class); default: procedural dataset")
    p.add_argument("--align-core", action="store_true", help="align the rigid core of each class before measuring")
    add_svm_options(p, count=2000)
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
    p.set_defaults(handler=run)


def run(args):
    """Run ``jaxpose evaluate`` with parsed `args`. Returns the exit code."""
    from .. import datasets, evaluation

    if args.json and Path(args.json).exists() and not args.force:
        return fail(f"{args.json} exists (use --force to overwrite)")
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
    from .. import evaluation

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
        from ..io.atomic import write_atomic

        write_atomic(args.json, json.dumps(result, indent=2) + "\n", force=args.force)
        print(f"wrote {args.json}")
    if args.plots:
        from .. import plot

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
