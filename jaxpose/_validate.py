"""Input checks on concrete (NumPy) values, run before anything is traced.

Every public entry point calls these first, so that bad input gets a readable
:class:`JaxposeError` instead of a NaN or a JAX-internal traceback.
"""
from __future__ import annotations

import os
import sys

import numpy as np

from .config import _bool, _int, _real, check_known, is_name  # (config's rules: NumPy-free, config is imported before NumPy)
from .errors import ConvergenceError, InvalidInputError, InvalidPoseWarning, JaxposeError, OpenMeshWarning

__all__ = [
    "JaxposeError",
    "InvalidInputError",
    "ConvergenceError",
    "OpenMeshWarning",
    "InvalidPoseWarning",
    "check_points",
    "check_gamma",
    "check_nu",
    "check_array",
    "check_mask",
    "check_faces",
    "is_name",
    "check_int",
    "check_bool",
    "check_real",
    "check_names",
    "check_known",
    "check_callback",
    "compute_dtype",
    "jax_value",
    "check_shape",
    "is_real_dtype",
    "default_float",
    "check_default_float",
    "is_traced",
    "check_traced_scalar",
    "check_concrete",
    "check_power",
    "check_throw",
]

MIN_POINTS = 4


def is_traced(x) -> bool:
    """True for JAX tracers (inside jit/vmap/grad), where values cannot be checked.

    Does not import JAX: before JAX is imported no tracer can exist, so NumPy-only paths stay light.
    """
    jax = sys.modules.get("jax")
    return jax is not None and isinstance(x, jax.core.Tracer)


def check_concrete(name: str, *values):
    """Refuse traced values (under jit, vmap or grad) given to a function that computes on the host
    in NumPy (the geometry readers and estimators): InvalidInputError naming ``name`` and the fix.
    Returns None."""
    # (np.asarray of a tracer raised JAX's TracerArrayConversionError, naming no argument)
    if any(is_traced(v) for v in values):
        raise InvalidInputError(f"{name}: a traced array (under jit, vmap or grad): meshes, point clouds and their "
                                "estimators (jaxpose.baselines, estimators.estimate, rotation.frame_of, sample_surface, "
                                "normalize_mesh) are computed on the host in NumPy; call them on concrete values "
                                "outside the transformation, or trace jaxpose.normalize(points) instead")


def is_real_dtype(dtype) -> bool:
    """NumPy's floats and integers, and the floats that ml_dtypes adds to NumPy for JAX (bfloat16,
    float8_*: dtype kind 'V' to NumPy); not bool, complex, object, datetimes or timedeltas."""
    dtype = np.dtype(dtype)
    if dtype.kind == "m":  # timedelta64: an integer subtype to NumPy, but no number JAX computes with
        return False
    if np.issubdtype(dtype, np.floating) or np.issubdtype(dtype, np.integer):
        return True
    ml_dtypes = sys.modules.get("ml_dtypes")  # imported with JAX: no such array exists before it
    if ml_dtypes is None or dtype.kind != "V":
        return False
    try:
        ml_dtypes.finfo(dtype)
    except (TypeError, ValueError):
        return False
    return True


