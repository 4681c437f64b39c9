"""Option objects: frozen, hashable (static under ``jit``), validated once; the one source of defaults.

The estimators' parameters, each default written here only:

* :class:`OCSVMOptions` (:data:`OCSVM`) -- the paper's estimator: gamma, nu and the surface
  samples it is fitted to;
* :class:`RobustOptions` (:data:`ROBUST`) -- the robust estimator: the depth exponent of its center;
  :class:`RobustConfig` -- how its voxel solid of a point cloud is built (static grid options).

Three objects cover every option of the OCSVM pipeline:

* :class:`SolverConfig` -- how the SVDD dual (eq. 2) is solved and when it stops;
* :class:`GridConfig` -- how the volume integrals of eqs. 4-5 are discretized;
* :class:`PoseConfig` -- both, plus how derivatives in (gamma, nu) are taken.

Public functions accept either a config object or the same options as flat keywords
(``normalize(points, method="ocsvm", resolution=32, tol=1e-4)``); :meth:`PoseConfig.create` maps the flat
names onto the right object and rejects unknown ones by name.

Example::

    >>> from jaxpose.config import PoseConfig
    >>> cfg = PoseConfig.create(resolution=32, tol=1e-4)
    >>> cfg.grid.resolution, cfg.svdd.tol
    (32, 0.0001)
"""
from __future__ import annotations

import dataclasses
import math
import numbers
import operator

from .errors import InvalidInputError  # (not _validate: the command line imports this module before NumPy)

__all__ = ["SAMPLING", "OCSVMOptions", "OCSVM", "OCSVM_ONLY", "RobustOptions", "ROBUST", "RobustConfig", "SolverConfig", "GridConfig", "PoseConfig", "BLOCK", "KERNELS", "SOLVERS", "DERIVATIVES", "MEMORY_BUDGET",
           "CELL_BYTES", "ITERATION_LIMIT", "TuneOptions", "TUNE", "DATASET_INSTANCES", "check_instances"]

SAMPLING = ("even", "random")  # how surface samples are drawn (jaxpose.sample.sample_surface)
BLOCK = 2048  # rows per block: kernel products and grid cells (memory O(BLOCK * m))
MEMORY_BUDGET = 2 * 2**30  # bytes one grid may take at its peak (the OCSVM's cells, the robust solid's voxels)
CELL_BYTES = 96  # peak bytes per cell of the OCSVM grid (measured 70-95, float32 and float64)
KERNELS = ("auto", "dense", "blocked")
SOLVERS = (None, "auto", "smo", "pg")
DERIVATIVES = ("trend", "exact", "secant")


def _integer(value):
    """``value`` as a Python int where it is a concrete integer scalar: a Python int, a NumPy
    integer, or a () NumPy or JAX array of an integer dtype (any width, signed or not); None for
    anything else: bools (Python's, NumPy's, a bool array), floats, other shapes, traced values.
    Told by type and dtype, without importing NumPy or JAX (see :func:`_bool`)."""
    if isinstance(value, bool):
        return None
    dtype = getattr(value, "dtype", None)
    if dtype is None:
        return int(value) if isinstance(value, numbers.Integral) else None
    if getattr(dtype, "kind", None) not in ("i", "u") or getattr(value, "shape", None) != ():
        return None
    try:
        return operator.index(value)
    except Exception:  # a traced value (JAX's TracerIntegerConversionError), or no __index__
        return None


def _is_traced(value) -> bool:
    """Whether `value` is a JAX tracer (under jit, vmap or grad), told by its type's name."""
    return any(kind.__name__ == "Tracer" and kind.__module__.startswith("jax") for kind in type(value).__mro__)


