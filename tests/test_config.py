"""Option objects: validated once, hashable (static under jit), one default per option."""
import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxpose import GridConfig, InvalidInputError, PoseConfig, SolverConfig
from jaxpose import _validate, tuning


def test_defaults_live_in_one_place():
    cfg = PoseConfig()
    assert cfg.svdd == SolverConfig() and cfg.grid == GridConfig()
    assert (cfg.grid.resolution, cfg.grid.refine, cfg.grid.band) == (64, 2, 16384)
    assert (cfg.svdd.tol, cfg.svdd.max_iter, cfg.svdd.solver) == (1e-3, 20_000, None)
    assert cfg.svdd.block == cfg.grid.block  # one block default


def test_configs_are_frozen_and_hashable():
    cfg = PoseConfig.create(resolution=32, tol=1e-4)
    assert hash(cfg) == hash(PoseConfig.create(resolution=32, tol=1e-4))
    assert cfg != PoseConfig()
    with pytest.raises(dataclasses.FrozenInstanceError):
        cfg.grid.resolution = 16  # type: ignore[misc]

    f = jax.jit(lambda x, config: x * config.grid.resolution, static_argnames=("config",))
    assert float(f(jnp.asarray(2.0), config=cfg)) == 64.0
    # NumPy numbers and bools as options: the same config, one static key (extrapolate=np.True_ was
    # refused, where every other bool option takes NumPy bools)
    same = PoseConfig.create(resolution=np.int64(32), tol=np.float64(1e-4), extrapolate=np.True_)
    assert same == cfg and hash(same) == hash(cfg) and type(same.grid.extrapolate) is bool


def test_flat_options_reach_the_right_object():
    cfg = PoseConfig.create(resolution=32, refine=4, tol=1e-5, solver="smo", block=512, derivative="secant")
    assert (cfg.grid.resolution, cfg.grid.refine, cfg.svdd.tol, cfg.svdd.solver) == (32, 4, 1e-5, "smo")
    assert cfg.grid.block == cfg.svdd.block == 512 and cfg.derivative == "secant"
    assert PoseConfig.create(**cfg.flat()) == cfg  # flat() inverts create()
    base = PoseConfig.create(resolution=16)
    assert PoseConfig.create(base, tol=1e-4).grid.resolution == 16  # options replace fields of a given config


@pytest.mark.parametrize("options,fragment", [
    (dict(resolution=4), "resolution must be >= 8"), (dict(resolution=8.0), "resolution must be an int"),
    (dict(refine=3), "power of 2"), (dict(band=-1), "band"), (dict(tol=0.0), "tol"), (dict(tol=np.nan), "tol"),
    (dict(max_iter=0), "max_iter"), (dict(check_every=0), "check_every"), (dict(block=True), "block"),
    (dict(max_iter=2**31 - 10), "max_iter \\+ check_every must be at most 2147483647"),
    (dict(kernel="x"), "kernel must be one of"), (dict(solver="newton"), "solver must be one of"),
    (dict(derivative="fd"), "derivative"), (dict(nu_delta=0.7), "nu_delta"), (dict(foo=1), "unknown option foo"),
])
def test_bad_options_name_the_option(options, fragment):
    with pytest.raises(InvalidInputError, match=fragment):
        PoseConfig.create(**options)


def test_an_int_below_its_minimum_reads_the_same_from_config_and_check_int():
    """config's int options and _validate.check_int are one rule with one message: the number
    refused as a number (config showed np.int64(4), Array(4, dtype=int32); check_int showed 4)."""
    from jaxpose._validate import check_int

    for value in (4, np.int64(4), np.array(4, np.uint8), jnp.int32(4)):
        with pytest.raises(InvalidInputError) as by_config:
            PoseConfig.create(resolution=value)
        with pytest.raises(InvalidInputError) as by_check:
            check_int(value, "resolution", 8)
        assert str(by_config.value) == str(by_check.value) == "resolution must be >= 8, got 4", value


