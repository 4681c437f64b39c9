"""The result of every estimator: :class:`Pose` (a similarity with its diagnostics) and
:class:`Status` (why a pose is not valid).

Importing this module does not import JAX (NumPy estimators return a Pose without it); methods
that compute with JAX arrays import it when called. What the validity checks are is
:mod:`jaxpose.pose.validity`'s contract.
"""
from __future__ import annotations

import enum
import sys
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from .._validate import InvalidInputError, check_int, is_real_dtype, is_traced
from ..host import MAX_ROUNDING  # the one bound, on the host's side (host.check_cast)

if TYPE_CHECKING:  # annotations only
    import jax

__all__ = ["Pose", "host", "Status", "status_message", "MAX_SPACING", "MAX_CELL", "MIN_SPREAD", "MAX_ROUNDING", "MIN_POINT_VOXELS",
           "ROTATION_TOL", "rotation_tol",
           "SECOND_BODY"]

MAX_SPACING = 2.0  # median nearest-neighbour distance of the samples, in kernel widths
MAX_CELL = 2.0  # finest grid cell edge, in kernel widths
MIN_SPREAD = 0.25  # region mean distance / samples' median distance from its centroid
MIN_POINT_VOXELS = 12  # robust, point clouds: the closed solid spans at least this many voxels along its largest extent
SECOND_BODY = 0.5  # robust, point clouds: a separate part with at least this share of the largest's occupied voxels


def _jnp():
    import jax.numpy as jnp

    return jnp


class Status(enum.IntEnum):
    """Why a pose is not valid (``Pose.status``); ``OK`` (0) when it is. ``Status(code).message``
    explains a code. When several apply, one is reported, a root cause before what it leads to
    (not the codes' numeric order):

    * ``method="ocsvm"``: BAD_PARAMETERS, FAR_FROM_ORIGIN, OUT_OF_RANGE, then
      :func:`jaxpose.pose.validity.pose_status`'s DEGENERATE_INPUT, SPARSE_SAMPLES, UNRESOLVED_GRID,
      EMPTY_REGION, COLLAPSED_REGION, NOT_FINITE (points with no extent or a non-finite
      coordinate are DEGENERATE_INPUT at any size);
    * ``method="robust"``: FAR_FROM_ORIGIN, BAD_PARAMETERS, DEGENERATE_INPUT, OUT_OF_RANGE,
      EMPTY_SOLID, SPARSE_CLOUD, SEPARATE_BODIES, NOT_FINITE.
    """

    OK = 0
    BAD_PARAMETERS = 1
    DEGENERATE_INPUT = 2
    SPARSE_SAMPLES = 3
    UNRESOLVED_GRID = 4
    EMPTY_REGION = 5
    COLLAPSED_REGION = 6
    NOT_FINITE = 7
    EMPTY_SOLID = 8
    FAR_FROM_ORIGIN = 9
    SPARSE_CLOUD = 10
    SEPARATE_BODIES = 11
    OUT_OF_RANGE = 12

    @property
    def message(self) -> str:
        """One sentence: what went wrong and what to change."""
        return _MESSAGES[self]


