"""A canonical frame as a result: its type, sign rule and ambiguity; the OCSVM region's frame.

A frame is a proper rotation R (3, 3) whose rows are a shape's canonical axes in world
coordinates (det R = +1); canonical coordinates are R (x - c) / s. The frames of
:mod:`jaxpose.rotation.core` (``core``) and of :mod:`jaxpose.baselines` (``pca_*``, ``inertia``) are
:class:`Frame` values built with the pieces here; :func:`region_frame` is the traced frame of
:func:`jaxpose.normalize` (``rotation=True``).

``ocsvm`` (point samples, traced JAX, :func:`region_frame`): the eigenvectors of the OCSVM
region's second moment (computed with its centroid by the grid integral of
:func:`jaxpose.moments.region_moments`), signs by the third moments of the samples along them
(the two largest in magnitude; the third axis from det = +1). Equivariant because the grid turns
with the points' principal frame.

Ambiguity. A frame is determined when its eigenvalues are apart, its sign cues are away from
zero and (``core``) its mirror plane stands out. With the relative eigen-gaps g1 = (l1 - l2) / l1,
g2 = (l2 - l3) / l2, the weakest used sign cue m as a multiple of its threshold and the mirror
contrast k (the difference of the two minor axes' mirror scores, or of the feet offsets along them
in units of their threshold where the feet chose), ``ambiguity = clip(1 - min(g1 / GAP_MIN,
g2 / GAP_MIN, m, k / SYMMETRY_MIN), 0, 1)``: 0 when every cue clears its threshold, 1 when one of
them is zero; ``flag = ambiguity > 0``. The thresholds are set a priori (module constants), not
fitted: a gap of 10 % (near-equal moments swap under small deformations), a third moment of
0.02 r^3 (what moving about 2 % of the volume across the body changes it by), a feet offset of
1 % of the length (about one voxel; :data:`jaxpose.rotation.core.FOOT_MIN`) and a symmetry contrast of 0.05.

Example::

    rot, margins, k = complete_signs(np.eye(3), [-0.5, 0.3, 0.01])   # rows 0, 2 negated; det +1
    ambiguity(relative_gaps([9.0, 4.0, 1.0]), 0.5)                   # 0.5: a sign cue at half its threshold
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ._validate import InvalidInputError, check_array, check_int, check_mask, check_shape, is_real_dtype

__all__ = ["Frame", "GAP_MIN", "SIGN_MIN", "SYMMETRY_MIN", "ZERO_EIGENVALUE", "SAFE_SPREAD", "proper", "descending_axes",
           "relative_gaps", "third_moments", "ambiguity", "complete_signs", "region_frame"]

GAP_MIN = 0.10  # relative eigen-gap below which two axes are called interchangeable
SIGN_MIN = 0.02  # third moment E[z^3] / r^3 below which a sign is called undetermined
SYMMETRY_MIN = 0.05  # mirror-score contrast below which the mirror axis is called undetermined


class Frame(NamedTuple):
    """A canonical frame with its diagnostics (NumPy float64).

    Attributes:
      rotation: (3, 3) proper rotation, rows = canonical axes in world coordinates.
      ambiguity: () in [0, 1]; 0 = every cue clears its threshold (module docs).
      eigenvalues: (3,) the second moments along the axes, largest first (units^2).
      gaps: (2,) relative eigen-gaps (l1 - l2) / l1, (l2 - l3) / l2, each in [0, 1] (:func:`relative_gaps`).
      margins: (3,) the sign statistic along each final axis (0 on the axis completed by det).
      mirror: index of the axis completed by det (the mirror axis for ``core``).
      symmetry: (3,) mirror scores in [0, 1] per axis (NaN where not computed).

    The ``ocsvm`` frame (:func:`jaxpose.rotation.rotation.frame_of`): eigenvalues are the OCSVM
    region's, margins |E[z^3] / r^3| / ``SIGN_MIN``, no mirror scores (NaN); where its frame was not
    finite (rotation the identity, ambiguity 1) eigenvalues, gaps and margins are NaN and mirror is
    -1: not reported.
    """

    rotation: np.ndarray
    ambiguity: float
    eigenvalues: np.ndarray
    gaps: np.ndarray
    margins: np.ndarray
    mirror: int
    symmetry: np.ndarray

    @property
    def flag(self) -> bool:
        """The frame is not well determined (ambiguity > 0)."""
        return bool(self.ambiguity > 0)


def proper(r):
    """r (3, 3) with its last row negated when det r < 0: a proper rotation from orthonormal rows.
    InvalidInputError for another shape or kind (NumPy's LinAlgError), or NaN or inf (returned as
    NaN, with NumPy's RuntimeWarning)."""
    r = np.array(check_shape(r, "r", (3, 3), finite=True), np.float64)
    if np.linalg.det(r) < 0:
        r[2] = -r[2]
    return r


def descending_axes(cov):
    """Eigenvalues (3,) descending and eigenvectors as rows (3, 3) of a symmetric (3, 3) matrix
    (finite: InvalidInputError for another shape, kind or NaN, NumPy's LinAlgError "Eigenvalues did
    not converge")."""
    lam, vec = np.linalg.eigh(np.asarray(check_shape(cov, "cov", (3, 3), finite=True), np.float64))
    return lam[::-1], vec[:, ::-1].T


ZERO_EIGENVALUE = 1e-12  # an eigenvalue below this share of the largest is rounding of 0 (eigh: errors ~ eps l1)


def relative_gaps(lam):
    """(2,) relative eigen-gaps (l1 - l2) / l1, (l2 - l3) / l2 of eigenvalues (3,) largest first
    (second moments: nonnegative), each in [0, 1].

    An eigenvalue below :data:`ZERO_EIGENVALUE` of the largest counts as 0 (a covariance's computed
    eigenvalues carry rounding errors of about eps times the largest, either sign), and the gap
    between two zeros is 0: the axes of a flat or a straight point set across it are not determined
    (two points: gaps (1, 0), the two minor axes interchangeable). InvalidInputError for ``lam``
    of another shape or kind (two values: NumPy's IndexError).
    """
    lam = np.asarray(check_shape(lam, "lam", (3,)), np.float64)
    lam = np.where(lam > ZERO_EIGENVALUE * max(lam[0], 0.0), lam, 0.0)
    return np.array([(lam[0] - lam[1]) / max(lam[0], 1e-300), (lam[1] - lam[2]) / max(lam[1], 1e-300)])


SAFE_SPREAD = (1e-90, 1e90)  # RMS spreads whose cubed coordinates float64 sums without under- or overflow


def third_moments(z):
    """(k,) the signed third moments E[z_j^3] / r^3 of centered coordinates ``z`` (n, k) along each
    column, r^2 = E[|z|^2] (the sign statistics of the frames, scale-free).

    Computed as written where the RMS spread r lies in :data:`SAFE_SPREAD`; outside, ``z`` is first
    scaled by a power of 2 (exact) to a spread near 1: cubes of coordinates beyond about 1e102
    overflow float64 and below about 1e-103 underflow, which made the statistic inf or 0 / 0 (NaN)
    and the frame's signs unread. InvalidInputError for ``z`` no (n, k) real array with n >= 1.

    Example::

        third_moments(np.array([[-1.0], [-1.0], [2.0]]))   # [0.7071]: E[z^3] = 2 over r^3 = sqrt(2)^3
    """
    given = np.asarray(z)
    if given.ndim != 2 or not len(given) or not is_real_dtype(given.dtype):
        raise InvalidInputError(f"z must be real numbers of shape (n, k) with n >= 1, got {given.dtype} of shape "
                                f"{given.shape}")
    z = given.astype(np.float64, copy=False)
    r = np.sqrt(np.mean(np.sum(z * z, axis=1)))
    if not SAFE_SPREAD[0] < r < SAFE_SPREAD[1]:
        top = float(np.max(np.abs(z)))
        if top > 0:  # (all zero: 0 / 0, no direction to read)
            z = np.ldexp(z, -np.frexp(top)[1])  # |z| <= 1, exact
            r = np.sqrt(np.mean(np.sum(z * z, axis=1)))
    return np.mean(z ** 3, axis=0) / r ** 3


def ambiguity(gaps, sign_ratio, contrast=None):
    """clip(1 - min(g1 / GAP_MIN, g2 / GAP_MIN, sign_ratio[, k / SYMMETRY_MIN]), 0, 1) (module docs).

    ``sign_ratio``: the weakest used sign margin as a multiple of its threshold (e.g. m / SIGN_MIN).
    ``gaps`` (2,) (:func:`relative_gaps`), ``sign_ratio`` and ``contrast`` () real numbers;
    InvalidInputError for other shapes or kinds (an IndexError or a TypeError of ``abs``). A NaN
    cue is one that could not be measured (a 0 / 0 third moment: coordinates whose cubes under- or
    overflow float64), so it determines nothing: ambiguity 1 (it was 0, "every cue clears its
    threshold", or NaN, by its place among the others)."""
    check_shape(gaps, "gaps", (2,))
    check_shape(sign_ratio, "sign_ratio", ())
    if contrast is not None:
        check_shape(contrast, "contrast", ())
    ratios = [gaps[0] / GAP_MIN, gaps[1] / GAP_MIN, abs(sign_ratio)]
    if contrast is not None:
        ratios.append(contrast / SYMMETRY_MIN)
    if np.any(np.isnan(np.asarray(ratios, np.float64))):
        return 1.0
    return float(np.clip(1.0 - min(ratios), 0.0, 1.0))


def complete_signs(axes, stat, completed=None, to_world=None):
    """Orient the rows of ``axes`` (3, 3) by the signs of ``stat`` (3,), one axis completed by det.

    Args:
      axes: (3, 3) orthonormal rows (grid coordinates when ``to_world`` is given).
      stat: (3,) signed statistics along the rows; each row is flipped where its stat is negative.
      completed: the axis whose sign comes from det = +1 (default: the smallest |stat|).
      to_world: optional (3, 3) rows of the grid axes in world coordinates (any determinant).

    Returns:
      rotation (3, 3) proper, in world coordinates; margins (3,) the stats after the flips
      (0 on the completed axis); the completed axis.

    Raises:
      InvalidInputError: arrays of other shapes or kinds, ``completed`` no int in 0 ... 2 (NumPy's
        broadcast error or IndexError).
    """
    stat = np.asarray(check_shape(stat, "stat", (3,)), np.float64)
    axes = check_shape(axes, "axes", (3, 3))
    if completed is not None and check_int(completed, "completed", 0) > 2:
        raise InvalidInputError(f"completed must be an axis, 0, 1 or 2, got {completed!r}")
    k = int(np.argmin(np.abs(stat))) if completed is None else int(completed)
    s = np.where(stat >= 0, 1.0, -1.0)
    r = np.asarray(axes, np.float64) * s[:, None]
    if to_world is not None:
        r = r @ np.asarray(check_shape(to_world, "to_world", (3, 3)), np.float64)
    if np.linalg.det(r) < 0:
        r[k] = -r[k]
    margins = np.abs(stat)
    margins[k] = 0.0
    return r, margins, k


def region_frame(second_moment, center, y, mask, axes, report=False):
    """The ``ocsvm`` frame (module docs) of a region fitted to pre-scaled points; pure JAX.

    Args:
      second_moment: (3, 3) the region's second moment about its centroid (pre-scaled frame).
      center: (3,) the region's centroid (pre-scaled frame).
      y: (m, 3) the pre-scaled points; mask: (m,) bool or None.
      axes: (3, 3) the pre-frame's axes as columns (a pre-scaled direction e is ``axes @ e`` in
        the world).
      report: (static) also return the frame's diagnostics (below); the rotation and ambiguity are
        the same numbers either way.

    Returns:
      rotation (3, 3) proper (rows = canonical axes in world coordinates) and ambiguity (),
      both without derivatives (the frame is piecewise constant where it is well determined, and
      eigenvectors have no useful derivative where it is not). With ``report``, a third value: a
      dict of ``eigenvalues`` (3,) of ``second_moment``, largest first (pre-scaled units);
      ``stat`` (3,) the signed third moments E[z^3] / r^3 of the points along the eigenvectors, in
      that order, before the flips; ``completed`` () int, the axis whose sign det = +1 set (the
      smallest |stat|); ``ok`` () bool, False where the frame was not finite and the identity
      with ambiguity 1 was returned instead.
    """
    import jax
    import jax.numpy as jnp

    _check_region_frame(second_moment, center, y, mask, axes)
    second_moment, center, y, axes = (jax.lax.stop_gradient(a) for a in (second_moment, center, y, axes))
    lam, vec = jnp.linalg.eigh(second_moment)
    lam, e = lam[::-1], vec[:, ::-1].T  # rows, largest first
    w = jnp.ones(y.shape[:1], y.dtype) if mask is None else jnp.asarray(mask, y.dtype)
    z = (y - center) @ e.T
    r = jnp.sqrt(jnp.sum(w * jnp.sum(z * z, axis=1)) / jnp.sum(w))
    stat = (w @ (z ** 3)) / jnp.sum(w) / r ** 3
    k = jnp.argmin(jnp.abs(stat))
    s = jnp.where(stat >= 0, 1.0, -1.0).astype(y.dtype)
    rot = (e * s[:, None]) @ axes.T
    flip = jnp.where((jnp.arange(3) == k) & (jnp.linalg.det(rot) < 0), -1.0, 1.0).astype(y.dtype)
    rot = rot * flip[:, None]
    gaps = jnp.stack([(lam[0] - lam[1]) / lam[0], (lam[1] - lam[2]) / lam[1]])
    used = jnp.min(jnp.where(jnp.arange(3) == k, jnp.inf, jnp.abs(stat)))
    ratio = jnp.minimum(jnp.min(gaps) / GAP_MIN, used / SIGN_MIN)
    amb = jnp.clip(1.0 - ratio, 0.0, 1.0)
    ok = jnp.all(jnp.isfinite(rot)) & jnp.isfinite(amb)
    if report:
        diagnostics = {"eigenvalues": lam, "stat": stat, "completed": k, "ok": ok}
        return jnp.where(ok, rot, jnp.eye(3, dtype=y.dtype)), jnp.where(ok, amb, 1.0), diagnostics
    return jnp.where(ok, rot, jnp.eye(3, dtype=y.dtype)), jnp.where(ok, amb, 1.0)


def _check_region_frame(second_moment, center, y, mask, axes):
    """The shapes of :func:`region_frame`'s arrays (known while tracing; their values are not
    read): InvalidInputError naming the one that does not fit (JAX's dot_general or axis errors)."""
    shape = lambda v: tuple(np.shape(v))
    for name, value, want in (("second_moment", second_moment, (3, 3)), ("center", center, (3,)), ("axes", axes, (3, 3))):
        if shape(value) != want:
            raise InvalidInputError(f"{name} must have shape {want}, got {shape(value)}")
    check_array(y, "y", finite=False)
    check_mask(mask, shape(y)[0], "y")
