"""``jaxpose tune``: load or make the classes, align and vary them, call :func:`jaxpose.tuning.tune`.

Thin: arguments to data, data to the library, the result to stdout and JSON. Exit codes: 0
success, 1 failure (message on stderr), 2 usage error.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..config import DATASET_INSTANCES, OCSVM, ROBUST, TUNE
from ..errors import InvalidInputError, JaxposeError  # (not _validate: it imports NumPy)
from .common import add_core_options, comma_names, fail

__all__ = ["add_parser", "run", "parser", "load_classes"]


def add_parser(sub):
    """Register ``tune`` on the sub-command parsers `sub`: every argument after it goes to :func:`run`."""
    p = sub.add_parser("tune", add_help=False, help="gradient-based tuning of gamma and nu (arguments go to jaxpose.cli.tune)")
    p.set_defaults(handler=_command)


def _command(args):
    return run(list(args.extra))


def parser():
    p = argparse.ArgumentParser(prog="jaxpose tune", description="gradient-based tuning of the OCSVM's gamma and "
                                "nu, or of the robust estimator's depth power, checked on held-out classes")
    p.add_argument("--data", default=None, help="folder with one sub-folder of meshes per class (default: the "
                   "built-in procedural dataset)")
    p.add_argument("--holdout-data", default=None, help="another such folder, only evaluated (e.g. another dataset)")
    p.add_argument("--holdout", type=float, default=None,
                   help="fraction of the classes held out of tuning (default 0.25 without --holdout-data, else 0)")
    add_core_options(p)
    p.add_argument("--variants", default="plain", help="comma list of input variants (plain, outliers, big_outliers, "
                   "points, holes), or all; each variant of a class counts as a class in the loss, and a class "
                   "held out (--holdout) is held out in every variant (default plain)")
    p.add_argument("--classes", default=None, help="comma-separated subset of the classes: of --data's class folders "
                   "(not --holdout-data's), or of the built-in dataset's 12 (default all)")
    p.add_argument("--instances", type=int, default=None,  # None: not given (refused with --data, as evaluate's)
                   help=f"built-in dataset: objects per class (default {TUNE.instances}, at most {DATASET_INSTANCES})")
    p.add_argument("--steps", type=int, default=TUNE.steps, help=f"Adam steps (default {TUNE.steps})")
    p.add_argument("--lr", type=float, default=TUNE.lr,
                   help=f"Adam's learning rate in (log gamma, logit nu) or log power (default {TUNE.lr:g})")
    p.add_argument("--reg", type=float, default=TUNE.reg, help="pull towards the start (share of the start loss per "
                   f"unit of log gamma / logit nu squared; default {TUNE.reg:g})")
    p.add_argument("--count", type=int, default=TUNE.count,
                   help=f"surface samples per object, drawn afresh at every step (default {TUNE.count})")
    p.add_argument("--seed", type=int, default=0, help="seed of the samples, the variants and the held-out split "
                   "(default 0)")
    p.add_argument("--scale-weight", type=float, default=TUNE.scale_weight, help="weight of the scale's spread (cv) in "
                   f"the loss, beside the center's sigma_tr (default {TUNE.scale_weight:g}: the center only)")
    p.add_argument("--method", choices=("ocsvm", "robust"), default="ocsvm",
                   help="what to tune: the OCSVM's gamma and nu (default), or the robust estimator's depth power "
                   "(on the objects' surface samples as point clouds)")
    p.add_argument("--gamma", type=float, default=None, help=f"ocsvm: starting gamma, the paper's (default {OCSVM.gamma:g})")
    p.add_argument("--nu", type=float, default=None, help=f"ocsvm: starting nu, the paper's (default {OCSVM.nu:g})")
    p.add_argument("--power", type=float, default=None, help=f"robust: starting depth power (default {ROBUST.power:g})")
    p.add_argument("--resolution", type=int, default=None, help="ocsvm: grid cells per axis of the volume integral "
                   "during tuning (default 16; normalize's default is 64); robust: voxels along the body (default 96)")
    p.add_argument("--refine", type=int, default=None, help="ocsvm: a power of 2: cells near the boundary split "
                   "2x2x2, log2(refine) times (default 2)")
    p.add_argument("--band", type=int, default=None, help="ocsvm: boundary cells refined at the first level, doubled "
                   "at each further level (default 2048)")
    p.add_argument("--tol", type=float, default=None, help="ocsvm: SVDD solver tolerance (default 1e-3)")
    p.add_argument("--solver", choices=("pg", "smo", "auto"), default=None,
                   help="ocsvm: SVDD solver (default: normalize's, pg up to 2500 points, auto above)")
    p.add_argument("--json", default=None, help="write the result here (trajectory, train and held-out spreads)")
    p.add_argument("--force", action="store_true", help="overwrite an existing --json file")
    return p


def load_classes(folder, names=None, align_core=False, variants=("plain",), seed=0, instances=TUNE.instances,
                 core_weight="vertices"):
    """{class[/variant]: [mesh, ...]} from a folder of class sub-folders (None: the procedural dataset),
    optionally rigid-core aligned (the core a share of ``core_weight``: "vertices" or "area"), in each input variant (:mod:`jaxpose.evaluation.variants`);
    ``names``: the classes to take (None: every class), as ``jaxpose evaluate --classes`` takes them
    (:func:`jaxpose.cli.common.dataset_classes`)."""
    from ..evaluation import alignment
    from ..evaluation.consistency import _check_variants
    from ..evaluation.variants import make_class
    from .common import dataset_classes

    _check_variants(variants)  # unknown, or one named twice (its classes were one, made twice)
    meshes = dataset_classes(folder, names, seed, instances)  # (evaluate's --data and --classes too)
    if align_core:
        meshes = alignment.align_classes(meshes, weight=core_weight)
    out = {}
    for variant in variants:
        for k, (name, objs) in enumerate(meshes.items()):
            out[name if variants == ("plain",) else f"{name}/{variant}"] = make_class(objs, variant, seed, k)
    return out


def run(argv) -> int:
    """Parse ``argv``, tune, print a summary (progress on stderr), write --json. -> exit code."""
    args_parser = parser()
    try:
        args = args_parser.parse_args(list(argv))
    except SystemExit as exc:
        return int(exc.code or 0)
    if args.json:  # before minutes of work, not after
        from ..errors import InvalidInputError
        from .common import check_output_file

        try:
            check_output_file(args.json, args.force, "--json")
        except InvalidInputError as exc:
            return fail(exc, code=2)  # a usage error, as the other checks before the work
    import jax

    # float64: the trend derivatives are differences of solutions 2 % apart
    x64 = jax.config.jax_enable_x64
    jax.config.update("jax_enable_x64", True)
    try:
        return _run(args)
    finally:
        jax.config.update("jax_enable_x64", x64)


def _run(args) -> int:
    from ..mesh import write_atomic
    from ..tuning import check_options, tune
    from .common import check_core_options, check_dataset_choice, check_folder_name, json_text, variant_names

    say = lambda s: print(s, file=sys.stderr, flush=True)
    try:
        options = _method_options(args)
        check_options(args.method, args.steps, args.lr, args.reg, args.scale_weight,
                      args.holdout if args.holdout is not None else 0.0, args.seed, args.count,
                      **{k: v for k, v in options.items() if k in ("gamma0", "nu0", "power0")})
        check_dataset_choice(args.instances, args.classes, args.data)  # (evaluate's check)
        check_folder_name(args.holdout_data, "--holdout-data")
        check_core_options(args.align_core, args.core_weight)
        variants = tuple(variant_names(args.variants))
        names = comma_names(args.classes) if args.classes else None
        _check_choices(args, options, variants)
    except InvalidInputError as exc:  # a usage error: before any work
        return fail(_flag_names(str(exc)), code=2)
    try:
        for flag, folder in (("--data", args.data), ("--holdout-data", args.holdout_data)):
            if folder is not None and not Path(folder).is_dir():  # (--holdout-data's after loading --data's classes)
                raise InvalidInputError(f"{flag} {folder} is not a folder")
        say("loading classes ...")
        classes = load_classes(args.data, names, args.align_core, variants, args.seed,
                               TUNE.instances if args.instances is None else args.instances, args.core_weight)
        held = (load_classes(args.holdout_data, None, args.align_core, variants, args.seed, core_weight=args.core_weight)
                if args.holdout_data else None)
        holdout = args.holdout if args.holdout is not None else (0.0 if held else 0.25)
        # a class's variants ("dog/plain", "dog/holes") are one class: held out together
        base = {name: name.rpartition("/")[0] if len(variants) > 1 else name for name in classes}
        if holdout > 0 and len(set(base.values())) < 2:  # (the library's words name its arguments, not these flags)
            chosen = f"--classes {args.classes} chooses" if args.classes else f"{args.data or 'the dataset'} has"
            return fail(f"--holdout {holdout:g} holds out whole classes, and {chosen} one "
                        f"({', '.join(map(repr, sorted(set(base.values()))))}): pass --holdout 0 to tune on it alone "
                        + ("(--holdout-data's classes check it)" if held else
                           "(checked on a fresh draw), or --holdout-data DIR for classes to check on"))
        fraction = holdout
        if holdout > 0 and len(variants) > 1:  # split by class, not by class/variant (a variant of a trained class
            from ..tuning import _split        # was held out: the verdict judged the tuner on what it had seen)

            _, out = _split(dict.fromkeys(sorted(set(base.values()))), holdout, args.seed)
            split = {name: objs for name, objs in classes.items() if base[name] in out}
            classes = {name: objs for name, objs in classes.items() if base[name] not in out}
            other = {(k if k not in split else f"{k} ({args.holdout_data})"): v for k, v in (held or {}).items()}
            held = {**split, **other}
            holdout = 0.0
        result = tune(classes, steps=args.steps, lr=args.lr, reg=args.reg, scale_weight=args.scale_weight,
                      holdout=holdout, holdout_classes=held, seed=args.seed, count=args.count, progress=say,
                      method=args.method, **options)
    except JaxposeError as exc:
        return fail(exc)
    result["data"] = dict(data=args.data, holdout_data=args.holdout_data, align_core=bool(args.align_core),
                          core_weight=args.core_weight, variants=list(variants), holdout=fraction)
    failure = _failure(result, args.method, args.count, args.resolution, args.power)
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        write_atomic(args.json, json_text(result).encode(), force=True)  # checked before the run
    if failure:
        return fail(failure)
    tr, ho = result["train"], result["holdout"]
    print(", ".join(f"{k} {result[k + '0']:.4g} -> {v:.4g}" for k, v in result["tuned"].items()))
    print(f"train sigma_tr {tr['sigma_tr_start']:.5g} -> {tr['sigma_tr_tuned']:.5g}")
    if ho:
        print(f"held-out sigma_tr {ho['sigma_tr_start']:.5g} -> {ho['sigma_tr_tuned']:.5g}")
    print(result["verdict"])
    print("use: " + ", ".join(f"{k} {result[k]:.4g}" for k in result["tuned"]))
    return 0


_FLAGS = {"gamma0": "--gamma", "nu0": "--nu", "power0": "--power", "scale_weight": "--scale-weight"}
"""The library's names of :func:`jaxpose.tuning.check_options`' arguments that the command line spells
otherwise: its refusals name the option as typed ("--gamma must be ...", not "gamma0 must be ...")."""


def _flag_names(message):
    """`message` with a leading argument name of the library in :data:`_FLAGS` as its option's."""
    name, space, rest = message.partition(" ")
    return f"{_FLAGS[name]} {rest}" if space and name in _FLAGS else message