_MESSAGES = {
    Status.OK: "valid",
    Status.BAD_PARAMETERS: ("a parameter is out of range (ocsvm: gamma finite and > 0, nu in [0, 1]; robust: power "
                            "finite and >= 0)"),
    Status.DEGENERATE_INPUT: "the points have no extent (all identical) or are not finite",
    Status.SPARSE_SAMPLES: (f"the samples are too sparse for gamma: their median spacing exceeds {MAX_SPACING:g} "
                            "kernel widths 1/sqrt(2 gamma), so the region is a cloud of separate balls; use more "
                            "samples or a smaller gamma"),
    Status.UNRESOLVED_GRID: (f"the grid does not resolve the kernel: its finest cell exceeds {MAX_CELL:g} kernel "
                             "widths 1/sqrt(2 gamma), so the result depends on the grid; raise resolution or "
                             "refine, or lower gamma"),
    Status.EMPTY_REGION: "the region {f >= 0} is empty on this grid (no positive volume)",
    Status.NOT_FINITE: "the center or the scale is not finite, or the scale is not positive",
    Status.EMPTY_SOLID: ("the points enclose no volume: the robust solid is empty or no voxel of it lies deeper "
                         "than its surface layer (an open sheet, a scan of one side); use method='ocsvm'"),
    Status.FAR_FROM_ORIGIN: (f"the points lie so far from the origin, relative to their spread, that their dtype "
                             f"cannot resolve them (rounding above {MAX_ROUNDING:g} of the spread): call with a "
                             "concrete array (moved on the host in float64), move the points near the origin "
                             "first, or enable jax_enable_x64"),
    Status.SPARSE_CLOUD: (f"the point cloud is too sparse for a closing: at the voxel size its spacing allows (the "
                          f"90th percentile of the 4-neighbour distance / max_closing) its solid spans fewer than "
                          f"{MIN_POINT_VOXELS} voxels; use more points, or the vertex_mean or ocsvm method"),
    Status.SEPARATE_BODIES: (f"the point cloud is several separate bodies: apart from the largest, a part holds at "
                             f"least {SECOND_BODY:g} of its occupied voxels (parts linked at a dilation of twice the "
                             "closing radius), so no single body sets the pose; normalize each body on its own, or, if it is "
                             "one body sampled too sparsely for its parts to link, sample its surface densely or use the "
                             "vertex_mean or ocsvm method"),
    Status.OUT_OF_RANGE: ("the points' size is beyond what their dtype computes a volume in (robust: its cube "
                          "under- or overflows; in float32, extents outside about 1e-11 ... 1e12) or their reference "
                          "size in (ocsvm: the squares of their distances from their mean under- or overflow; in "
                          "float32, an RMS distance below 4.2e-18 or above 1.8e19 / sqrt(points)): call with a "
                          "concrete array (rescaled on the host in float64), rescale the points first, or enable "
                          "jax_enable_x64"),
    Status.COLLAPSED_REGION: (f"the region collapsed: its mean distance is below {MIN_SPREAD:g} of the samples' "
                              "median distance from its centroid (nu near 1, or too few samples)"),
}


def status_message(code) -> str:
    """The message of a status code: a concrete integer scalar (an int, a NumPy integer, a () NumPy
    or JAX integer array; :func:`jaxpose._validate.check_int`) that is a :class:`Status` code.

    Raises:
      InvalidInputError: a bool, a float, an array of several codes (one pose's status: index a
        batch's first), a traced code (under jit, vmap or grad: read it outside), or an int that is
        no Status code.
    """
    # (int(code) took True as BAD_PARAMETERS and 1.9 as 1; a traced code was JAX's ConcretizationTypeError,
    # a batch's codes NumPy's TypeError, an unknown code enum's ValueError)
    value = check_int(code, "code", 0)
    if value not in Status._value2member_map_:
        raise InvalidInputError(f"code {value} is no Status code; valid: 0 ... {max(Status)._value_} "
                                f"({', '.join(s.name for s in Status)})")
    return Status(value).message



def _xp(*values):
    """NumPy when every given value is concrete NumPy (or a Python number), else jax.numpy."""
    given = [v for v in values if v is not None]
    if all(isinstance(v, (np.ndarray, np.generic, bool, int, float)) for v in given):
        return np
    return _jnp()


def _is_jax(value) -> bool:
    """A JAX array (concrete or traced); found without importing JAX."""
    jax = sys.modules.get("jax")
    return jax is not None and isinstance(value, jax.Array)


def _similarity_xp(*values):
    """Where a similarity is computed: jax.numpy when a value is traced, or when every array given
    is a JAX array; otherwise NumPy in float64 on the host (a NumPy field or NumPy points: every
    digit of a center far from the origin is kept). Python numbers do not count."""
    given = [v for v in values if v is not None]
    if any(is_traced(v) for v in given):
        return _jnp()
    arrays = [v for v in given if type(v) not in (bool, int, float)]  # NumPy scalars count as NumPy
    if arrays and all(_is_jax(v) for v in arrays):
        return _jnp()
    return np


def _floats(xp, *values):
    """The values as arrays of ``xp``: NumPy float64 on the host, JAX arrays as they are in JAX."""
    if xp is np:
        return [None if v is None else np.asarray(v, np.float64) for v in values]
    return [None if v is None else xp.asarray(v) for v in values]