def _not_static(value, name, what):
    """The InvalidInputError of a traced ``value`` given for an option that must be ``what`` ("a
    concrete int", "a static Python number", "a static Python bool"), else None: the one check
    (:func:`_int`, :func:`_real`, :func:`_bool`) of every option that sets what is compiled (sizes,
    counts, tolerances, ratios, flags) and so must be known while tracing; it says how to pass one
    (``jax.jit``'s ``static_argnames``, or ``functools.partial`` outside the transformation)."""
    if not _is_traced(value):
        return None
    return InvalidInputError(f"{name} must be {what}, not a traced value (under jit, vmap or grad): pass {name} as a "
                             f"static argument (jax.jit(f, static_argnames=...)) or bind it outside the transformation "
                             f"(functools.partial(f, {name}=...)), got {value!r}")


def _not_an_int(value, name):
    """The InvalidInputError of a value :func:`_integer` refuses."""
    return _not_static(value, name, "a concrete int") or InvalidInputError(f"{name} must be an int, got {value!r}")


def _int(value, name, minimum):
    """``value`` as an int >= ``minimum``: a concrete integer scalar (:func:`_integer`); bools refused.
    The one int rule: :func:`jaxpose._validate.check_int` is this. An int below ``minimum`` is
    shown as its number (``got 4``, whether it came as ``4``, ``np.int64(4)`` or ``jnp.int32(4)``)."""
    number = _integer(value)
    if number is None:
        raise _not_an_int(value, name)
    if number < minimum:
        raise InvalidInputError(f"{name} must be >= {minimum}, got {number}")
    return number


DATASET_INSTANCES = 200  # objects per class of the built-in dataset at most: it is built whole in memory
# (0.1-0.75 MB an object, the spider's the most: 12 classes of 200, about 1.8 GB, within MEMORY_BUDGET)


def check_instances(value, name, minimum):
    """``value`` as the built-in dataset's objects per class: an int in [minimum, DATASET_INSTANCES]
    (the one rule of make_dataset, evaluate's and tune's ``--instances`` and TuneOptions)."""
    number = _int(value, name, minimum)
    if number > DATASET_INSTANCES:
        raise InvalidInputError(f"{name} must be <= {DATASET_INSTANCES} (the built-in dataset is built in memory, "
                                f"up to 0.75 MB an object), got {number}; for more objects, write them to a folder "
                                "and give it as --data / load_folder")
    return number


def _bool(value, name):
    """``value`` as a bool: Python's or NumPy's, as :func:`jaxpose._validate.check_bool` takes;
    NumPy's told by its type, without importing NumPy (the command line imports this module
    before NumPy, to give NumPy one BLAS thread first: :func:`jaxpose.batch.workers.configure_process`)."""
    kind = type(value)
    if not (kind is bool or (kind.__module__ == "numpy" and kind.__name__ in ("bool", "bool_"))):
        raise _not_static(value, name, "a static Python bool") or InvalidInputError(
            f"{name} must be True or False, got {value!r}")
    return bool(value)


def is_name(value, names) -> bool:
    """``value`` is a str (or None) among ``names``: the one check of an option chosen by name. An
    array was compared element-wise (NumPy's "truth value of an array is ambiguous" ValueError, or
    a one-element array taken as its name and then an unhashable dict key)."""
    return (value is None or isinstance(value, str)) and value in names


def _choice(value, name, choices):
    if not is_name(value, choices):
        raise InvalidInputError(f"{name} must be one of {', '.join(repr(c) for c in choices)}, got {value!r}")
    return value


def _set(obj, **values):
    for key, value in values.items():
        object.__setattr__(obj, key, value)


def check_known(given, valid, what="option", show=str):
    """Refuse the names in ``given`` that are not in ``valid`` (InvalidInputError: "unknown
    option(s) a, b; valid: ..." in ``valid``'s order; ``what`` names them, ``show`` writes each)."""
    unknown = sorted(set(given) - set(valid))
    if unknown:
        raise InvalidInputError(f"unknown {what}{'s' if len(unknown) > 1 else ''} {', '.join(map(show, unknown))}; "
                                f"valid: {', '.join(valid)}")


