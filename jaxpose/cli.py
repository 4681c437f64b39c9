"""Command line: ``jaxpose normalize | evaluate | tune | bench`` (also ``python -m jaxpose``).

Thin: parse arguments, call the library, print and write results. No math here.
Exit codes: 0 success, 1 failure (message on stderr, no traceback), 2 usage error.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from ._validate import JaxposeError

__all__ = ["main", "build_parser"]

EXAMPLE = "example"


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


def _add_normalize(sub):
    from .estimators import CENTERS, DEFAULT_METHOD, METHODS, SCALES
    from .mesh import SAMPLING
    from .rotation import ROTATIONS

    p = sub.add_parser("normalize", help="normalize the translation and scale of one mesh or point cloud")
    p.add_argument("input", nargs="?", help="mesh file (OBJ, PLY, OFF, STL, GLB, ...) or 'example'")
    p.add_argument("-o", "--output", help="normalized mesh to write (format from the extension)")
    p.add_argument("--example", action="store_true", help="use the built-in example shape as input")
    _add_svm_options(p)
    p.add_argument("--method", choices=tuple(METHODS), default=None,
                   help=f"center/scale method (default {DEFAULT_METHOD}; ocsvm is the paper's)")
    p.add_argument("--center", choices=CENTERS, default=None, help="center estimator (overrides --method's)")
    p.add_argument("--scale", choices=SCALES, default=None, help="scale estimator (overrides --method's)")
    p.add_argument("--strict", action="store_true", help="closed-surface estimators refuse open meshes")
    p.add_argument("--sampling", choices=SAMPLING, default="even", help="surface sampling (default even)")
    p.add_argument("--resolution", type=int, default=None, help="grid resolution of the volume moments")
    p.add_argument("--transform", help="where to write the transform JSON (default: OUTPUT.transform.json)")
    p.add_argument("--rotation", nargs="?", const="core", default=None, metavar="METHOD",
                   choices=ROTATIONS, help="also the canonical orientation (default method core; "
                                           f"{', '.join(ROTATIONS)}); off by default")
    p.add_argument("--force", action="store_true", help="overwrite existing outputs")
    p.set_defaults(handler=_cmd_normalize)


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
                        "method (comma-separated, default all: core,ocsvm,pca_vertices,pca_surface,inertia)")
    p.add_argument("--json", help="write the full result as JSON here")
    p.add_argument("--plots", help="write figures into this folder")
    p.add_argument("--force", action="store_true", help="overwrite an existing --json file")
    p.set_defaults(handler=_cmd_evaluate)


# ---- tune and bench: registered here, implemented in jaxpose.tuning / benchmarks/,
# which receive every argument after the command name (see _delegate).
_DELEGATED = ("tune", "bench")


def _add_tune(sub):
    p = sub.add_parser("tune", add_help=False, help="gradient-based tuning of gamma and nu (arguments go to jaxpose.tuning)")
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
    except KeyboardInterrupt:
        return _fail("interrupted", code=130)


def _fail(message, code=1):
    text = " ".join(str(message).split()) or "failed"
    print(f"jaxpose: error: {text}", file=sys.stderr)
    return code


# --------------------------------------------------------------------------- normalize
def transform_path(output) -> Path:
    """``out.ply`` -> ``out.transform.json``."""
    output = Path(output)
    return output.with_name(output.stem + ".transform.json")


def _cmd_normalize(args):
    from . import mesh

    source = args.input
    if args.example:
        if source is not None:
            return _fail("give either INPUT or --example, not both", code=2)
        source = EXAMPLE
    if source is None:
        return _fail("normalize needs an INPUT file (or --example)", code=2)
    use_example = source == EXAMPLE and not Path(source).exists()
    outputs = [Path(args.output)] if args.output else []
    json_path = Path(args.transform) if args.transform else (transform_path(args.output) if args.output else None)
    if json_path is not None:
        outputs.append(json_path)
    for path in outputs:  # refuse before any work is done
        if path.exists() and not args.force:
            return _fail(f"{path} exists (use --force to overwrite)")
    from .estimators import DEFAULT_METHOD, resolve

    center_name, scale_name = resolve(args.method, args.center, args.scale)
    geometry = mesh.example_shape() if use_example else source
    normalized, pose = mesh.normalize_mesh(
        geometry,
        gamma=args.gamma,
        nu=args.nu,
        count=args.count,
        seed=args.seed,
        sampling=args.sampling,
        method=args.method,
        center=args.center,
        scale=args.scale,
        strict=args.strict,
        resolution=args.resolution,
        rotation=args.rotation or False,
    )
    record = {
        "input": EXAMPLE if use_example else str(Path(source).resolve()),
        "method": args.method or DEFAULT_METHOD,
        "center_method": center_name,
        "scale_method": scale_name,
        "gamma": args.gamma,
        "nu": args.nu,
        "count": args.count,
        "seed": args.seed,
        "sampling": args.sampling,
        "center": [float(v) for v in _flat(pose.center)],
        "scale": float(_flat(pose.scale)[0]),
        "matrix": mesh.pose_matrix(pose).tolist(),
        "converged": bool(getattr(pose, "converged", True)),
    }
    if args.rotation:
        record.update(rotation_method=args.rotation, rotation=_flat(pose.rotation).reshape(3, 3).tolist(),
                      ambiguity=float(_flat(pose.ambiguity)[0]), rotation_flagged=bool(_flat(pose.ambiguity)[0] > 0))
    if args.output:
        mesh.export(normalized, args.output, force=args.force)
    if json_path is not None:
        mesh.write_atomic(json_path, json.dumps(record, indent=2) + "\n", force=args.force)
    _print_transform(record, args.output, json_path)
    if not record["converged"]:
        print("jaxpose: warning: the solver stopped at its iteration cap", file=sys.stderr)
    return 0


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
    if args.json:
        from .mesh import write_atomic

        write_atomic(args.json, json.dumps(result, indent=2) + "\n", force=args.force)
        print(f"wrote {args.json}")
    if args.plots:
        from . import plot

        plot.evaluation_figures(result, args.plots)
        print(f"wrote figures to {args.plots}")
    return 0


def _evaluate_rotation(args, classes, variants):
    from . import evaluation

    methods = None if args.rotation == "all" else [m for m in args.rotation.split(",") if m]
    with _ProgressBar() as progress:
        result = evaluation.evaluate_rotation(classes, methods=methods, variants=variants, align_core=args.align_core,
                                              seed=args.seed, progress=progress, frames=True,
                                              ocsvm={"gamma": args.gamma, "nu": args.nu, "count": args.count})
    print(evaluation.format_rotation_table(result))
    if args.json:
        from .mesh import write_atomic

        write_atomic(args.json, json.dumps(result, indent=2) + "\n", force=args.force)
        print(f"wrote {args.json}")
    if args.plots:
        from . import plot

        plot.rotation_figures(result, args.plots)
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
    return _delegate("tuning", args.extra)


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


def _delegate(module_name, argv):
    """Hand the remaining arguments to ``jaxpose.<module>.cli(argv) -> int``."""
    import importlib

    module = importlib.import_module(f"jaxpose.{module_name}")
    return module.cli(list(argv))