def check_array(x, name: str = "x", min_rows: int = 0, finite: bool = True):
    """Check an (n, 3) array of real numbers (n >= min_rows), finite where ``finite``; return it
    unchanged.

    Tracers are returned as they are (only their shape and dtype are checked); ``finite=False``
    checks a concrete array's shape and dtype alone too (JAX functions whose NaN the pose's status
    reports). A mesh or a path given for the array is named so, with the fix (it read "must have
    shape (m, 3), got ()").
    """
    if hasattr(x, "vertices"):  # a Trimesh, PointCloud (its .shape is its vertices') or Surface
        raise InvalidInputError(f"{name} must have shape (m, 3), an array, got a {type(x).__name__}: pass its vertices "
                                f"(.vertices), or surface samples (jaxpose.sample_surface(mesh, count)); "
                                "jaxpose.normalize_mesh takes a mesh itself")
    if isinstance(x, (str, bytes, os.PathLike)):
        raise InvalidInputError(f"{name} must have shape (m, 3), an array, got the {type(x).__name__} {str(x)!r:.80}: "
                                "a file is loaded first (jaxpose.mesh.load, jaxpose.sample_surface(path, count)); "
                                "jaxpose.normalize_mesh takes a path itself")
    shape = getattr(x, "shape", None)
    if shape is None:
        try:
            x = np.asarray(x)
        except Exception as exc:  # ragged lists and the like
            raise InvalidInputError(f"{name} must be an (m, 3) array: {exc}") from None
        shape = x.shape
    if len(shape) != 2 or shape[1] != 3:
        raise InvalidInputError(f"{name} must have shape (m, 3), got {tuple(shape)}")
    if shape[0] < min_rows:
        raise InvalidInputError(f"{name} needs at least {min_rows} point{'' if min_rows == 1 else 's'}, got {shape[0]}")
    if is_traced(x) or not finite:  # (the dtype read where the array says it: no copy to the host)
        try:
            dtype = np.dtype(x.dtype)
        except (AttributeError, TypeError):  # a list, or an array whose dtype NumPy does not name (torch)
            dtype = np.asarray(x).dtype
        if not is_real_dtype(dtype):  # known when tracing
            raise InvalidInputError(f"{name} must be real numbers, got dtype {dtype}")
        return x
    arr = np.asarray(x)
    if not is_real_dtype(arr.dtype):
        raise InvalidInputError(f"{name} must be real numbers, got dtype {arr.dtype}")
    if finite and not np.all(np.isfinite(arr)):
        bad = int(np.count_nonzero(~np.isfinite(arr).all(axis=1)))
        raise InvalidInputError(f"{name} has {bad} row{'s' if bad != 1 else ''} with NaN or inf coordinates")
    return x


def check_mask(mask, rows: int, name: str = "points"):
    """``mask`` None or of shape (rows,), one flag per point of the (rows, 3) array ``name``
    (its shape is known while tracing; its values are not read); InvalidInputError otherwise (JAX's
    broadcast errors). Returns ``mask`` unchanged."""
    if mask is not None and tuple(np.shape(mask)) != (rows,):
        raise InvalidInputError(f"mask must have shape ({rows},), one flag per point of {name}, got "
                                f"{tuple(np.shape(mask))}")
    return mask


def check_points(points, name: str = "points", min_points: int = MIN_POINTS):
    """Check an (m, 3) array of finite, not all identical points; return it unchanged.

    Tracers are returned as they are (only their shape and dtype are checked).
    """
    points = check_array(points, name, min_points)
    if is_traced(points):
        return points
    arr = np.asarray(points)
    if len(arr) and np.all(arr == arr[0]):
        raise InvalidInputError(f"all {arr.shape[0]} {name} are identical: no shape to normalize")
    if len(arr) and arr.dtype.kind in "iu" and np.all((f := arr.astype(np.float64)) == f[0]):  # what is computed with
        raise InvalidInputError(f"all {arr.shape[0]} {name} are identical as float64 (integers beyond 2**53 round "
                                "together): no shape to normalize; subtract their offset first")
    return points


def check_faces(faces, n):
    """``faces`` as an (f, 3) int64 array of indices of ``n`` vertices (f >= 1), else
    InvalidInputError: integers, or floats holding whole numbers (as :func:`jaxpose.mesh.load`
    takes them); fractions, bools and other kinds refused (float indices were truncated into
    other faces, out-of-range ones an IndexError)."""
    faces = np.asarray(faces)
    if faces.ndim != 2 or faces.shape[1] != 3 or not len(faces):
        raise InvalidInputError(f"faces must be (f, 3) integer indices of the vertices (shape (f, 3), f >= 1), got "
                                f"shape {faces.shape}")
    kind = faces.dtype.kind
    with np.errstate(invalid="ignore"):  # (inf: no whole number, refused below, not a RuntimeWarning)
        whole = kind == "f" and bool(np.all(np.mod(faces, 1) == 0))
    if kind not in "iu" and not whole:
        fractions = " with fractions" if kind == "f" else ""
        raise InvalidInputError(f"faces must be (f, 3) integer indices of the vertices, got {faces.dtype}{fractions}")
    if faces.min() < 0 or faces.max() >= n:  # (an IndexError deep in the ray votes)
        low, high = (int(v) for v in (faces.min(), faces.max()))
        raise InvalidInputError(f"faces index vertices that do not exist (indices {low} ... {high}, {n} vertices)")
    return faces.astype(np.int64, copy=False)


