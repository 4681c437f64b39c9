"""Gradient-based tuning of an estimator's continuous parameters for consistent centers, checked on
held-out classes: (gamma, nu) of the OCSVM (``method="ocsvm"``, the default here) or the depth
exponent ``power`` of the robust estimator (``method="robust"``, on the classes' points:
:func:`jaxpose.pose.pose.robust_pipeline`, whose derivative in the power is exact).

Objective, per class of objects that share a frame (rigid-core aligned):

    sigma_tr = sqrt(mean_objects ||c_i - c_bar||^2)

plus ``scale_weight`` times the coefficient of variation of the scale; the loss is its mean over
the training classes, plus a pull towards the start ``reg * loss_0 * ||theta - theta_0||^2`` in
the unconstrained coordinates theta = (log gamma, logit nu), or theta = (log power,) (``reg`` is
dimensionless: moving log gamma by 1 costs ``reg`` of the starting loss). Minimized with optax.adam (rate decaying to
a tenth along a cosine). The derivatives are :func:`jaxpose.normalize`'s default trend
derivatives (``derivative="trend"``, ``docs/design.md``).

Noise. A class's sigma_tr depends on which surface points were drawn (about 10 % between seeds
on articulated meshes), and a tuner that sees one draw fits it. Meshes are therefore sampled
again at every step (seed ``seed + step``), so each step's gradient is that of a fresh draw; the
result is the mean of the iterates over the second half of the steps (Polyak averaging), not the
best step seen. The gradients are those a user gets from ``jax.grad`` of
:func:`jaxpose.normalize` (ends of the secants solved to tolerance; pass ``secant_iterations``
for the cheaper lock-step approximation). The result is then checked on a fresh draw of the
held-out classes (whole classes kept out of the steps, and/or another dataset): if the tuned
parameters do not lower their spread below the start's, the tuner says so and returns the start
(``kept_defaults``).

Every object of a class has the same point count, so a class is one stacked (n, m, 3) array and
the pose is ``jax.lax.map`` of :func:`jaxpose.pose.pose.pose_pipeline` with a static config: one
compilation per class size, none inside the loop.
"""
from __future__ import annotations

import functools
import math
import time
from collections.abc import Mapping

import jax
import jax.numpy as jnp
import numpy as np

from . import _validate
from .config import OCSVM, ROBUST, TUNE, PoseConfig, RobustConfig, TuneOptions
from .mesh import sample_surface
from .sample import check_count
from .occupancy.points import spacing_subset
from .pose.pose import pose_pipeline, robust_pipeline

__all__ = ["tune", "check_options", "objective", "spread_of", "METHODS"]

METHODS = ("ocsvm", "robust")

_NU_MIN, _NU_MAX = 0.02, 0.98  # keep the secant interval inside (0, 1)


def _from_theta(theta):
    gamma = jnp.exp(theta[0])
    nu = _NU_MIN + (_NU_MAX - _NU_MIN) * jax.nn.sigmoid(theta[1])
    return gamma, nu


def _start_theta(gamma0, nu0):
    u = (nu0 - _NU_MIN) / (_NU_MAX - _NU_MIN)
    if not 0.0 < u < 1.0:
        raise _validate.InvalidInputError(f"nu0 must be a number in ({_NU_MIN}, {_NU_MAX}), got {nu0}")
    return jnp.asarray([math.log(gamma0), math.log(u / (1.0 - u))])


def _params(theta, method):
    """The estimator's parameters {name: value} at theta (module docs)."""
    if method == "robust":
        return {"power": jnp.exp(theta[0])}
    gamma, nu = _from_theta(theta)
    return {"gamma": gamma, "nu": nu}


def _class_stats(points, params, config, method):
    """points (n, m, 3) -> (sigma_tr, cv of scale, all valid) for one class. One object after the
    other (``lax.map``): under ``vmap`` the solver's and the grid's skipped work would all run."""
    if method == "robust":
        queries = jnp.asarray(spacing_subset(points.shape[1], config.spacing_samples))
        pose = jax.lax.map(lambda p: robust_pipeline(p, None, queries, None, params["power"], config), points)
    else:
        pose = jax.lax.map(lambda p: pose_pipeline(p, None, params["gamma"], params["nu"], config), points)
    d = pose.center - jnp.mean(pose.center, axis=0)
    sigma = jnp.sqrt(jnp.mean(jnp.sum(d * d, axis=-1)))
    return sigma, jnp.std(pose.scale) / jnp.mean(pose.scale), jnp.all(pose.valid)