def _shape_of(value, name):
    """The shape of a real array (or array-like); InvalidInputError for anything else (a traced
    one's dtype is known while tracing: bools and complex numbers are refused as concrete ones)."""
    if is_traced(value):
        if not is_real_dtype(value.dtype):  # (a complex center or points were taken as complex, bools as 0 / 1)
            raise InvalidInputError(f"{name} must be real numbers, got a traced {np.dtype(value.dtype)} array")
        return tuple(value.shape)
    if hasattr(value, "shape") and hasattr(value, "dtype"):  # an array (a JAX one: not copied off its device)
        try:
            real = is_real_dtype(value.dtype)
        except TypeError:  # a dtype NumPy does not name (torch, TensorFlow, pandas' nullable): read below
            real = None
        if real is False:
            raise InvalidInputError(f"{name} must be real numbers, got {value!r:.80}")
        if real:
            return tuple(value.shape)
    try:
        arr = np.asarray(value)
    except Exception as exc:  # ragged lists and the like
        raise InvalidInputError(f"{name} must be an array of real numbers: {exc}") from None
    if not is_real_dtype(arr.dtype):  # (bfloat16 included; bool, complex, strings not)
        raise InvalidInputError(f"{name} must be real numbers, got {value!r:.80}")
    return arr.shape


def _check_similarity(pose):
    """The batch axes of a pose whose similarity fields fit (center (..., 3), scale the center's
    leading shape, rotation None or those axes + (3, 3); real numbers, traced or not; a concrete
    rotation proper, :func:`_check_rotation`, :meth:`Pose.from_center_scale`'s rule), before
    ``matrix``, ``apply`` or ``inverse`` compute with them; InvalidInputError otherwise. A Pose
    built directly (``Pose(center, scale)``) is not checked where it is made (JAX rebuilds one
    from any leaves): a (3,) scale scaled each axis on its own (no similarity) and made a
    (3, 4, 4) matrix, a string scale '2' was taken as 2, and a center of another shape was NumPy's
    broadcast error."""
    c_shape, s_shape = _shape_of(pose.center, "center"), _shape_of(pose.scale, "scale")
    batch = c_shape[:-1]
    if c_shape[-1:] != (3,) or s_shape != batch:
        raise InvalidInputError(f"a Pose's center must have shape (..., 3) and its scale the center's leading shape "
                                f"(one number per pose: a similarity scales every axis alike), got {c_shape} and "
                                f"{s_shape}")
    if pose.rotation is not None:  # (an improper or skewed one was applied as given)
        _check_rotation(pose.rotation, batch, "a Pose's rotation")
    return batch


def _check_points(x, batch):
    """Points given to :meth:`Pose.apply` of a pose with batch axes ``batch`` (its center's
    leading axes): (n, 3) (or one point (3,)) for one pose, batch + (n, 3) for a batch; concrete
    points finite. Returns ``x`` unchanged."""
    if hasattr(x, "vertices"):  # a mesh: 'points must be real numbers, got <trimesh.Trimesh(...)>'
        raise InvalidInputError(f"points must be an (n, 3) array, got a {type(x).__name__}: pass its vertices "
                                "(pose.apply(mesh.vertices))")
    shape = _shape_of(x, "points")
    ok = shape[-1:] == (3,) and (len(shape) == len(batch) + 2 and shape[:len(batch)] == batch
                                 or not batch and len(shape) == 1)
    if not ok:
        want = f"({''.join(f'{b}, ' for b in batch)}n, 3)"
        raise InvalidInputError(f"points must have shape {want} for this pose, got {shape}")
    if not is_traced(x) and not np.all(np.isfinite(np.asarray(x))):
        raise InvalidInputError("points have NaN or inf coordinates")
    return x