def compute_dtype(points):
    """The floating dtype JAX computes points in (concrete, or a JAX array or tracer, read from its
    dtype): at least float32 (float16, bfloat16 and integers are promoted), float64 only when x64
    is enabled; NumPy's longdouble (wider than JAX's widest float) computes as float64 would."""
    from jax import dtypes

    given = getattr(points, "dtype", None)  # NumPy and JAX arrays, tracers: no copy
    dtype = np.result_type(np.asarray(points).dtype if given is None else np.dtype(given), np.float32)
    if not np.issubdtype(dtype, np.floating):
        dtype = np.dtype(np.float32)
    elif dtype.itemsize > 8:  # longdouble (float128): JAX has no such dtype (its TypeError deep in a staged call)
        dtype = np.dtype(np.float64)
    return np.dtype(dtypes.canonicalize_dtype(dtype))


def jax_value(value):
    """``value`` as JAX can take it: a concrete NumPy array or scalar of NumPy's longdouble (float128
    on x86, wider than JAX's widest float; its complex clongdouble too) as its float64 (complex128)
    value, the rule of :func:`compute_dtype` (a longdouble computes as float64 would); every other
    value (Python numbers, other dtypes, JAX arrays, tracers, None) is returned as it is. JAX has no
    name for longdouble: it was JAX's TypeError 'Error interpreting argument ... as an abstract
    array' in a staged call."""
    dtype = getattr(value, "dtype", None)
    if not isinstance(value, (np.ndarray, np.generic)) or dtype.kind not in "fc":
        return value
    if dtype.itemsize > (8 if dtype.kind == "f" else 16):
        return np.asarray(value, np.float64 if dtype.kind == "f" else np.complex128)
    return value


def check_shape(value, name, shape, finite=False):
    """``value`` as a NumPy array of real numbers of exactly ``shape`` (its dtype kept, not copied
    where it is one); InvalidInputError naming ``name`` otherwise, and for NaN or inf where
    ``finite`` (low-level host functions of fixed shapes: a wrong one was NumPy's IndexError,
    LinAlgError or broadcast error deep inside). A traced value is refused by name: the callers
    compute on the host."""
    want = f"({', '.join(map(str, shape))}{',' if len(shape) == 1 else ''})"
    if is_traced(value):
        raise InvalidInputError(f"{name}: a traced array (under jit, vmap or grad); this function computes on the host "
                                "in NumPy: call it on concrete values")
    try:
        a = np.asarray(value)
    except Exception as exc:  # ragged lists and the like
        raise InvalidInputError(f"{name} must be real numbers of shape {want}: {exc}") from None
    if not is_real_dtype(a.dtype) or a.shape != tuple(shape):
        raise InvalidInputError(f"{name} must be real numbers of shape {want}, got {a.dtype} of shape {a.shape}")
    if finite and not np.all(np.isfinite(a)):
        raise InvalidInputError(f"{name} must be finite, got NaN or inf")
    return a