def test_fit_svdd_and_volume_moments_refuse_an_unknown_option_by_name():
    # their flat options went to SolverConfig(**options) / GridConfig(**options): a raw TypeError
    import jaxpose
    from jaxpose.occupancy.svdd import SVDD

    pts = np.random.default_rng(0).normal(size=(20, 3))
    with pytest.raises(InvalidInputError, match="unknown option resolution; valid: tol, max_iter"):
        jaxpose.fit_svdd(pts, 1.0, 0.5, resolution=32)  # a grid option
    zero = jnp.asarray(0.0)
    svdd = SVDD(jnp.zeros((2, 3)), jnp.full(2, 0.5), jnp.asarray(1.0), jnp.asarray(1.0), jnp.asarray(1.0), zero,
                jnp.asarray(0), zero, jnp.asarray(True), jnp.ones(2, bool))
    with pytest.raises(InvalidInputError, match="unknown option tol; valid: resolution, refine"):
        jaxpose.volume_moments(svdd, tol=1e-4)  # a solver option
    assert SolverConfig.create(tol=1e-4) == SolverConfig(tol=1e-4) and GridConfig.create() == GridConfig()


def test_config_or_options_not_both():
    import jaxpose

    pts = np.random.default_rng(0).normal(size=(20, 3))
    with pytest.raises(InvalidInputError, match="either config or options"):
        jaxpose.fit_svdd(pts, 1.0, 0.5, config=SolverConfig(), tol=1e-4)
    with pytest.raises(InvalidInputError, match="config must be a PoseConfig"):
        jaxpose.normalize(pts, method="ocsvm", config=GridConfig())


def test_grid_memory_is_bounded():
    """A grid whose cells would not fit MEMORY_BUDGET is refused when the option is made, with the figure."""
    from jaxpose.config import CELL_BYTES, MEMORY_BUDGET

    assert GridConfig().memory == CELL_BYTES * (64**3 + 8 * 16384)
    assert GridConfig(resolution=281).memory <= MEMORY_BUDGET
    with pytest.raises(InvalidInputError, match=r"resolution=1000 \(refine=2, band=16384\) needs about 89\.4\d GiB"
                                                r".*the limit is 2 GiB: use a resolution in \[8, 281\]"):
        GridConfig(resolution=1000)
    # no resolution fits: it read 'use a resolution in [8, 0] with a smaller band or refine'
    with pytest.raises(InvalidInputError, match=r"the limit is 2 GiB: no resolution fits this band and refine \(their "
                                                r"refined cells alone need \d+ GiB\): use a smaller band or refine$"):
        GridConfig(resolution=64, refine=1024, band=10**6)
    with pytest.raises(InvalidInputError, match="resolution=1000"):
        PoseConfig.create(resolution=1000)


# --------------------------------------------------------------------------- the estimators' parameters
def test_estimator_options_are_the_paper_values_and_validated():
    from jaxpose.config import OCSVM, ROBUST, OCSVMOptions, RobustOptions

    # the paper's gamma = 47 and nu = 0.5 (section 4), and the robust center's depth^4 weights (docs/estimators.md)
    assert (OCSVM.gamma, OCSVM.nu, ROBUST.power) == (47.0, 0.5, 4.0)
    assert hash(OCSVM) == hash(OCSVMOptions()) and ROBUST == RobustOptions()
    with pytest.raises(dataclasses.FrozenInstanceError):
        OCSVM.gamma = 1.0  # type: ignore[misc]
    for bad, fragment in [(dict(gamma=0.0), "gamma"), (dict(gamma=float("inf")), "gamma"), (dict(nu=1.5), "nu"),
                          (dict(nu=True), "nu"), (dict(count=3), "count"), (dict(seed=-1), "seed"),
                          (dict(sampling="grid"), "sampling")]:
        with pytest.raises(InvalidInputError, match=fragment):
            OCSVMOptions(**bad)
    with pytest.raises(InvalidInputError, match="power"):
        RobustOptions(power=-1.0)


