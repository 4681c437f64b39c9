"""Gradient-based tuning of (gamma, nu) for consistent centers.

Objective: the average over classes of the within-class dispersion of the center,

    sigma_tr = mean_classes sqrt(mean_objects ||c_i - c_bar||^2)

(centers in the units of each object; objects of one class should share a frame),
plus ``scale_weight`` times the mean over classes of the coefficient of variation of
the scale. Minimized with optax.adam in unconstrained coordinates
(log gamma, logit nu), starting at the paper's (47, 0.5). d/dgamma is the exact
implicit derivative, d/dnu the secant slope over nu (1 +- 1.5 %) (see
``jaxpose.sensitivity``).

Every object of a class is sampled with the same point count, so a class is one
stacked (n, m, 3) array and the pose is ``jax.vmap`` of ``pose.pose_pipeline``
with a static config: the objective and its gradient are compiled once per class
shape and never re-traced inside the loop.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from . import _validate
from .config import PoseConfig
from .pose import pose_pipeline
from .sensitivity import NU_DELTA

__all__ = ["tune", "objective", "cli"]

_NU_MIN, _NU_MAX = 0.02, 0.98  # keep the secant interval inside (0, 1)


def _from_theta(theta):
    gamma = jnp.exp(theta[0])
    nu = _NU_MIN + (_NU_MAX - _NU_MIN) * jax.nn.sigmoid(theta[1])
    return gamma, nu


def _logit(x):
    return math.log(x / (1.0 - x))


def _start_theta(gamma0, nu0):
    u = (nu0 - _NU_MIN) / (_NU_MAX - _NU_MIN)
    if not 0.0 < u < 1.0:
        raise _validate.InvalidInputError(f"nu0 must be in ({_NU_MIN}, {_NU_MAX}), got {nu0}")
    return jnp.asarray([math.log(gamma0), _logit(u)])


def _class_stats(points, gamma, nu, config):
    """points (n, m, 3) -> (sigma_tr, cv of scale, all valid) for one class."""
    fn = lambda p: pose_pipeline(p, None, gamma, nu, config)
    pose = jax.vmap(fn)(points)
    c = pose.center
    d = c - jnp.mean(c, axis=0)
    sigma = jnp.sqrt(jnp.mean(jnp.sum(d * d, axis=-1)))
    s = pose.scale
    cv = jnp.std(s) / jnp.mean(s)
    return sigma, cv, jnp.all(pose.valid)


def _make_loss(config, scale_weight):
    @jax.jit
    def class_loss(theta, points):
        gamma, nu = _from_theta(theta)
        sigma, cv, ok = _class_stats(points, gamma, nu, config)
        return sigma + scale_weight * cv, (sigma, cv, ok)

    def value_and_grad(theta, points):
        # Forward mode: two parameters, so a JVP with 2 tangents is cheaper than reverse mode
        # (see jaxpose._hyper).
        J, (loss, aux) = jax.jacfwd(lambda t: (lambda r: (r[0], r))(class_loss(t, points)), has_aux=True)(theta)
        return (loss, aux), J

    return class_loss, jax.jit(value_and_grad)


def _stack(classes, name):
    out = {}
    for cname, objs in classes.items():
        arrs = [np.asarray(_validate.check_points(o, name=f"{name}[{cname!r}]")) for o in objs]
        if len(arrs) < 2:
            raise _validate.InvalidInputError(f"class {cname!r} needs at least 2 objects, got {len(arrs)}")
        counts = {a.shape[0] for a in arrs}
        if len(counts) != 1:
            raise _validate.InvalidInputError(f"class {cname!r}: all objects must have the same point count, got {sorted(counts)}")
        out[cname] = jnp.asarray(np.stack(arrs))
    if not out:
        raise _validate.InvalidInputError("tune needs at least one class")
    return out


def _split(classes, holdout, seed):
    """Hold out round(holdout * n_classes) whole classes (at least 1, leaving at least 1)."""
    if holdout <= 0:
        return classes, {}
    if not holdout < 1:
        raise _validate.InvalidInputError(f"holdout must be in [0, 1), got {holdout}")
    names = sorted(classes)
    if len(names) < 2:
        raise _validate.InvalidInputError(f"holdout needs at least 2 classes, got {len(names)}")
    k = min(max(int(round(holdout * len(names))), 1), len(names) - 1)
    held = set(np.random.default_rng(seed).permutation(len(names))[:k].tolist())
    train = {n: classes[n] for i, n in enumerate(names) if i not in held}
    test = {n: classes[n] for i, n in enumerate(names) if i in held}
    return train, test


def objective(stacked, theta, class_loss):
    """Mean over classes of (loss, sigma_tr, cv) at theta; python floats."""
    vals = [class_loss(theta, p) for p in stacked.values()]
    loss = float(np.mean([float(v[0]) for v in vals]))
    sigma = float(np.mean([float(v[1][0]) for v in vals]))
    cv = float(np.mean([float(v[1][1]) for v in vals]))
    return loss, sigma, cv


def tune(classes, gamma0=47.0, nu0=0.5, steps=20, lr=0.05, scale_weight=0.0, holdout=0.0, seed=0,
         progress=None, nu_delta=NU_DELTA, **normalize_options) -> dict:
    """Tune (gamma, nu) by gradient descent on the mean within-class center dispersion.

    classes : {name: [(m, 3) arrays]} (same m within a class; at least 2 objects each)
    gamma0, nu0 : start (the paper's 47, 0.5); steps, lr : optax.adam steps and initial rate
        (cosine decay to lr / 10 over the steps)
    scale_weight : weight of the mean coefficient of variation of the scale
    holdout : fraction of the classes kept out of tuning (whole classes: at least one
        is held out and one kept), evaluated at the start and the end only; seed : split seed
    progress : optional callable(str) told about every step
    normalize_options : static options of ``normalize`` (resolution, refine, band, tol, ...)

    Returns a JSON-able dict: gamma, nu (best training loss seen), start and end
    train/held-out sigma_tr, the trajectory [{step, gamma, nu, loss, sigma_tr, cv_scale}],
    timing.
    """
    import optax

    config = PoseConfig.create(**{**normalize_options, "derivative": "secant", "nu_delta": nu_delta})
    _validate.check_gamma(gamma0)
    _validate.check_nu(nu0)
    if int(steps) < 0:
        raise _validate.InvalidInputError(f"steps must be >= 0, got {steps}")
    train, test = _split(dict(classes), float(holdout), int(seed))
    train_s = _stack(train, "classes")
    test_s = _stack(test, "classes") if test else {}
    class_loss, class_vg = _make_loss(config, float(scale_weight))
    say = progress or (lambda _msg: None)

    theta = _start_theta(float(gamma0), float(nu0))
    # Adam's steps keep their size (~lr in log gamma) until the gradient changes sign, so with a
    # constant rate it overshot the valley (measured: best at step 7, then 1.5 % worse); the rate
    # decays to lr / 10 along a cosine.
    opt = optax.adam(optax.cosine_decay_schedule(float(lr), max(int(steps), 1), alpha=0.1))
    state = opt.init(theta)
    update = jax.jit(opt.update)
    trajectory = []
    t0 = time.perf_counter()
    best = None
    for step in range(int(steps) + 1):
        vals = [class_vg(theta, p) for p in train_s.values()]
        loss = float(np.mean([float(v[0][0]) for v in vals]))
        sigma = float(np.mean([float(v[0][1][0]) for v in vals]))
        cv = float(np.mean([float(v[0][1][1]) for v in vals]))
        valid = all(bool(v[0][1][2]) for v in vals)
        grad = sum(v[1] for v in vals) / len(vals)
        g, n = _from_theta(theta)
        rec = dict(step=step, gamma=float(g), nu=float(n), loss=loss, sigma_tr=sigma, cv_scale=cv, valid=valid,
                   grad=[float(x) for x in grad])
        trajectory.append(rec)
        say(f"step {step}: gamma={rec['gamma']:.3f} nu={rec['nu']:.4f} sigma_tr={sigma:.5g} loss={loss:.5g}")
        if valid and np.isfinite(loss) and (best is None or loss < best[0]):
            best = (loss, theta)
        if step == int(steps):
            break
        if not bool(jnp.all(jnp.isfinite(grad))):
            say("non-finite gradient; stopping")
            break
        upd, state = update(grad, state, theta)
        theta = optax.apply_updates(theta, upd)
    elapsed = time.perf_counter() - t0
    best_theta = best[1] if best is not None else theta
    start_theta = _start_theta(float(gamma0), float(nu0))
    g_best, n_best = _from_theta(best_theta)
    result = dict(
        gamma=float(g_best), nu=float(n_best),
        gamma0=float(gamma0), nu0=float(nu0),
        train=dict(sigma_tr_start=trajectory[0]["sigma_tr"],
                   sigma_tr_end=objective(train_s, best_theta, class_loss)[1],
                   classes=len(train_s), objects=int(sum(p.shape[0] for p in train_s.values())),
                   names=sorted(train_s)),
        holdout=None,
        trajectory=trajectory,
        steps=int(steps), lr=float(lr), scale_weight=float(scale_weight), seed=int(seed),
        options=config.flat(), nu_delta=float(nu_delta),
        seconds=elapsed,
    )
    if test_s:
        result["holdout"] = dict(sigma_tr_start=objective(test_s, start_theta, class_loss)[1],
                                 sigma_tr_end=objective(test_s, best_theta, class_loss)[1],
                                 classes=len(test_s), objects=int(sum(p.shape[0] for p in test_s.values())),
                                 names=sorted(test_s))
    return result


# --------------------------------------------------------------------------- command line
def _parser():
    p = argparse.ArgumentParser(prog="jaxpose tune", description="gradient-based tuning of gamma and nu")
    p.add_argument("--data", default=None, help="folder of class subfolders of meshes (default: procedural dataset)")
    p.add_argument("--steps", type=int, default=20)
    p.add_argument("--lr", type=float, default=0.05)
    p.add_argument("--holdout", type=float, default=0.0, help="fraction of the classes held out of tuning")
    p.add_argument("--json", default=None, help="write the result here")
    p.add_argument("--force", action="store_true", help="overwrite an existing --json file")
    p.add_argument("--count", type=int, default=500, help="surface samples per object")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--scale-weight", type=float, default=0.0)
    p.add_argument("--gamma", type=float, default=47.0)
    p.add_argument("--nu", type=float, default=0.5)
    p.add_argument("--resolution", type=int, default=16)
    p.add_argument("--refine", type=int, default=2)
    p.add_argument("--band", type=int, default=2048)
    p.add_argument("--tol", type=float, default=1e-4)
    p.add_argument("--solver", choices=("pg", "smo", "auto"), default=None,
                   help="SVDD solver (default: normalize's, pg up to 2500 points, auto above)")
    p.add_argument("--classes", default=None, help="comma-separated subset of classes")
    p.add_argument("--instances", type=int, default=10, help="objects per class (procedural dataset)")
    return p


def cli(argv) -> int:
    """``jaxpose tune [--data DIR] [--steps N] [--lr X] [--holdout F] [--json PATH [--force]] [--count N]
    [--seed S] [--solver pg|smo|auto] ...``."""
    parser = _parser()
    try:
        args = parser.parse_args(list(argv))
    except SystemExit as exc:
        return int(exc.code or 0)
    if args.json and Path(args.json).exists() and not args.force:  # before minutes of work, not after
        print(f"jaxpose tune: error: {args.json} exists (use --force to overwrite)", file=sys.stderr)
        return 1
    # float64: the secant nu-derivative is a difference of two solutions 3 % of nu apart,
    # and float32 solver noise (tol >= 1e-5) is a sizeable part of it.
    x64 = jax.config.jax_enable_x64
    jax.config.update("jax_enable_x64", True)
    try:
        return _run_cli(args)
    finally:
        jax.config.update("jax_enable_x64", x64)


def _run_cli(args) -> int:
    try:
        from . import datasets
        from .mesh import sample_surface, write_atomic

        if args.data:
            meshes = datasets.load_folder(args.data)
        else:
            names = args.classes.split(",") if args.classes else None
            meshes = datasets.make_dataset(args.seed, instances=args.instances, classes=names)
        if args.classes and args.data:
            keep = set(args.classes.split(","))
            meshes = {k: v for k, v in meshes.items() if k in keep}
        classes = {name: [sample_surface(m, args.count, seed=args.seed + i) for i, m in enumerate(objs)]
                   for name, objs in meshes.items()}
        result = tune(classes, gamma0=args.gamma, nu0=args.nu, steps=args.steps, lr=args.lr,
                      scale_weight=args.scale_weight, holdout=args.holdout, seed=args.seed,
                      progress=lambda s: print(s, file=sys.stderr, flush=True),
                      resolution=args.resolution, refine=args.refine, band=args.band, tol=args.tol,
                      solver=args.solver)
    except _validate.JaxposeError as exc:
        print(f"jaxpose tune: error: {exc}", file=sys.stderr)
        return 1
    text = json.dumps(result, indent=2)
    if args.json:
        write_atomic(args.json, text.encode(), force=True)  # checked before the run
    tr, ho = result["train"], result["holdout"]
    print(f"gamma {result['gamma0']:.4g} -> {result['gamma']:.4g}, nu {result['nu0']:.4g} -> {result['nu']:.4g}")
    print(f"train sigma_tr {tr['sigma_tr_start']:.5g} -> {tr['sigma_tr_end']:.5g}")
    if ho:
        print(f"held-out sigma_tr {ho['sigma_tr_start']:.5g} -> {ho['sigma_tr_end']:.5g}")
    return 0