def check_traced_scalar(value, name):
    """A traced parameter's shape and dtype, which are known while tracing (its value is not: the
    pose's validity flag reports a bad one): a () real number (not bool, not complex), as a
    concrete one must be; InvalidInputError naming ``name`` otherwise. Returns ``value``;
    concrete values pass unchecked (their own checks read them)."""
    # (a traced (2,) gamma failed deep inside JAX, 'Incompatible shapes for broadcasting'; a complex
    # one lost its imaginary part with only a NumPy warning; a bool was taken as 0 or 1)
    if is_traced(value) and (tuple(value.shape) != () or not is_real_dtype(value.dtype)):
        shape = "".join(f"{n}, " for n in value.shape).rstrip(", ")
        raise InvalidInputError(f"{name} must be a real scalar, got a traced {np.dtype(value.dtype)}[{shape}] "
                                f"(one value: to vary {name}, jax.vmap over it)")
    return value


def default_float() -> np.dtype:
    """JAX's default float dtype, the one a Python float becomes under ``jit``: float32, float64
    with ``jax_enable_x64``. Does not import JAX: before JAX is imported its setting is the
    ``JAX_ENABLE_X64`` environment variable's."""
    jax = sys.modules.get("jax")
    config = getattr(jax, "config", None)
    if config is not None and hasattr(config, "jax_enable_x64"):
        x64 = bool(config.jax_enable_x64)
    else:
        x64 = os.environ.get("JAX_ENABLE_X64", "").strip().lower() in ("1", "true", "t", "yes", "y", "on")
    return np.dtype(np.float64 if x64 else np.float32)


def check_gamma(gamma, name="gamma"):
    """A concrete gamma: a finite real number > 0 (:func:`check_real`'s rule and wording, "gamma
    must be a finite number > 0, got ...") that JAX's default float dtype holds as a normal number
    (float32: 1.2e-38 ... 3.4e38; beyond, it would become inf or 0 inside the pipeline); traced, a
    () real (:func:`check_traced_scalar`). ``name``: the argument's (``gamma0``). Returns ``gamma``
    unchanged."""
    if is_traced(gamma):
        return check_traced_scalar(gamma, name)
    check_default_float(_real(gamma, name, 0.0, closed=False), name, normal=True)
    return gamma


def check_default_float(value: float, name: str, normal: bool = False) -> float:
    """Refuse a concrete number that JAX's default float (:func:`default_float`) cannot hold:
    beyond its max (inf under ``jit``) or, with ``normal``, a positive one below its smallest normal
    number (0 or subnormal). Returns ``value``."""
    finfo = np.finfo(default_float())
    low = float(finfo.tiny) if normal else 0.0
    if not low <= value <= float(finfo.max):
        raise InvalidInputError(f"{name}={value:g} is outside the range of {finfo.dtype} (JAX's default float), "
                                f"{low:.3g} ... {float(finfo.max):.3g}")
    return value


def check_power(power, name: str = "power"):
    """A depth exponent p (or a depth's ``bias``, the same rule): concrete, a finite number >= 0
    (:func:`check_real`; a () array of reals is its number) that JAX's default float holds
    (:func:`check_default_float`: beyond its max it is inf inside the pipeline); traced, a () real
    (:func:`check_traced_scalar`). Returns ``power`` unchanged."""
    if is_traced(power):
        return check_traced_scalar(power, name)
    check_default_float(check_real(power, name, 0), name)
    return power


def check_nu(nu, name="nu"):
    """A concrete nu: a real number in [0, 1] (:func:`check_real`'s rule and wording, "nu must be a
    number in [0, 1], got ..."); traced, a () real (:func:`check_traced_scalar`). ``name``: the
    argument's (``nu0``). Returns ``nu`` unchanged."""
    if is_traced(nu):
        return check_traced_scalar(nu, name)
    _real(nu, name, 0.0, 1.0)
    return nu


def check_int(value, name, minimum):
    """``value`` as an int >= ``minimum``; a clear error otherwise. An int is a concrete integer
    scalar: a Python or NumPy integer, or a () NumPy or JAX array of an integer dtype (config's
    rule, :func:`jaxpose.config._integer`); bools, floats and traced values are refused."""
    return _int(value, name, minimum)  # config's rule and messages (NumPy-free: config is imported before NumPy)