def _failure(result, method, count=TUNE.count, resolution=None, power=None):
    """None, or the command's one-line error for a run that tuned nothing (no step had every pose
    valid: :func:`jaxpose.tuning.tune`'s ``error``), with the options to try, each with the value
    the run had (``count``, ``resolution``, ``power``: the run's ``--count``, ``--resolution`` and
    ``--power``, None where not given: their defaults)."""
    if not result.get("error"):
        return None
    if method == "robust":  # (its reasons are the solid's, which the power does not change: the samples, the grid)
        from ..config import RobustConfig

        grid = RobustConfig().resolution if resolution is None else resolution
        hint = (f"draw more samples (--count, now {count}) or give another --resolution (now {grid}: voxels along "
                f"the body), or start from another --power (now {ROBUST.power if power is None else power:g})")
    else:
        hint = (f"start nearer the defaults (--gamma {OCSVM.gamma:g} --nu {OCSVM.nu:g}) or draw more samples "
                f"(--count, now {count})")
    return f"{result['error']}; {hint}"


def _check_choices(args, options, variants):
    """What the run would refuse only after loading the classes, refused before (InvalidInputError,
    a usage error): the variants, the grid and solver options
    (``--resolution``, ``--refine``, ``--band``, ``--tol``; the robust method's ``--resolution``)."""
    from ..config import PoseConfig, RobustConfig
    from ..evaluation.consistency import _check_variants

    _check_variants(variants)
    grid = {k: v for k, v in options.items() if k not in ("gamma0", "nu0", "power0")}
    (RobustConfig if args.method == "robust" else PoseConfig).create(**grid)