@pytest.mark.parametrize("bad, message", [
    # TuneOptions took any value (its siblings refuse theirs): steps=-1, lr=0, holdout=1.0 ...
    (dict(steps=-1), "steps must be >= 0"), (dict(steps=2.5), "steps must be an int"),
    (dict(lr=0.0), "lr must be a finite number > 0"), (dict(reg=-1.0), "reg must be"),
    (dict(scale_weight=float("nan")), "scale_weight must be"), (dict(holdout=1.0), r"holdout must be a number in \[0, 1\)"),
    (dict(count=3), "count must be >= 4"), (dict(instances=1), "instances must be >= 2"),
])
def test_tune_options_are_validated(bad, message):
    from jaxpose.config import TUNE, TuneOptions

    assert TuneOptions() == TUNE and dataclasses.replace(TUNE, steps=3).steps == 3
    with pytest.raises(InvalidInputError, match=message):
        TuneOptions(**bad)


@pytest.mark.parametrize("bad", [
    dict(steps=-1), dict(steps=2.5), dict(lr=0.0), dict(lr=float("nan")), dict(reg=-1.0), dict(scale_weight=float("nan")),
    dict(holdout=1.0), dict(holdout=-0.5), dict(count=3), dict(lr="0.1"), dict(holdout=np.array([0.1])),
    dict(reg=np.bool_(True)), dict(lr=10**400),
])
def test_tune_options_are_the_one_check_of_tunes_schedule(bad):
    """TuneOptions and tuning.check_options (tune, the command) checked the same values twice, in two
    wordings; check_options builds a TuneOptions: one check, one message. TuneOptions took what
    check_options refused (lr="0.1", a (1,) array, a NumPy bool) and raised OverflowError for an int
    beyond a float's range; both refuse them now, by name."""
    from jaxpose import tuning
    from jaxpose.config import TuneOptions

    with pytest.raises(InvalidInputError) as direct:
        TuneOptions(**bad)
    with pytest.raises(InvalidInputError) as through:
        tuning.check_options(**bad)
    assert str(direct.value) == str(through.value) and str(direct.value).startswith(f"{next(iter(bad))} must be")


def test_config_real_and_check_real_take_the_same_values():
    """config._real took whatever float() takes (Decimal("0.1"), an object with __float__) where
    _validate.check_real refuses it (the docstring: they refuse the same): both refuse those, both
    take Python's and NumPy's reals and () arrays of reals."""
    from decimal import Decimal
    from fractions import Fraction

    from jaxpose._validate import check_real
    from jaxpose.config import _real

    class Floaty:
        def __float__(self):
            return 0.5

    for bad in (Decimal("0.1"), Floaty(), "0.1", True, np.bool_(True), np.array([0.5]), None, 1 + 0j):
        with pytest.raises(InvalidInputError):
            check_real(bad, "x", 0.0)
        with pytest.raises(InvalidInputError, match="^x must be a number in"):
            _real(bad, "x", 0.0, 1.0)
    for good in (0.5, 1, Fraction(1, 2), np.float32(0.5), np.int64(1), np.array(0.5), np.array(1, np.uint8)):
        assert _real(good, "x", 0.0, 1.0) == check_real(good, "x", 0.0) == float(good)