def host(pose):
    """The pose with every field a NumPy value: floats float64, flags bool, codes int (None kept).

    The type of every pose the host entry points return (:func:`jaxpose.normalize_mesh`,
    :func:`jaxpose.pose.estimators.estimate`, the command line, the batch runner), whatever the method.
    Reads JAX arrays back from the device once.

    Raises:
      InvalidInputError: `pose` is no :class:`Pose`, or a field of it is traced (under jit, vmap or
        grad: use the pose's JAX arrays there, and host() outside).
    """
    if not isinstance(pose, Pose):  # (a (center, scale) pair: AttributeError 'tuple' object has no attribute)
        raise InvalidInputError(f"host takes a Pose, got {type(pose).__name__}: make one of a center and scale with "
                                "Pose.from_center_scale(center, scale)")

    def convert(name, value):
        if value is None:
            return None
        if isinstance(value, Pose):  # inverse_of
            return host(value)
        if is_traced(value):  # (was a TypeError)
            raise InvalidInputError(f"host(pose): Pose.{name} is traced (under jit, vmap or grad): host() converts "
                                    "concrete poses; use the pose's JAX arrays inside the transformation, host() "
                                    "outside it")
        a = np.asarray(value)
        if a.dtype.kind == "f":
            return a.astype(np.float64)
        return a.astype(bool) if a.dtype.kind == "b" else a.astype(np.int64) if a.dtype.kind in "iu" else a

    return Pose(**{name: convert(name, getattr(pose, name)) for name in Pose._fields})