def _base(cls, config, options, valid):
    """The config a ``create`` starts from: ``config`` (default ``cls()``), which must be a ``cls``;
    refuses, naming them, the keyword ``options`` not in ``valid`` (listed in that order)."""
    base = cls() if config is None else config
    if not isinstance(base, cls):
        raise InvalidInputError(f"config must be a {cls.__name__}, got {type(base).__name__}")
    check_known(options, valid)
    return base


def _create(cls, config, options):
    """``config`` (default ``cls()``) with the keyword ``options`` (its fields) replaced; an unknown
    name raises InvalidInputError naming it and the valid ones (``cls(**options)`` raised
    ``__init__``'s TypeError)."""
    base = _base(cls, config, options, tuple(f.name for f in dataclasses.fields(cls)))
    return dataclasses.replace(base, **options) if options else base


def _real(value, name, low, high=math.inf, closed=True, interval=None, closed_high=True):
    """``value`` as a float in [low, high] (or (low, high] with ``closed=False``, [low, high) with
    ``closed_high=False``): the one number rule
    of the library (:func:`jaxpose._validate.check_real` is this with ``high`` inf) and its one
    wording. A real number is a ``numbers.Real`` (Python's, NumPy's) or a () NumPy or JAX array or
    scalar of reals (ml_dtypes' floats included); bools, strings (``"0.1"``), timedeltas, other
    objects that ``float()`` takes (``Decimal``, a class with ``__float__``), arrays of other
    shapes, traced values and ints beyond a float's range are refused by name (told without
    importing NumPy: by type and dtype kind).

    The message: ``"{name} must be a finite number >= {low}"`` (``> {low}`` with ``closed=False``)
    where ``high`` is inf, ``"{name} must be a number in {interval}"`` where it is finite
    (``interval`` default from low, high, closed: ``[0, 1]``); then ``", got {value}"``, a () array
    shown as its number. A traced value: ``"{name} must be a static Python number, not a traced
    value ..."`` with how to pass one (:func:`_not_static`)."""
    traced = _not_static(value, name, "a static Python number")
    if traced is not None:  # (it read "tol must be a finite number > 0, got JitTracer(~float32[])")
        raise traced
    dtype, shown = getattr(value, "dtype", None), None
    if (isinstance(value, (bool, str, bytes)) or getattr(value, "shape", ()) != ()
            or (dtype is not None and getattr(dtype, "kind", None) not in ("f", "i", "u", "V"))
            or (dtype is None and not isinstance(value, numbers.Real))):
        v = math.nan  # (float() took "0.1", a (1,) array, NumPy's bools and timedeltas, Decimal, any object with __float__)
    else:
        try:
            v = float(value)
        except (TypeError, ValueError):  # (a traced value: JAX's ConcretizationTypeError, a TypeError)
            v = math.nan
        except OverflowError:  # an int no float holds (was the OverflowError itself)
            v, shown = math.nan, f"an int of {int(value).bit_length()} bits"
    if not (math.isfinite(v) and (low <= v if closed else low < v) and (v <= high if closed_high else v < high)):
        if (shown is None and getattr(dtype, "kind", None) in ("f", "i", "u") and getattr(value, "shape", None) == ()
                and not _is_traced(value)):
            shown = repr(value.item())  # a () array as its number ("got -2.0", not "got array(-2.)")
        if math.isinf(high) and interval is None:
            rule = f"a finite number {'>=' if closed else '>'} {low:g}"
        else:
            rule = f"a number in {interval or ('[' if closed else '(') + f'{low:g}, {high:g}' + (']' if closed_high else ')')}"
        raise InvalidInputError(f"{name} must be {rule}, got {shown or repr(value)}")
    return v