def test_one_number_rule_one_wording():
    """_validate.check_real ("must be a finite number > 0") and the options objects' config._real
    ("must be a number in (0, inf)") worded one rule twice, and took different values: check_real
    took a NumPy timedelta (an integer subtype to NumPy) and refused an ml_dtypes bfloat16 scalar,
    _real the reverse. check_real is _real now: the same values, the same message, for the half-line
    and for an options object's field."""
    import math

    import ml_dtypes

    from jaxpose._validate import check_real
    from jaxpose.config import RobustOptions, TuneOptions, _real

    for value in (np.timedelta64(3), ml_dtypes.bfloat16(2.0), np.array(-2.0), -1, float("nan"), float("inf"), 10**400,
                  "1", True, np.array([1.0]), 0.0, 2, np.float32(0.5), np.array(3, np.uint8), jnp_scalar()):
        for strict in (False, True):
            outcomes = []
            for check in (lambda: check_real(value, "x", 0, strict), lambda: _real(value, "x", 0, math.inf, not strict)):
                try:
                    outcomes.append(check())
                except InvalidInputError as exc:
                    outcomes.append(str(exc))
            assert outcomes[0] == outcomes[1], (value, strict, outcomes)
    with pytest.raises(InvalidInputError, match=r"^x must be a finite number > 0, got -2.0$"):
        check_real(np.array(-2.0), "x", 0, strict=True)
    with pytest.raises(InvalidInputError, match=r"^lr must be a finite number > 0, got 0.0$"):
        TuneOptions(lr=0.0)
    with pytest.raises(InvalidInputError, match=r"^power must be a finite number >= 0, got -1.0$"):
        RobustOptions(power=-1.0)
    with pytest.raises(InvalidInputError, match=r"^x must be a finite number >= 0, got np.timedelta64\(3\)$"):
        check_real(np.timedelta64(3), "x", 0)
    assert check_real(ml_dtypes.bfloat16(2.0), "x", 0) == 2.0
    with pytest.raises(InvalidInputError, match=r"^x must be a number in \[0, 1\], got 2.0$"):  # a bounded interval
        _real(2.0, "x", 0.0, 1.0)


def jnp_scalar():
    import jax.numpy as jnp

    return jnp.asarray(-3)


def test_every_entry_point_reads_the_one_default():
    """The functions, the batch options and the command line all default to jaxpose.config's values."""
    import inspect

    import jaxpose
    from jaxpose import mesh, tuning
    from jaxpose.batch.task import NormalizeOptions
    from jaxpose.cli import build_parser, tune
    from jaxpose.config import OCSVM, ROBUST
    from jaxpose.evaluation import evaluate
    from jaxpose.pose import estimators, sensitivity

    params = inspect.signature(sensitivity.pose_sensitivity).parameters
    assert (params["gamma"].default, params["nu"].default) == (OCSVM.gamma, OCSVM.nu)
    # evaluate leaves the OCSVM's gamma, nu, count None (refused where nothing runs the OCSVM); unset,
    # config's (recorded in its params: test_evaluation)
    params = inspect.signature(evaluate).parameters
    assert all(params[name].default is None for name in ("gamma", "nu", "count"))
    # normalize_mesh leaves the OCSVM's options None (refused where nothing runs the OCSVM); unset, config's
    for fn in (jaxpose.normalize_mesh, mesh.check_arguments):
        params = inspect.signature(fn).parameters
        assert all(params[name].default is None for name in mesh.OCSVM_ONLY), fn.__name__
    assert mesh.ocsvm_arguments() == {name: getattr(OCSVM, name) for name in mesh.OCSVM_ONLY}
    # normalize / normalize_batch take both methods' parameters as keywords left unset (an option of the
    # other method is refused by name); unset, each method's is config's
    from jaxpose.config import PoseConfig, RobustConfig
    from jaxpose.pose import pose as pose_module

    assert pose_module._options("ocsvm", None, {}, False) == (PoseConfig(), {"gamma": OCSVM.gamma, "nu": OCSVM.nu})
    assert pose_module._options("robust", None, {}, False) == (RobustConfig(), {"power": ROBUST.power})
    # tune leaves the starts None (refused with the other method); unset, each method's is config's
    params = inspect.signature(tuning.tune).parameters
    assert (params["gamma0"].default, params["nu0"].default, params["power0"].default) == (None, None, None)
    checked = tuning.check_options("ocsvm"), tuning.check_options("robust")
    assert (checked[0]["gamma0"], checked[0]["nu0"], checked[1]["power0"]) == (OCSVM.gamma, OCSVM.nu, ROBUST.power)
    # tune's schedule: config.TUNE, read by tune, check_options and the command (each kept its own copy)
    from jaxpose.config import TUNE
    command = tune.parser().parse_args([])
    for field in dataclasses.fields(TUNE):
        default = getattr(TUNE, field.name)
        if field.name != "instances":
            for fn in (tuning.tune, tuning.check_options):
                assert inspect.signature(fn).parameters[field.name].default == default, (fn.__name__, field.name)
        if field.name == "instances":  # unset (refused with --data, as evaluate's); the dataset made with TUNE's
            assert command.instances is None and f"default {default}," in " ".join(tune.parser().format_help().split())
        elif field.name != "holdout":  # the command's holdout: 0.25 of the classes unless --holdout-data
            assert getattr(command, field.name) == default, field.name
    assert inspect.signature(tune.load_classes).parameters["instances"].default == TUNE.instances
    assert (NormalizeOptions().gamma, NormalizeOptions().nu, NormalizeOptions().count) == (
        OCSVM.gamma, OCSVM.nu, OCSVM.count)
    assert inspect.signature(estimators.robust_center_scale).parameters["power"].default == ROBUST.power
    args = tune.parser().parse_args([])  # unset (refused with --method robust); the command fills them in
    assert (args.gamma, args.nu, args.power) == (None, None, None)
    assert tune._method_options(args) == {"gamma0": OCSVM.gamma, "nu0": OCSVM.nu, "resolution": 16, "refine": 2,
                                          "band": 2048, "tol": 1e-3, "solver": None}
    assert tune._method_options(tune.parser().parse_args(["--method", "robust"])) == {"power0": ROBUST.power}
    # normalize and evaluate leave them None (refused where nothing runs the OCSVM); the library fills them in
    for command in (["normalize", "x.ply"], ["evaluate"]):
        assert build_parser().parse_args(command).gamma is None