class Pose(NamedTuple):
    """A similarity x -> R (x - center) / scale, with the diagnostics of how it was found.
    A pytree; the one similarity type of the library (the rows of the batch runner's transforms
    table carry theirs as :attr:`jaxpose.batch.transforms.Transform.pose`).

    Types (one policy for every method): the JAX entry points (:func:`jaxpose.normalize`,
    :func:`jaxpose.normalize_batch`) return JAX arrays in JAX's default float dtype (float32, or
    float64 with ``jax_enable_x64``, whatever the points' dtype) for a traced input or a traced
    parameter, so that they jit, vmap and differentiate; otherwise, for a concrete input their
    ``center`` and ``scale`` are NumPy float64 (mapped back on the host, so that a far offset keeps
    its digits), the other fields JAX arrays (``rotation`` and ``ambiguity`` in JAX's default float
    dtype too, as a traced pose's); ``status``, ``iterations`` and ``count`` are int32
    (the solvers' counters, :data:`jaxpose.config.ITERATION_LIMIT`), traced or not, with or
    without x64, every method; the host entry
    points (:func:`jaxpose.normalize_mesh`, :func:`jaxpose.pose.estimators.estimate`, the command line
    and the batch runner, every method, ``ocsvm`` included) return NumPy values: floats float64,
    ``valid`` / ``converged`` bool, ``status`` / ``iterations`` / ``count`` int64 (:func:`host`).

    Where ``matrix``, ``apply`` and ``inverse`` compute: in JAX when a value is traced or when
    every array involved (the fields, and the points given to ``apply``) is a JAX array; otherwise
    on the host in NumPy float64 (no JAX import), so a float64 center far from the origin keeps
    its digits even when other fields are JAX arrays (a concrete :func:`jaxpose.normalize` pose)
    and float64 points are moved in float64. ``apply`` subtracts the center first (exact for
    points near a far center). ``inverse()`` keeps the pose it inverts (``inverse_of``) and maps
    back from it as scale R^T y + center, the center added last: in float64,
    ``pose.inverse().apply(pose.apply(x))`` gives x back to the last bit far from the origin, and
    ``pose.inverse().inverse()`` is ``pose``.

    Attributes:
      center: (3,) in the units of the input.
      scale: () > 0, in the units of the input. ``Pose(...)`` makes an integer array given for either
        floats, as :meth:`from_center_scale` does (NumPy's float64, JAX's default float dtype, traced
        or not); JAX's own rebuilds of a Pose (``jit``, ``vmap``, ``jax.tree.map``) keep its leaves.
      converged: () bool, the SVDD solver reached its tolerance, with gamma and nu in range.
      valid: () bool, ``status == Status.OK``: parameters in range, samples dense enough for gamma,
        a grid that resolves the kernel, a non-empty region that has not collapsed, a finite center
        and a positive finite scale (:mod:`jaxpose.pose.validity`). Convergence is apart (``converged``).
      iterations: () solver iterations.
      ambiguity: None, or () in [0, 1]: how poorly the rotation is determined (0: every cue of
        :mod:`jaxpose.rotation.rotation` clears its threshold); see ``flagged``.
      rotation: None (no rotation: R = I), or (3, 3) a proper rotation whose rows are the canonical
        axes in the input's coordinates (``rotation=True`` of :func:`normalize` and friends).
      status: () int, a :class:`jaxpose.pose.validity.Status` code: 0 when valid, else why not
        (``Status(int(pose.status)).message``).
      count: None, or () int: how many points the SVDD was fitted to (fewer than given above
        ``MAX_POINTS``).
      inverse_of: None, or the Pose this one is the inverse of (set by :meth:`inverse`; its
        ``apply`` and ``matrix`` are then computed from that pose's center, scale and rotation, so
        that they do not round through 1 / scale and -R center / scale); ``_replace`` of its
        center, scale or rotation makes a pose of its own (``inverse_of`` None), of its
        diagnostics makes them in ``inverse_of`` too.

    Example::

        >>> pose = Pose.from_center_scale(np.array([1e6, 0.0, 0.0]), 2.0)
        >>> x = np.array([[1e6 + 0.5, 1.0, -2.0]])
        >>> y = pose.apply(x)                   # (x - center) / scale, float64 on the host
        >>> y
        array([[ 0.25,  0.5 , -1.  ]])
        >>> bool((pose.inverse().apply(y) == x).all())   # y * scale + center: x to the last bit
        True

    Poses from :func:`normalize_batch` carry a leading batch axis on every field.
    """

    center: jax.Array
    scale: jax.Array
    converged: jax.Array = True
    valid: jax.Array = True
    iterations: jax.Array = 0
    ambiguity: jax.Array | None = None
    rotation: jax.Array | None = None
    status: jax.Array = 0
    count: jax.Array | None = None
    inverse_of: "Pose | None" = None

    @classmethod
    def from_center_scale(cls, center, scale, rotation=None, ambiguity=None) -> "Pose":
        """A Pose from a given center (3,) and scale () (and optionally rotation (3, 3), and with it
        its ambiguity () in [0, 1], 0 when not given); valid when center and scale are finite and
        scale > 0. Leading batch axes: the center's, shared by the other fields (the diagnostics
        too); each pose of a batch is valid or not on its own.

        Raises InvalidInputError for shapes that do not fit, a concrete rotation that is not proper,
        or a concrete ambiguity outside [0, 1] or NaN (traced values cannot be checked).

        Concrete values stay NumPy float64 (every digit of a center far from the origin is kept);
        traced values stay JAX arrays (a traced rotation or ambiguity beside a concrete center: in
        JAX's default float dtype). Where the center or the scale is traced, every float field takes
        the center's float dtype, JAX's default float dtype for an integer center (traced or not).
        """
        c_shape, s_shape = _shape_of(center, "center"), _shape_of(scale, "scale")
        batch = c_shape[:-1]
        if c_shape[-1:] != (3,) or s_shape != batch:
            raise InvalidInputError(f"center must have shape (..., 3) and scale its leading shape, got "
                                    f"{c_shape} and {s_shape}")
        if rotation is not None:
            _check_rotation(rotation, batch)
        if ambiguity is not None:
            if rotation is None:
                raise InvalidInputError("ambiguity is the rotation's: give a rotation with it")
            if (a_shape := _shape_of(ambiguity, "ambiguity")) != batch:
                raise InvalidInputError(f"ambiguity must have shape {batch}, the center's leading shape, got {a_shape}")
            if not is_traced(ambiguity):  # (NaN: flagged False, a well determined rotation by accident)
                a = np.asarray(ambiguity, np.float64)
                if not np.all((a >= 0) & (a <= 1)):
                    bad = a[~((a >= 0) & (a <= 1))].flat[0]
                    raise InvalidInputError(f"ambiguity must lie in [0, 1] (0: a well determined rotation, 1: not "
                                            f"determined at all), got {bad}")
        xp = _jnp() if is_traced(center) or is_traced(scale) else np
        center = xp.asarray(center, dtype=None if xp is not np else np.float64)
        if not xp.issubdtype(center.dtype, xp.floating):  # integers: a float pose (a scale 2.5 was cast to 2)
            center = center.astype(xp.result_type(float))
        scale = xp.asarray(scale, center.dtype)
        valid = xp.all(xp.isfinite(center), axis=-1) & xp.isfinite(scale) & (scale > 0)  # per pose of a batch
        if rotation is not None:
            # a traced rotation (or ambiguity) beside a concrete center stays a JAX array, in JAX's
            # default float dtype (NumPy cannot hold a tracer)
            rxp = _jnp() if xp is not np or is_traced(rotation) or is_traced(ambiguity) else np
            dtype = center.dtype if rxp is xp else _jnp().result_type(float)
            rotation = rxp.asarray(rotation, dtype)
            ambiguity = rxp.broadcast_to(rxp.asarray(0.0 if ambiguity is None else ambiguity, dtype), batch)
        status = xp.where(valid, int(Status.OK), int(Status.NOT_FINITE)).astype(np.int32)
        return cls(center, scale, xp.broadcast_to(xp.asarray(True), batch), valid, xp.broadcast_to(xp.asarray(0), batch),
                   ambiguity, rotation, status)

    @property
    def flagged(self):
        """() bool (or None without a rotation): the rotation is not well determined (ambiguity > 0)."""
        return None if self.ambiguity is None else _xp(self.ambiguity).asarray(self.ambiguity) > 0

    @property
    def matrix(self):
        """(..., 4, 4) homogeneous matrix of x -> R (x - center) / scale (NumPy float64 on the
        host, a JAX array in JAX: see the class docs); for an inverse, [scale R^T, center] of the
        pose it inverts."""
        if self.inverse_of is not None:
            return self.inverse_of._inverse_matrix()
        _check_similarity(self)
        xp = _similarity_xp(self.center, self.scale, self.rotation)
        c, s, r = _floats(xp, self.center, self.scale, self.rotation)
        if r is None:
            lin = xp.broadcast_to(xp.eye(3, dtype=c.dtype), c.shape[:-1] + (3, 3)) / s[..., None, None]
            shift = -c / s[..., None]
        else:
            lin = xp.asarray(r, c.dtype) / s[..., None, None]
            shift = -xp.einsum("...ij,...j->...i", lin, c)
        return _homogeneous(xp, lin, shift)

    def _inverse_matrix(self):
        _check_similarity(self)
        xp = _similarity_xp(self.center, self.scale, self.rotation)
        c, s, r = _floats(xp, self.center, self.scale, self.rotation)
        eye = xp.broadcast_to(xp.eye(3, dtype=c.dtype), c.shape[:-1] + (3, 3))
        lin = (eye if r is None else xp.swapaxes(xp.asarray(r, c.dtype), -1, -2)) * s[..., None, None]
        return _homogeneous(xp, lin, c)

    def apply(self, x):
        """Points x : (n, 3), or one point (3,) -> R (x - center) / scale, of x's shape; for an
        inverse, scale R^T x + center of the pose it inverts (rotated, scaled, then the center added).

        The center is subtracted first (exact for points near a center far from the origin). On
        the host (NumPy points, or a NumPy field) in float64, returning NumPy float64; in JAX when
        traced or when the points and every field are JAX arrays (class docs). A batch of poses
        (fields with leading axes B, from :func:`jaxpose.normalize_batch`) moves points
        (B, n, 3), each set by its pose.

        Raises:
          InvalidInputError: points of another shape, not real, or (concrete) not finite.
        """
        forward = self.inverse_of
        if forward is not None:
            _check_points(x, _check_similarity(forward))
            xp = _similarity_xp(x, forward.center, forward.scale, forward.rotation)
            y, c, s, r = _floats(xp, x, forward.center, forward.scale, forward.rotation)
            if r is not None:
                y = y @ xp.asarray(r, y.dtype)
            c, s = _per_set(c, s)
            return y * s + c
        _check_points(x, _check_similarity(self))
        xp = _similarity_xp(x, self.center, self.scale, self.rotation)
        x, c, s, r = _floats(xp, x, self.center, self.scale, self.rotation)
        c, s = _per_set(c, s)
        y = (x - c) / s
        if r is None:
            return y
        return y @ xp.swapaxes(xp.asarray(r, y.dtype), -1, -2)

    def inverse(self) -> "Pose":
        """The inverse similarity y -> scale R^T y + center, as a Pose: center -R center / scale,
        scale 1 / scale, rotation R^T (computed where :attr:`matrix` is), the diagnostics kept, and
        ``inverse_of`` this pose, from which its ``apply`` and ``matrix`` compute (no rounding
        through the inverted fields). The inverse of an inverse is the pose it inverts."""
        if self.inverse_of is not None:
            return self.inverse_of
        _check_similarity(self)
        xp = _similarity_xp(self.center, self.scale, self.rotation)
        c, s, r = _floats(xp, self.center, self.scale, self.rotation)
        if r is None:
            return self._replace(center=-c / s[..., None], scale=1.0 / s, inverse_of=self)
        center = -xp.einsum("...ij,...j->...i", r, c) / s[..., None]
        return self._replace(center=center, scale=1.0 / s, rotation=xp.swapaxes(r, -1, -2), inverse_of=self)