@dataclasses.dataclass(frozen=True)
class OCSVMOptions:
    """The paper's estimator (``method="ocsvm"``): its parameters and the samples it is fitted to.

    Attributes:
      gamma: Gaussian kernel width, dimensionless (points in the reference frame of
        :mod:`jaxpose.pose.frame`), > 0; the paper's value.
      nu: the OCSVM's slack, the share of samples allowed outside the region, in [0, 1].
      count: surface samples per object (>= 4).
      seed: the samples' seed (>= 0).
      sampling: ``"even"`` (stratified per-face counts) or ``"random"`` (:data:`SAMPLING`).

    Example::

        options = dataclasses.replace(OCSVM, gamma=30.0)  # the defaults, but a wider kernel
    """

    gamma: float = 47.0
    nu: float = 0.5
    count: int = 2000
    seed: int = 0
    sampling: str = "even"

    def __post_init__(self):
        _set(self, gamma=_real(self.gamma, "gamma", 0.0, closed=False), nu=_real(self.nu, "nu", 0.0, 1.0),
             count=_int(self.count, "count", 4), seed=_int(self.seed, "seed", 0),
             sampling=_choice(self.sampling, "sampling", SAMPLING))


@dataclasses.dataclass(frozen=True)
class RobustOptions:
    """The robust estimator (``method="robust"``, the default): center sum d^p x / sum d^p over the
    voxels of the robust solid, d a voxel's depth to the outside.

    Attributes:
      power: the depth exponent p of the center's weights, >= 0 (0: the solid's centroid).

    Example::

        pose = jaxpose.normalize(points, power=RobustOptions(power=2.0).power)  # a depth^2-weighted center
    """

    power: float = 4.0

    def __post_init__(self):
        _set(self, power=_real(self.power, "power", 0.0))


@dataclasses.dataclass(frozen=True)
class TuneOptions:
    """:func:`jaxpose.tuning.tune`'s schedule and data (``jaxpose tune``): the defaults of both.

    Attributes:
      steps: Adam steps (>= 0).
      lr: Adam's learning rate in the tuned coordinates ((log gamma, logit nu) or log power), > 0.
      reg: pull towards the start, a share of the start's loss per unit squared distance, >= 0.
      scale_weight: weight of the scale's spread (cv) in the loss, >= 0.
      holdout: share of the classes held out of the loss (whole classes) and evaluated, in [0, 1).
      count: surface samples per object, drawn afresh at every step (>= 4).
      instances: objects per class of the built-in procedural dataset (``jaxpose tune``; 2 to
        :data:`DATASET_INSTANCES`).

    The one check of these values: :func:`jaxpose.tuning.check_options` (``tune``, ``jaxpose
    tune``) checks them by building one, field by field in this order.

    Example::

        result = tuning.tune(classes, steps=TUNE.steps * 2)  # twice the default schedule
    """

    steps: int = 12
    lr: float = 0.1
    reg: float = 0.05
    scale_weight: float = 0.0
    holdout: float = 0.0
    count: int = 400
    instances: int = 6

    def __post_init__(self):
        _set(self, steps=_int(self.steps, "steps", 0), lr=_real(self.lr, "lr", 0.0, closed=False),
             reg=_real(self.reg, "reg", 0.0), scale_weight=_real(self.scale_weight, "scale_weight", 0.0),
             holdout=_real(self.holdout, "holdout", 0.0, math.nextafter(1.0, 0.0), interval="[0, 1)"),
             count=_int(self.count, "count", 4), instances=check_instances(self.instances, "instances", 2))


OCSVM = OCSVMOptions()  # the defaults, read by every function that takes these parameters
ROBUST = RobustOptions()
TUNE = TuneOptions()
OCSVM_ONLY = tuple(field.name for field in dataclasses.fields(OCSVMOptions))
"""The options only the OCSVM reads (as the center, the scale or the frame), the fields of
:class:`OCSVMOptions`: ``("gamma", "nu", "count", "seed", "sampling")``. The one list that
:func:`jaxpose.normalize_mesh`, :class:`jaxpose.batch.task.NormalizeOptions` and the ``normalize``
command read to refuse them where no OCSVM runs (None standing for their defaults, :data:`OCSVM`)."""


ITERATION_LIMIT = 2**31 - 1  # SolverConfig: the solvers' iteration counters are int32