@functools.lru_cache(maxsize=8)
def _make_loss(config, scale_weight, method="ocsvm"):
    """(class_loss(theta, points) -> (loss, (sigma, cv, ok)), jitted value-and-Jacobian by forward mode),
    one pair per (config, scale_weight, method), so that later calls reuse the compilations."""
    @jax.jit
    def class_loss(theta, points):
        sigma, cv, ok = _class_stats(points, _params(theta, method), config, method)
        return sigma + scale_weight * cv, (sigma, cv, ok)

    def value_and_grad(theta, points):  # one or two parameters: forward mode (see jaxpose._hyper)
        J, (loss, aux) = jax.jacfwd(lambda t: (lambda r: (r[0], r))(class_loss(t, points)), has_aux=True)(theta)
        return (loss, aux), J

    return class_loss, jax.jit(value_and_grad)


def _sampler(classes, count, name):
    """{class: seed -> (n, m, 3) float array}: meshes sampled per seed, arrays as given."""
    out = {}
    for cname, objs in classes.items():
        objs = list(objs)
        if len(objs) < 2:
            raise _validate.InvalidInputError(f"class {cname!r} needs at least 2 objects, got {len(objs)}")
        arrays = [o for o in objs if not hasattr(o, "vertices")]
        if arrays and len(arrays) != len(objs):
            raise _validate.InvalidInputError(f"class {cname!r}: give all meshes or all point arrays")
        if arrays:
            arrs = [np.asarray(_validate.check_points(a, name=f"{name}[{cname!r}]")) for a in arrays]
            if len({a.shape[0] for a in arrs}) != 1:
                raise _validate.InvalidInputError(f"class {cname!r}: all objects must have the same point count, "
                                                  f"got {sorted({a.shape[0] for a in arrs})}")
            fixed = jnp.asarray(np.stack(arrs))
            out[cname] = lambda seed, fixed=fixed: fixed
        else:
            out[cname] = lambda seed, objs=objs: jnp.asarray(np.stack(
                [sample_surface(o, count, seed=int(seed) + k * 7919) for k, o in enumerate(objs)]))
    if not out:
        raise _validate.InvalidInputError(f"{name} needs at least one class")
    return out


def _split(classes, holdout, seed):
    """Hold out round(holdout * n_classes) whole classes (at least 1, leaving at least 1)."""
    if holdout <= 0:
        return classes, {}
    if not holdout < 1:
        raise _validate.InvalidInputError(f"holdout must be in [0, 1), got {holdout}")
    names = sorted(classes)
    if len(names) < 2:
        raise _validate.InvalidInputError(
            f"holdout={holdout:g} holds out whole classes: it needs at least 2 (one held out, one tuned on), got "
            f"{len(names)} ({', '.join(map(repr, names))}); pass holdout=0 to tune on it alone (checked on a fresh "
            "draw), or holdout_classes to check on others")
    k = min(max(int(round(holdout * len(names))), 1), len(names) - 1)
    held = set(np.random.default_rng(seed).permutation(len(names))[:k].tolist())
    return ({n: classes[n] for i, n in enumerate(names) if i not in held},
            {n: classes[n] for i, n in enumerate(names) if i in held})


def objective(samplers, theta, class_loss, seed):
    """Mean over classes of (loss, sigma_tr, cv) at theta on the draw ``seed`` (an int >= 0;
    InvalidInputError otherwise); Python floats."""
    seed = _validate.check_int(seed, "seed", 0)
    vals = [class_loss(theta, s(seed)) for s in samplers.values()]
    return tuple(float(np.mean([float(x) for x in v])) for v in
                 ([v[0] for v in vals], [v[1][0] for v in vals], [v[1][1] for v in vals]))


def spread_of(samplers, gamma, nu, class_loss, seed):
    """Mean sigma_tr over classes at (gamma, nu) on the draw ``seed`` (for reports; ocsvm)."""
    return objective(samplers, _start_theta(float(gamma), float(nu)), class_loss, seed)[1]