_SIMILARITY = ("center", "scale", "rotation")  # the fields an inverse's apply and matrix read from inverse_of
_tuple_replace = Pose._replace


def _replace(self, **changes) -> "Pose":
    """The pose with ``changes`` (field: value) made, as NamedTuple's ``_replace``; an inverse
    (``inverse_of`` set) stays the inverse of the pose it names only while it is that pose's
    inverse: a new center, scale or rotation makes it a pose of its own (``inverse_of`` None:
    ``apply``, ``matrix`` and ``inverse()`` then compute from its fields), and new diagnostics
    are made in ``inverse_of`` too (``pose.inverse()._replace(valid=False).inverse().valid`` is
    False). ``inverse_of`` given is kept as given."""
    if self.inverse_of is not None and "inverse_of" not in changes:
        if any(name in changes for name in _SIMILARITY):
            changes["inverse_of"] = None
        elif changes:
            changes["inverse_of"] = self.inverse_of._replace(**changes)
    return _tuple_replace(self, **_float_similarity(changes))


Pose._replace = _replace  # (typing.NamedTuple refuses a _replace written in the class body)
_tuple_new = Pose.__new__


def _float_field(value):
    """An integer array (NumPy, or JAX, traced or not) as floats: NumPy's float64, JAX's default
    float dtype (:meth:`Pose.from_center_scale`'s rule); any other value as it is (Python numbers and
    lists are NumPy float64 where computed with; a pytree's leaves that are not arrays pass)."""
    kind = getattr(getattr(value, "dtype", None), "kind", None)
    if kind not in ("i", "u"):
        return value
    if isinstance(value, (np.ndarray, np.generic)):
        return np.asarray(value, np.float64)
    if _is_jax(value) or is_traced(value):
        jnp = _jnp()
        return jnp.asarray(value, jnp.result_type(float))
    return value