@dataclasses.dataclass(frozen=True)
class SolverConfig:
    """How the SVDD dual is solved (see :func:`jaxpose.fit_svdd`).

    Attributes:
      tol: stop when the relative KKT violation is at most ``tol`` (> 0, finite).
      max_iter: iteration cap (>= 1, and ``max_iter + check_every`` at most
        :data:`ITERATION_LIMIT`); ``SVDD.converged`` is False when it is hit. SMO stops at
        it exactly; projected gradient at the first check at or past it (in steps of
        ``check_every``: at most ``max_iter + check_every - 1`` iterations).
      check_every: projected-gradient steps between two checks of the stopping rule (>= 1).
      kernel: ``"auto"`` (dense up to 12,000 points), ``"dense"`` or ``"blocked"``
        (memory O(m * block), the kernel matrix is never stored).
      block: kernel rows per block of the blocked products (>= 1).
      solver: ``None`` (``"pg"`` up to 2,500 points, ``"auto"`` above, on CPU), ``"pg"``,
        ``"smo"`` or ``"auto"`` (SMO, then projected gradient if it has not converged).
    """

    tol: float = 1e-3
    max_iter: int = 20_000
    check_every: int = 10
    kernel: str = "auto"
    block: int = BLOCK
    solver: str | None = None

    def __post_init__(self):
        _set(self, tol=_real(self.tol, "tol", 0.0, closed=False), max_iter=_int(self.max_iter, "max_iter", 1),
             check_every=_int(self.check_every, "check_every", 1),
             kernel=_choice(self.kernel, "kernel", KERNELS), block=_int(self.block, "block", 1),
             solver=_choice(self.solver, "solver", SOLVERS))
        if self.max_iter + self.check_every > ITERATION_LIMIT:  # the solvers count iterations in int32
            raise InvalidInputError(f"max_iter + check_every must be at most {ITERATION_LIMIT}, got "
                                    f"{self.max_iter} + {self.check_every}")

    @classmethod
    def create(cls, config: "SolverConfig | None" = None, **options) -> "SolverConfig":
        """``config`` (default: the defaults) with the keyword ``options`` replaced; unknown names
        raise InvalidInputError."""
        return _create(cls, config, options)


@dataclasses.dataclass(frozen=True)
class GridConfig:
    """How the volume integrals over {f >= 0} are discretized (see :func:`jaxpose.volume_moments`).

    Attributes:
      resolution: coarse cells per axis (>= 8) on a box that provably covers the region.
      refine: a power of 2: cells near the boundary are split in 2 x 2 x 2, log2(refine) times.
      band: cells refined at the first level (>= 0), doubled at each further level.
      block: cells per block of the evaluation of f (>= 1).
      extrapolate: Richardson-combine the two finest levels (error O(h^4) instead of O(h^2)).

    The grid's peak memory, :attr:`memory` (``CELL_BYTES`` per cell: resolution^3 coarse cells and
    8 children per refined cell), must fit ``MEMORY_BUDGET``; a larger grid is refused with the figure.
    """

    resolution: int = 64
    refine: int = 2
    band: int = 16384
    block: int = BLOCK
    extrapolate: bool = True

    def __post_init__(self):
        refine = _int(self.refine, "refine", 1)
        if refine & (refine - 1):
            raise InvalidInputError(f"refine must be a power of 2, got {self.refine!r}")
        _set(self, resolution=_int(self.resolution, "resolution", 8), refine=refine,
             band=_int(self.band, "band", 0), block=_int(self.block, "block", 1),
             extrapolate=_bool(self.extrapolate, "extrapolate"))
        if self.memory > MEMORY_BUDGET:
            largest = int((MEMORY_BUDGET / CELL_BYTES - self._children) ** (1.0 / 3.0)) if \
                MEMORY_BUDGET / CELL_BYTES > self._children else 0
            fix = (f"use a resolution in [8, {largest}]" if largest >= 8 else  # ('[8, 0]' read as a range)
                   f"no resolution fits this band and refine (their refined cells alone need "
                   f"{CELL_BYTES * self._children / 2**30:.3g} GiB): use a smaller band or refine")
            raise InvalidInputError(
                f"resolution={self.resolution} (refine={self.refine}, band={self.band}) needs about "
                f"{self.memory / 2**30:.2f} GiB for the grid ({self.memory / CELL_BYTES:.2g} cells at {CELL_BYTES} "
                f"bytes); the limit is {MEMORY_BUDGET / 2**30:g} GiB: {fix}")

    @classmethod
    def create(cls, config: "GridConfig | None" = None, **options) -> "GridConfig":
        """``config`` (default: the defaults) with the keyword ``options`` replaced; unknown names
        raise InvalidInputError."""
        return _create(cls, config, options)

    @property
    def _children(self) -> int:
        levels = self.refine.bit_length() - 1
        return 8 * self.band * (2**levels - 1)

    @property
    def memory(self) -> int:
        """Peak bytes of the grid (an upper bound: every refinement slot filled)."""
        return CELL_BYTES * (self.resolution**3 + self._children)