def check_bool(value, name):
    """``value`` as a bool (Python or NumPy bools only); a clear error otherwise (a string such as
    ``"no"`` would be truthy)."""
    return _bool(value, name)  # config's rule (NumPy-free: config is imported before NumPy)


def check_names(value, name, key=None, what=None):
    """``value``, a collection of names (a list, tuple, set, ...), as a tuple; one string is
    refused by name (its characters would be taken as the names: ``methods="vertex_mean"`` read
    as 'v', 'e', ...), as is anything that is not iterable, and a name given twice (each is run
    once and kept under its name: a repeat ran twice, its result keyed by name kept one of them).
    ``key(name)``, default the name itself, tells two spellings of one apart (``"depth_weighted_solid:2"``
    and ``":2.0"``); the refusal names both spellings, and a key that is a str (what the name means,
    as ``"robust at power 4"``) too: ``methods names 'robust:4' twice (as 'robust'; both are robust at
    power 4)``. With ``what`` (what one name names), a collection of none is refused too: "methods
    names no method; give at least one"."""
    if isinstance(value, (str, bytes)):
        raise InvalidInputError(f"{name} must be a list of names, got the string {value!r}: pass [{value!r}]")
    try:
        names = tuple(value)
    except TypeError:
        raise InvalidInputError(f"{name} must be a list of names, got {value!r:.80}") from None
    seen = {}
    for item in names:
        try:
            k = item if key is None else key(item)
            hash(k)
        except TypeError:  # not a name: the caller's own check names it
            continue
        if k in seen:
            meaning = f"; both are {k}" if isinstance(k, str) and k not in (item, seen[k]) else ""
            same = "" if seen[k] == item else f" (as {seen[k]!r}{meaning})"
            raise InvalidInputError(f"{name} names {item!r} twice{same}; give each once")
        seen[k] = item
    if what is not None and not names:
        raise InvalidInputError(f"{name} names no {what}; give at least one")
    return names


def check_callback(value, name):
    """``value`` if it is None or callable; InvalidInputError naming ``name`` otherwise (checked
    before any work, not at its first call)."""
    if value is not None and not callable(value):
        raise InvalidInputError(f"{name} must be a callable or None, got {value!r:.80}")
    return value


def check_real(value, name, minimum, strict=False):
    """``value`` as a finite float >= ``minimum`` (> with ``strict``): :func:`jaxpose.config._real`,
    the one number rule and wording of the library (the options objects' too: "{name} must be a
    finite number >= {minimum}, got ..."). Bools, non-numbers, NaN, inf, timedeltas and ints beyond
    a float's range refused by name; a concrete () array of reals (NumPy, JAX, ml_dtypes) is its
    number."""
    return _real(value, name, minimum, closed=not strict)


def check_throw(throw, read="Pose.valid / Pose.status", **values):
    """``throw`` as a bool (:func:`check_bool`); True refused (InvalidInputError) where the result
    will be traced, so that no exception can read it: a traced value among ``values`` (named by its
    keyword; pytrees searched), or a call staged into a trace (``jit`` or ``eval_shape`` around a
    concrete call). ``read``: the result's flags to read instead. Checked before any work; a
    ``throw=True`` under jit, vmap or grad did nothing (the invalid pose passed silently)."""
    throw = check_bool(throw, "throw")
    jax = sys.modules.get("jax")
    if not throw or jax is None:  # (no JAX imported: nothing is traced)
        return throw
    traced = [name for name, value in values.items() if any(is_traced(leaf) for leaf in jax.tree.leaves(value))]
    if traced or is_traced(jax.numpy.zeros(())):  # (inside a trace even a new constant is a tracer)
        where = f"traced {traced[0]}" if traced else "a call staged into jit or eval_shape"
        raise InvalidInputError(f"throw=True raises on a concrete result only; here ({where}: under jit, vmap or grad) "
                                f"the result is traced and no exception can read it: leave throw out and read {read} "
                                "(jnp.where on it inside, or after the transformation), or call with concrete values")
    return throw