def _float_similarity(fields):
    """``fields`` (a dict) with an integer ``center`` and ``scale`` made floats (:func:`_float_field`)."""
    return {name: _float_field(value) if name in ("center", "scale") else value for name, value in fields.items()}


def _new(cls, *args, **kwargs):
    """``Pose(...)``: NamedTuple's constructor, with an integer center or scale made floats as
    :meth:`Pose.from_center_scale` makes them (a JAX integer center, traced or not, computed its
    ``matrix`` with the rotation cast to integers: zeros). JAX rebuilds a Pose without this (the
    pytree registered by :func:`_register_pytree`): ``jax.tree.map`` returns its leaves as they are."""
    _register_pytree()
    pose = _tuple_new(cls, *args, **kwargs)
    center, scale = _float_field(pose.center), _float_field(pose.scale)
    if center is pose.center and scale is pose.scale:
        return pose
    return tuple.__new__(cls, (center, scale, *pose[2:]))


Pose.__new__ = staticmethod(_new)  # (typing.NamedTuple refuses a __new__ written in the class body)
_REGISTERED = []


def _register_pytree():
    """Register :class:`Pose` as a JAX pytree whose rebuild skips :func:`_new` (``tuple.__new__``):
    the same leaves, order and key paths (``GetAttrKey``) as a NamedTuple's, but JAX's rebuilds
    (``jit``, ``vmap``, ``grad``, ``tree.map``, ``eval_shape``'s ShapeDtypeStructs) keep the
    leaves they are given. Once JAX is imported (no import of it here); called by every ``Pose(...)``
    and by :mod:`jaxpose.pose.pose`."""
    if _REGISTERED or "jax" not in sys.modules:
        return
    from jax import tree_util

    _REGISTERED.append(True)
    tree_util.register_pytree_with_keys(
        Pose, lambda pose: ([(tree_util.GetAttrKey(name), value) for name, value in zip(Pose._fields, pose)], None),
        lambda _, children: tuple.__new__(Pose, tuple(children)), flatten_func=lambda pose: (tuple(pose), None))