_SOLVER_FIELDS = tuple(f.name for f in dataclasses.fields(SolverConfig))
_GRID_FIELDS = tuple(f.name for f in dataclasses.fields(GridConfig))


@dataclasses.dataclass(frozen=True)
class PoseConfig:
    """Every static option of :func:`jaxpose.normalize`.

    Attributes:
      svdd: :class:`SolverConfig`.
      grid: :class:`GridConfig`.
      derivative: what the derivatives in (gamma, nu) are (``docs/design.md``, "How gradients
        flow"): ``"trend"`` (default) the slope of the SVDD solution over theta (1 +- delta) in
        both gamma and nu, which follows the pose over steps of 1-2 %; ``"exact"`` the implicit
        KKT derivative of the computed solution, the slope of the one piece of a piecewise
        function that theta lies on; ``"secant"`` the slope in nu and the implicit derivative in
        gamma. Derivatives in the points are implicit in every mode.
      gamma_delta: relative half-width of the gamma interval of the trend, in (0, 0.5).
      nu_delta: relative half-width of the nu interval of the trend and the secant, in (0, 0.5).
      secant_iterations: how the two solutions at the ends of an interval are computed: None
        (default) each solved to ``nu_tol``; or that many projected-gradient steps of both from
        the solution at the center, in lock-step (>= 1): cheaper, but the difference converges
        as slowly as the solver's slowest modes (``docs/design.md``).
      nu_tol: solver tolerance of the secant solves, in gamma and in nu (None: min(tol, 1e-5);
        see :meth:`secant_tol`).
    """

    svdd: SolverConfig = SolverConfig()
    grid: GridConfig = GridConfig()
    derivative: str = "trend"
    nu_delta: float = 0.01
    nu_tol: float | None = None
    gamma_delta: float = 0.01
    secant_iterations: int | None = None

    FLAT = tuple(dict.fromkeys(_SOLVER_FIELDS + _GRID_FIELDS + ("derivative", "nu_delta", "nu_tol", "gamma_delta",
                                                                        "secant_iterations")))

    def __post_init__(self):
        if not isinstance(self.svdd, SolverConfig) or not isinstance(self.grid, GridConfig):
            raise InvalidInputError("PoseConfig needs a SolverConfig (svdd) and a GridConfig (grid)")
        _choice(self.derivative, "derivative", DERIVATIVES)
        deltas = {name: _real(getattr(self, name), name, 0.0, 0.5, closed=False, closed_high=False)
                  for name in ("nu_delta", "gamma_delta")}
        nu_tol = None if self.nu_tol is None else _real(self.nu_tol, "nu_tol", 0.0, closed=False)
        iters = None if self.secant_iterations is None else _int(self.secant_iterations, "secant_iterations", 1)
        _set(self, nu_tol=nu_tol, secant_iterations=iters, **deltas)

    def secant_tol(self) -> float:
        """Solver tolerance of the secant solves: ``nu_tol``, or min(tol, 1e-5) (measured: the
        slopes at 1e-5 and 1e-6 agree to 3 digits, at 1e-4 to ~5 %)."""
        if self.nu_tol is not None:
            return self.nu_tol
        return min(self.svdd.tol, 1e-5)

    @classmethod
    def create(cls, config: "PoseConfig | None" = None, **options) -> "PoseConfig":
        """``config`` (default: the defaults) with the flat keyword ``options`` replaced.

        Solver names (``tol``, ``max_iter``, ``check_every``, ``kernel``, ``solver``) go to
        :class:`SolverConfig`, grid names (``resolution``, ``refine``, ``band``, ``extrapolate``)
        to :class:`GridConfig`; ``block`` sets both. Raises InvalidInputError naming any unknown
        option or bad value.
        """
        base = _base(cls, config, options, sorted(cls.FLAT))
        if not options:
            return base
        svdd = {k: v for k, v in options.items() if k in _SOLVER_FIELDS}
        grid = {k: v for k, v in options.items() if k in _GRID_FIELDS}
        rest = {k: v for k, v in options.items() if k not in _SOLVER_FIELDS + _GRID_FIELDS}
        return dataclasses.replace(base, svdd=dataclasses.replace(base.svdd, **svdd),
                                   grid=dataclasses.replace(base.grid, **grid), **rest)

    def flat(self) -> dict:
        """The options as flat keywords (JSON-able), the inverse of :meth:`create`."""
        return {**dataclasses.asdict(self.svdd), **dataclasses.asdict(self.grid), "derivative": self.derivative,
                "nu_delta": self.nu_delta, "nu_tol": self.nu_tol, "gamma_delta": self.gamma_delta,
                "secant_iterations": self.secant_iterations}