_STARTS = {"gamma0": "ocsvm", "nu0": "ocsvm", "power0": "robust"}  # a start -> the method that tunes it


def check_options(method="ocsvm", steps=TUNE.steps, lr=TUNE.lr, reg=TUNE.reg, scale_weight=TUNE.scale_weight,
                  holdout=TUNE.holdout, seed=0, count=TUNE.count, gamma0=None, nu0=None, power0=None) -> dict:
    """:func:`tune`'s scalar arguments checked (before any class is loaded or anything compiled),
    as {name: value}: steps, lr, reg, scale_weight, holdout, count by
    :class:`jaxpose.config.TuneOptions` (their one check: steps int >= 0; lr finite > 0; reg,
    scale_weight finite >= 0; holdout in [0, 1); count int >= 4), count then a sample count
    (:func:`jaxpose.sample.check_count`: its memory); seed int >= 0; power0 finite > 0; gamma0, nu0 as
    :func:`jaxpose.normalize`'s with nu0 in (0.02, 0.98) (ocsvm). The method's starts left None
    are :data:`jaxpose.config.OCSVM`'s (gamma, nu) or :data:`jaxpose.config.ROBUST`'s (power);
    those of the other method must be left None (refused by name, as :func:`jaxpose.normalize`
    refuses the other method's options).

    Raises:
      InvalidInputError: naming the first bad argument.
    """
    if not _validate.is_name(method, METHODS):
        raise _validate.InvalidInputError(f"method must be one of {', '.join(map(repr, METHODS))}, got {method!r}")
    given = {"gamma0": gamma0, "nu0": nu0, "power0": power0}
    for key, owner in _STARTS.items():
        if owner != method and given[key] is not None:
            raise _validate.InvalidInputError(
                f"{key} is an option of method={owner!r}; method={method!r} does not use it (pass "
                f"method={owner!r} or leave {key} out)")
    gamma0 = OCSVM.gamma if gamma0 is None else gamma0
    nu0 = OCSVM.nu if nu0 is None else nu0
    power0 = ROBUST.power if power0 is None else power0
    schedule = TuneOptions(steps=steps, lr=lr, reg=reg, scale_weight=scale_weight, holdout=holdout, count=count)
    out = dict(method=method, **{k: getattr(schedule, k) for k in ("steps", "lr", "reg", "scale_weight", "holdout")},
               seed=_validate.check_int(seed, "seed", 0), count=check_count(schedule.count))  # (+ the samples' memory)
    if method == "robust":
        out["power0"] = _validate.check_real(power0, "power0", 0, True)
    else:
        _validate.check_gamma(gamma0, "gamma0")  # the argument the caller passed, by its name
        _validate.check_nu(nu0, "nu0")
        _start_theta(float(gamma0), float(nu0))  # nu0 inside the tuned interval
        out.update(gamma0=float(gamma0), nu0=float(nu0))
    return out


def _invalid_reason(samplers, seed, method, start, normalize_options):
    """Why the start's pose of the first training class's first object is not valid (``"name: "``
    and its :class:`jaxpose.pose.result.Status` message), or None (valid, or not found): a
    diagnosis for a run where no step had every pose valid."""
    import warnings

    from .pose.pose import normalize
    from .pose.result import Status

    name = sorted(samplers)[0]
    try:
        points = samplers[name](seed)[0]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            status = int(normalize(points, method=method, **start, **normalize_options).status)
    except Exception:  # a diagnosis only: the failure is reported without it
        return None
    return f"{name}: {Status(status).message}" if status else None