def test_the_command_line_and_normalize_mesh_refuse_the_same_ocsvm_options():
    """Where no OCSVM runs (the robust default), the ``normalize`` command, normalize_mesh and
    NormalizeOptions refuse exactly the same options as the OCSVM's: the fields of
    config.OCSVMOptions, read from one list, config.OCSVM_ONLY (the command kept its own copy)."""
    import inspect

    from jaxpose import config, mesh
    from jaxpose.batch.task import NormalizeOptions
    from jaxpose.cli import build_parser
    from jaxpose.cli import normalize as command

    assert command.OCSVM_ONLY is mesh.OCSVM_ONLY is config.OCSVM_ONLY and not hasattr(command, "_OCSVM_ONLY")
    parser = build_parser()
    flags = {a.dest for a in parser._subparsers._group_actions[0].choices["normalize"]._actions}
    names = sorted(flags & set(inspect.signature(mesh.normalize_mesh).parameters) - {"method"})
    values = dict(gamma=20.0, nu=0.3, count=500, seed=3, sampling="random", resolution=64, center="vertex_mean",
                  scale="unit_cube", rotation="pca_vertices", strict=True)  # a value other than the default
    assert sorted(values) == names  # every option both take
    by_command, by_function, by_options = set(), set(), set()
    for name in names:
        value = values[name]
        flag = [f"--{name}"] + ([] if value is True else [str(value)])
        args = parser.parse_args(["normalize", "in.ply", "--method", "robust", *flag])
        if f"--{name} applies to the ocsvm method" in (command.ignored_options(args) or ""):
            by_command.add(name)
        try:
            mesh.check_arguments(method="robust", **{name: value})
        except InvalidInputError as exc:
            if f"{name} is an option of the ocsvm estimator" in str(exc):
                by_function.add(name)
        try:
            NormalizeOptions(method="robust", **{name: value})
        except InvalidInputError as exc:
            if f"{name} is an option of the ocsvm estimator" in str(exc):
                by_options.add(name)
    ocsvm = {field.name for field in dataclasses.fields(config.OCSVMOptions)}
    assert by_command == by_function == by_options == ocsvm