@dataclasses.dataclass(frozen=True)
class RobustConfig:
    """Static options of the robust estimator of a point cloud (:mod:`jaxpose.occupancy.points`).

    Attributes:
      resolution: voxels along the main body's largest extent (>= 8).
      coarse: the same for the first pass over every point (>= 8).
      keep_ratio: a separate component is kept when its boundary has at least this share of the
        main body's, in [0, 1].
      max_closing: the pitch is coarsened so that the closing radius stays within this many
        voxels (>= 1); the radius may then grow to 3 times its start when the fill leaks.
      spacing_samples: the points' spacing is measured from at most this many of them (>= 1).

    The grid of a pass has ``resolution + 6 max_closing + 7`` cells per axis; its peak memory
    (about 64 bytes per cell) must fit ``MEMORY_BUDGET``.
    """

    resolution: int = 96
    coarse: int = 48
    keep_ratio: float = 0.5
    max_closing: int = 4
    spacing_samples: int = 10_000

    def __post_init__(self):
        ratio = _real(self.keep_ratio, "keep_ratio", 0.0, 1.0)  # the number rule (float() took "0.5", a traced one)
        _set(self, resolution=_int(self.resolution, "resolution", 8), coarse=_int(self.coarse, "coarse", 8),
             keep_ratio=ratio, max_closing=_int(self.max_closing, "max_closing", 1),
             spacing_samples=_int(self.spacing_samples, "spacing_samples", 1))
        cells = max(self.resolution, self.coarse) + 6 * self.max_closing + 7
        if 64 * cells**3 > MEMORY_BUDGET:
            raise InvalidInputError(
                f"resolution={self.resolution} needs about {64 * cells**3 / 2**30:.2f} GiB for the voxel grid "
                f"({cells}^3 cells); the limit is {MEMORY_BUDGET / 2**30:g} GiB: use a smaller resolution")

    FLAT = ("resolution", "coarse", "keep_ratio", "max_closing", "spacing_samples")

    @classmethod
    def create(cls, config: "RobustConfig | None" = None, **options) -> "RobustConfig":
        """``config`` (default: the defaults) with the keyword ``options`` replaced; unknown names
        raise InvalidInputError."""
        return _create(cls, config, options)

    def flat(self) -> dict:
        """The options as flat keywords (JSON-able), the inverse of :meth:`create`."""
        return dataclasses.asdict(self)