# the command's own defaults for tuning (a coarse OCSVM grid); the parameters' defaults are config's
_OCSVM_DEFAULTS = {"gamma": OCSVM.gamma, "nu": OCSVM.nu, "resolution": 16, "refine": 2, "band": 2048, "tol": 1e-3,
                   "solver": None}
_ROBUST_DEFAULTS = {"power": ROBUST.power}


def _method_options(args):
    """The keywords of :func:`jaxpose.tuning.tune` for ``args.method``; an option of the other
    method raises InvalidInputError naming the method it belongs to."""
    own = _ROBUST_DEFAULTS if args.method == "robust" else _OCSVM_DEFAULTS
    other, other_name = (_OCSVM_DEFAULTS, "ocsvm") if args.method == "robust" else (_ROBUST_DEFAULTS, "robust")
    for key in other:
        if key not in own and key != "resolution" and getattr(args, key) is not None:
            raise InvalidInputError(f"--{key} is an option of --method {other_name}; --method "
                                              f"{args.method} does not use it")
    out = {k: (getattr(args, k) if getattr(args, k) is not None else v) for k, v in own.items()}
    if args.method == "robust":
        out = {"power0": out["power"], **({"resolution": args.resolution} if args.resolution is not None else {})}
    else:
        out = {"gamma0": out.pop("gamma"), "nu0": out.pop("nu"), **out}
    return out