def test_a_seed_is_any_concrete_integer_scalar_at_every_entry_point(monkeypatch):
    """An int seed may be a NumPy or JAX integer scalar of any integer dtype, a () integer array
    too (jnp.int32(0) and np.array(0) were refused as not an int); bools, floats, other shapes and
    traced values are refused by name."""
    import trimesh

    import jaxpose
    from jaxpose import mesh, sample, tuning
    from jaxpose.batch.task import NormalizeOptions
    from jaxpose.config import OCSVMOptions
    from jaxpose.pose import pose as pose_module

    class Reached(Exception):  # the pipeline was called: every argument accepted (nothing compiled)
        pass

    def reached(*args, **kwargs):
        raise Reached

    monkeypatch.setattr(pose_module, "_robust_jit", reached)
    monkeypatch.setattr(pose_module, "_robust_batched", reached)
    box = trimesh.creation.box()
    points = np.random.default_rng(0).normal(size=(40, 3))

    def normalize(seed):
        with pytest.raises(Reached):
            jaxpose.normalize(points, seed=seed)
        with pytest.raises(Reached):
            jaxpose.normalize_batch([points, points[:30]], seed=seed)

    entries = {  # each public entry point that takes a seed (or the check it runs before any work)
        "OCSVMOptions": lambda seed: OCSVMOptions(seed=seed).seed,
        "NormalizeOptions": lambda seed: NormalizeOptions(method="ocsvm", seed=seed).seed,
        "normalize_mesh": lambda seed: mesh.check_arguments(method="ocsvm", seed=seed),
        "sample_surface": lambda seed: sample.sample_surface(box, 10, seed=seed),
        "mesh.sample_surface": lambda seed: mesh.sample_surface(box, 10, seed=seed),
        "tune": lambda seed: tuning.check_options(seed=seed)["seed"],
        "normalize": normalize,
    }
    for value in (np.int64(3), np.uint8(3), np.array(3), np.array(3, np.int16), jnp.int32(3), jnp.uint32(3),
                  jnp.array(3, jnp.int8)):
        for name, entry in entries.items():
            got, expected = entry(value), entry(3)
            if isinstance(expected, int):
                assert got == expected and type(got) is int, (name, value)
            elif expected is not None and not isinstance(expected, tuple):
                np.testing.assert_array_equal(got, expected)  # the same samples as seed=3
    for value in (True, np.bool_(True), jnp.bool_(True), 3.0, np.float32(3), jnp.float32(3), np.array([3]), "3",
                  -1, jnp.int32(-1)):
        for name, entry in entries.items():
            with pytest.raises(InvalidInputError, match="seed must be"):
                entry(value)
    from jaxpose.evaluation import evaluate, evaluate_rotation

    for value in (True, 3.0, jnp.float32(3)):  # refused before any work (an int seed is check_int's: above)
        for entry in (evaluate, evaluate_rotation):
            with pytest.raises(InvalidInputError, match="seed must be"):
                entry({"boxes": [box, box.copy()]}, seed=value)
    with pytest.raises(InvalidInputError, match="seed must be a concrete int.*traced"):
        jax.jit(lambda seed: sample.sample_surface(box, 10, seed=seed))(3)
    with pytest.raises(InvalidInputError, match="seed must be a concrete int.*traced"):
        jax.jit(lambda seed: OCSVMOptions(seed=seed))(3)


@pytest.mark.parametrize("call, message", [
    # SolverConfig's tol, PoseConfig's deltas and nu_tol, check_gamma and check_nu each had their own words
    # ('finite and > 0', 'must be in (0, 0.5)', 'must be > 0' / 'must be finite' / 'a real scalar', 'must be in [0, 1]')
    (lambda: SolverConfig(tol=-1), "tol must be a finite number > 0, got -1"),
    (lambda: SolverConfig(tol="1e-3"), "tol must be a finite number > 0, got '1e-3'"),
    (lambda: PoseConfig.create(gamma_delta=0.7), r"gamma_delta must be a number in \(0, 0.5\), got 0.7"),
    (lambda: PoseConfig.create(nu_delta=0.5), r"nu_delta must be a number in \(0, 0.5\), got 0.5"),
    (lambda: PoseConfig.create(nu_tol=float("nan")), "nu_tol must be a finite number > 0, got nan"),
    (lambda: _validate.check_gamma(-1.0), "gamma must be a finite number > 0, got -1.0"),
    (lambda: _validate.check_gamma(float("inf")), "gamma must be a finite number > 0, got inf"),
    (lambda: _validate.check_nu(1.5), r"nu must be a number in \[0, 1\], got 1.5"),
    # tuning.check_options named gamma0 / nu0 'gamma' / 'nu'
    (lambda: tuning.check_options(gamma0=-1.0), "gamma0 must be a finite number > 0, got -1.0"),
    (lambda: tuning.check_options(nu0=2.0), r"nu0 must be a number in \[0, 1\], got 2.0"),
])
def test_number_rules_have_config_real_wording(call, message):
    from jaxpose.errors import InvalidInputError

    with pytest.raises(InvalidInputError, match="^" + message + "$"):
        call()