_register_pytree()


def _per_set(center, scale):
    """A batch's center (B, 3) and scale (B,) as (B, 1, 3) and (B, 1, 1), to broadcast over each
    set's points (B, n, 3); one pose's as they are."""
    if center.ndim > 1:
        return center[..., None, :], scale[..., None, None]
    return center, scale


ROTATION_TOL = 1e-4  # |R R^T - I| of a proper float32/float64 rotation, at most (the library's float32 ones: ~1e-6)


def rotation_tol(dtype=None):
    """The largest entry of |R R^T - I| a proper rotation of ``dtype`` may carry: :data:`ROTATION_TOL`
    (1e-4: the library's float32 rotations sit near 1e-6, and a rotation written with 5 decimals
    passes), or 8 machine epsilons of a coarser float (float16 0.0078, bfloat16 0.0625).

    Example:
      >>> rotation_tol(np.float32), rotation_tol(np.float16)
      (0.0001, 0.0078125)
    """
    import ml_dtypes  # (JAX's own dependency: its finfo knows bfloat16)

    try:
        eps = float(ml_dtypes.finfo(np.dtype(dtype if dtype is not None else np.float64)).eps)
    except (TypeError, ValueError):  # an integer or other dtype: no epsilon of its own
        eps = 0.0
    return max(ROTATION_TOL, 8.0 * eps)


def _check_rotation(rotation, batch, name="rotation"):
    """The one rotation rule of a Pose (:meth:`Pose.from_center_scale`, and ``matrix``, ``apply``,
    ``inverse`` of a Pose built directly): shape batch + (3, 3), real numbers, traced or not; where
    concrete (its values read on the host; a traced one's are not, under jit, vmap or grad) a
    proper rotation: finite, orthonormal rows (every entry of R R^T - I within ``ROTATION_TOL``,
    :func:`rotation_tol` of its dtype: float32 rotations pass, float16 ones at their precision) and det R > 0 (a reflection, det -1, is refused).
    InvalidInputError naming ``name`` otherwise."""
    shape = _shape_of(rotation, name)
    if shape != batch + (3, 3):
        raise InvalidInputError(f"{name} must have shape {batch + (3, 3)}, got {shape}")
    if is_traced(rotation):
        return
    tol = rotation_tol(getattr(rotation, "dtype", None))
    r = np.asarray(rotation, np.float64)
    eye = np.broadcast_to(np.eye(3), r.shape)
    if not np.all(np.isfinite(r)):
        raise InvalidInputError(f"{name} must be a proper rotation (orthonormal rows, determinant +1), got NaN or inf")
    skew = float(np.abs(r @ np.swapaxes(r, -1, -2) - eye).max()) if r.size else 0.0
    if skew > tol:
        raise InvalidInputError(f"{name} must be a proper rotation (orthonormal rows, determinant +1): its rows are "
                                f"not orthonormal (R R^T differs from I by {skew:.3g} > {tol:g})")
    if r.size and not np.all((det := np.linalg.det(r)) > 0):
        raise InvalidInputError(f"{name} must be a proper rotation (orthonormal rows, determinant +1), got determinant "
                                f"{float(np.min(det)):.3g}: a reflection (negate one row to make it proper)")


def _homogeneous(xp, lin, shift):
    """(..., 4, 4) from the linear part (..., 3, 3) and the translation (..., 3)."""
    top = xp.concatenate([lin, shift[..., None]], axis=-1)
    bottom = xp.broadcast_to(xp.asarray([0, 0, 0, 1], lin.dtype), lin.shape[:-2] + (1, 4))
    return xp.concatenate([top, bottom], axis=-2)