def tune(classes, gamma0=None, nu0=None, steps=TUNE.steps, lr=TUNE.lr, scale_weight=TUNE.scale_weight,
         holdout=TUNE.holdout, holdout_classes=None, seed=0, count=TUNE.count, reg=TUNE.reg, progress=None, method="ocsvm", power0=None, **normalize_options) -> dict:
    """Tune (gamma, nu) or the robust power by gradient descent on the mean within-class center
    spread (module docs).

    Args:
      classes: {name: [Trimesh | PointCloud, ...]} (sampled afresh at every step), or {name:
        [(m, 3) arrays]} (the same m within a class; used as given); at least 2 objects each.
      gamma0, nu0: the start (None: :data:`jaxpose.config.OCSVM`'s, the paper's; nu0 in (0.02, 0.98)); steps: optax.adam steps
        (>= 0); lr: initial rate (cosine decay to lr / 10).
      scale_weight: weight of the coefficient of variation of the scale in the loss.
      holdout: fraction of ``classes`` held out of the steps (whole classes, at least one held out
        and one kept); holdout_classes: more held-out classes (e.g. another dataset).
      seed: split seed and first sampling seed; count: samples per mesh; reg: pull towards the
        start (module docs; >= 0).
      progress: optional callable(str), told about every step.
      method: ``"ocsvm"`` (tunes gamma, nu) or ``"robust"`` (tunes ``power`` from ``power0`` > 0,
        None: :data:`jaxpose.config.ROBUST`'s, on the classes' points). The other method's starts
        are refused by name (:func:`check_options`): gamma0, nu0 with ``"robust"``, power0 with
        ``"ocsvm"``.
      normalize_options: static options of :func:`jaxpose.normalize` for that method
        (ocsvm: resolution, tol, ...; robust: resolution, coarse, ...).

    Returns:
      A JSON-able dict: ``gamma``, ``nu`` (ocsvm) or ``power`` (robust): the parameters to use
      (the tuned ones, or the start when they do not lower the held-out spread), ``tuned``
      {gamma, nu} or {power}, ``method``, ``kept_defaults``,
      ``verdict`` (a sentence), ``train`` and ``holdout`` {sigma_tr_start, sigma_tr_tuned,
      classes, names} on a fresh draw, the ``trajectory`` [{step, gamma, nu (or power),
      loss, sigma_tr, cv_scale, grad, valid}] (one draw per step; sigma_tr NaN where not every
      pose of the step is valid), ``options``, ``seconds``. Where no step had every pose valid
      nothing was tuned: ``error`` (= ``verdict``) says so and why (the first training object's
      :class:`jaxpose.pose.result.Status` at the start), and the parameters, ``tuned``,
      ``kept_defaults`` and the spreads are None (no recommendation).

    Raises:
      InvalidInputError: bad classes, parameters or options.
    """
    import optax

    checked = check_options(method, steps, lr, reg, scale_weight, holdout, seed, count, gamma0, nu0, power0)
    steps, lr, reg, scale_weight, holdout, seed, count = (checked[k] for k in ("steps", "lr", "reg", "scale_weight",
                                                                             "holdout", "seed", "count"))
    for name, given in (("classes", classes), ("holdout_classes", holdout_classes)):
        if not isinstance(given, Mapping) and not (given is None and name == "holdout_classes"):
            raise _validate.InvalidInputError(f"{name} must be a dict {{class name: [meshes or (m, 3) arrays]}}, got "
                                              f"{type(given).__name__}" + (": pass {'name': [...]}" if isinstance(given, (list, tuple)) else ""))
    _validate.check_callback(progress, "progress")
    if method == "robust":
        config = RobustConfig.create(**normalize_options)
        theta0 = jnp.asarray([math.log(checked["power0"])])
        start = {"power": checked["power0"]}
    else:
        config = PoseConfig.create(**normalize_options)
        theta0 = _start_theta(checked["gamma0"], checked["nu0"])
        start = {"gamma": checked["gamma0"], "nu": checked["nu0"]}
    train, test = _split(dict(classes), float(holdout), int(seed))
    train_s = _sampler(train, count, "classes")
    test_s = {**(_sampler(test, count, "classes") if test else {}),
              **({f"holdout:{k}": v for k, v in _sampler(holdout_classes, count, "holdout_classes").items()}
                 if holdout_classes else {})}
    class_loss, class_vg = _make_loss(config, float(scale_weight), method)
    say = progress or (lambda _msg: None)
    opt = optax.adam(optax.cosine_decay_schedule(float(lr), max(int(steps), 1), alpha=0.1))
    state, theta = opt.init(theta0), theta0
    update = jax.jit(opt.update)
    trajectory, iterates, loss0 = [], [], None
    t0 = time.perf_counter()
    for step in range(int(steps) + 1):
        vals = [class_vg(theta, s(int(seed) + step)) for s in train_s.values()]
        loss = float(np.mean([float(v[0][0]) for v in vals]))
        loss0 = loss if loss0 is None else loss0
        grad = sum(v[1] for v in vals) / len(vals) + 2.0 * float(reg) * loss0 * (theta - theta0)
        valid = all(bool(v[0][1][2]) for v in vals)
        rec = dict(step=step, **{k: float(v) for k, v in _params(theta, method).items()}, loss=loss,
                   sigma_tr=float(np.mean([float(v[0][1][0]) for v in vals])) if valid else math.nan,
                   cv_scale=float(np.mean([float(v[0][1][1]) for v in vals])),
                   valid=valid, grad=[float(x) for x in grad],
                   seconds=time.perf_counter() - t0)
        trajectory.append(rec)
        say(f"step {step}/{int(steps)}: " + " ".join(f"{k}={rec[k]:.4g}" for k in start)
            + (f" sigma_tr={rec['sigma_tr']:.5g}" if valid else " invalid poses") + f" ({rec['seconds']:.0f} s)")
        if step >= int(steps) // 2 and rec["valid"]:
            iterates.append(theta)
        if step == int(steps) or not bool(jnp.all(jnp.isfinite(grad))):
            break
        upd, state = update(grad, state, theta)
        theta = optax.apply_updates(theta, upd)
    fmt = lambda d: ", ".join(f"{k} {v:.4g}" for k, v in d.items())
    result = dict(method=method, **{f"{k}0": v for k, v in start.items()}, trajectory=trajectory, steps=int(steps),
                  lr=float(lr), reg=float(reg), scale_weight=float(scale_weight), seed=int(seed), count=int(count),
                  options=config.flat())
    if not any(rec["valid"] for rec in trajectory):  # nothing tuned: the start's poses were invalid at every step
        reason = _invalid_reason(train_s, int(seed), method, start, normalize_options)
        names = lambda samplers: dict(sigma_tr_start=None, sigma_tr_tuned=None, classes=len(samplers),
                                      names=sorted(samplers))
        result.update(tuned=None, kept_defaults=None, **{k: None for k in start}, train=names(train_s),
                      holdout=names(test_s) if test_s else None, seconds=time.perf_counter() - t0)
        result["verdict"] = result["error"] = (f"no step had every pose valid, from ({fmt(start)})"
                                               + (f"; e.g. {reason}" if reason else "")
                                               + ": nothing was tuned, no recommendation")
        say(result["verdict"])
        return result
    tuned = jnp.mean(jnp.stack(iterates), axis=0) if iterates else theta0
    tuned_params = {k: float(v) for k, v in _params(tuned, method).items()}
    check = int(seed) + 100_003  # a draw no step has seen
    block = lambda samplers: dict(sigma_tr_start=objective(samplers, theta0, class_loss, check)[1],
                                  sigma_tr_tuned=objective(samplers, tuned, class_loss, check)[1],
                                  classes=len(samplers), names=sorted(samplers))
    result.update(tuned=tuned_params, train=block(train_s), holdout=block(test_s) if test_s else None,
                  seconds=time.perf_counter() - t0)
    judge = result["holdout"] or result["train"]
    where = "held-out classes" if result["holdout"] else "training classes (fresh draw; no held-out classes)"
    lower = judge["sigma_tr_tuned"] < judge["sigma_tr_start"]
    change = judge["sigma_tr_tuned"] / judge["sigma_tr_start"] - 1.0
    result["kept_defaults"] = not lower
    result.update(tuned_params if lower else start)
    if int(steps) == 0:  # (it read "... by +0.0%: they do not transfer" of a start nothing moved)
        result["verdict"] = (f"steps=0: nothing was tuned; the start ({fmt(start)}) gives a center spread of "
                             f"{judge['sigma_tr_start']:.5g} on the {where}")
    else:
        one = len(tuned_params) == 1  # (robust's power: "use it", not "use them")
        result["verdict"] = (f"tuned ({fmt(tuned_params)}) changes the center spread of the {where} by "
                             f"{change:+.1%}: " + (f"use {'it' if one else 'them'}" if lower else
                                                   f"{'it does' if one else 'they do'} not transfer; keeping "
                                                   f"({fmt(start)})"))
    say(result["verdict"])
    return result