def test_number_rules_take_what_they_took():
    assert SolverConfig(tol=1e-3).tol == 1e-3 and PoseConfig.create(gamma_delta=0.49, nu_delta=1e-9).gamma_delta == 0.49
    assert PoseConfig.create(nu_tol=1e-6).nu_tol == 1e-6 and PoseConfig.create().nu_tol is None
    assert _validate.check_gamma(47) == 47 and _validate.check_nu(0) == 0 and _validate.check_nu(1.0) == 1.0


def test_a_traced_static_option_says_how_to_pass_it():
    """A traced tol, keep_ratio, gamma_delta, ... (under jit, vmap or grad) read "tol must be a finite
    number > 0, got JitTracer(~float32[])" or "keep_ratio must be in [0, 1], got JitTracer(...)",
    as if its value were wrong; every option that must be static (config._real, _int, _bool: one
    check, config._not_static) says so and how to pass it. Refused while tracing: nothing compiles.
    RobustConfig's keep_ratio, its own check, took the string "0.5" (float()); the number rule refuses it."""
    import jaxpose
    from jaxpose.config import RobustConfig
    from jaxpose.occupancy.solid import robust_solid

    p = np.random.default_rng(0).normal(size=(50, 3))
    how = r"not a traced value \(under jit, vmap or grad\): pass {0} as a static argument \(jax\.jit\(f, " \
          r"static_argnames=\.\.\.\)\) or bind it outside the transformation \(functools\.partial\(f, {0}=\.\.\.\)\)"
    numbers = {
        "tol": [lambda t: jaxpose.fit_svdd(p, 1.0, 0.5, tol=t), lambda t: jaxpose.normalize(p, method="ocsvm", tol=t),
                lambda t: SolverConfig(tol=t)],
        "keep_ratio": [lambda t: jaxpose.normalize(p, keep_ratio=t), lambda t: jaxpose.normalize_batch([p], keep_ratio=t),
                       lambda t: RobustConfig(keep_ratio=t), lambda t: robust_solid(p, keep_ratio=t)],
        "gamma_delta": [lambda t: jaxpose.normalize(p, method="ocsvm", gamma_delta=t)],
        "nu_tol": [lambda t: PoseConfig.create(nu_tol=t)],
    }
    for name, calls in numbers.items():
        for call in calls:
            for transform in (jax.jit, jax.vmap):
                with pytest.raises(InvalidInputError, match=f"^{name} must be a static Python number, {how.format(name)}"):
                    transform(call)(jnp.full((2,) if transform is jax.vmap else (), 0.1))
    with pytest.raises(InvalidInputError, match=f"^max_iter must be a concrete int, {how.format('max_iter')}"):
        jax.jit(lambda n: jaxpose.fit_svdd(p, 1.0, 0.5, max_iter=n))(10)
    with pytest.raises(InvalidInputError, match=f"^extrapolate must be a static Python bool, {how.format('extrapolate')}"):
        jax.jit(lambda e: GridConfig(extrapolate=e))(True)
    with pytest.raises(InvalidInputError, match=r"^keep_ratio must be a number in \[0, 1\], got '0.5'"):
        RobustConfig(keep_ratio="0.5")
    assert RobustConfig(keep_ratio=np.float32(0.25)).keep_ratio == 0.25 and RobustConfig(keep_ratio=1).keep_ratio == 1.0
