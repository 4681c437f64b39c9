"""The ``core`` frame of a shape, and the robust voxel solid its frames are read from (:func:`frame_solid`).

``core`` (meshes and point clouds, :func:`core_frame`), on the robust voxel solid of
:mod:`jaxpose.occupancy.solid`:

1. Pre-frame. The grid of the solid is laid out along the principal axes of the input's surface
   (exact area moments of the triangles; the covariance of the points of a point cloud), their
   signs fixed by the input's third moments (:func:`pre_frame`): rotating the input rotates the
   grid with it, so the voxels, and everything computed from them, are the same.
2. Axes. The eigenvectors (largest first) of the second moments of the solid, each voxel weighted
   by its depth^4 (depth: distance to the outside): the weight falls with the fourth power of a
   part's thickness, so limbs, which are thin and move, hardly count and the axes are those of
   the trunk.
3. Mirror axis. Bodies that articulate (people, animals) are bilaterally symmetric: any signed
   statistic along the left-right axis is noise of the pose. Their long axis lies in the mirror
   plane, so the mirror axis is the one of the two minor axes whose plane (through the depth^2
   centroid) maps the depth^2-weighted solid better onto itself (:func:`symmetry_scores`); its
   sign comes from det R = +1. Its contrast (against the other minor axis, and against the long
   axis, which must lie in the mirror plane) enters the ambiguity against ``SYMMETRY_MIN``.
4. Signs of the other two axes: each points to where the far mass of the (unweighted) solid lies,
   the sign of its third moment E[z^3] / r^3 (z along the axis about the solid's centroid, r the
   solid's RMS radius, so margins are comparable between axes and with the share of the volume a
   moving limb carries). On a person the first axis points to the feet (the legs are the far mass).
5. Feet. The third moment cannot orient a body front to back: nothing heavy sits in front of or
   behind the trunk. When it leaves the minor non-mirror axis undetermined, that axis points to
   where the feet point (:func:`feet_offset`: the slab of the solid at the legs' end of the first
   axis, each part of it against the solid just above it), if that slab is thin enough to be feet.
   Feet point forward, not sideways: when the mirror test of step 3 is undetermined (an
   asymmetric pose), the minor axis the feet point along more is the forward one and the other
   the mirror axis.
6. Cross-check. The deep core (depth^4 centroid) lies toward the head's end of the first axis's
   extent (a person's legs are longer than head and neck); where it does not agree with the third
   moment's sign, the first axis is called undetermined.

Equivariance holds up to float rounding for inputs whose pre-frame third moments are not zero; an
exactly mirror-symmetric input leaves the sign of its pre-frame's mirror axis to rounding, and its
grid may then come out mirrored (voxel-level differences).
"""
from __future__ import annotations

import numpy as np
from scipy import ndimage

from .._validate import InvalidInputError, check_array, check_concrete, check_faces, check_int, check_real, check_shape
from ..geometry import surface_labels
from ..occupancy import solid
from . import parts
from ..orientation import SIGN_MIN, SYMMETRY_MIN, Frame, ambiguity, complete_signs, descending_axes, relative_gaps, third_moments

__all__ = ["FOOT", "FEET_DEPTH", "FOOT_MIN", "AXES_POWER", "SYMMETRY_POWER", "OFF_SOLID", "pre_frame", "frame_solid",
           "symmetry_scores", "feet_offset", "core_frame"]

FOOT = 0.05  # the feet: this share of the length at the legs' end (ankles at about 4 % of a person's height)
FEET_DEPTH = 0.5  # feet are thinner than half the trunk's depth (ankle ~4 cm, head ~9 cm, trunk ~11 cm)
FOOT_MIN = 0.01  # feet offset (in lengths) below which it is called undetermined: about one voxel
AXES_POWER = 4.0  # depth exponent of the axes' weights
SYMMETRY_POWER = 2.0  # depth exponent of the mirror test's weights


# ------------------------------------------------------------------ the core frame
_ONE_THREAD = 4 * 65536  # OpenBLAS runs a matrix product of at most this many multiply-adds on one thread
_ONE_THREAD_VECTOR = 9216  # ... and a matrix-vector product of fewer than this many (OpenBLAS's classic threshold)


def _turned(points, matrix):
    """``points @ matrix`` for (m, 3) points and a (3, 3) matrix or a (3,) vector, the same numbers,
    as products small enough that OpenBLAS runs them on one thread (at most ``_ONE_THREAD``
    multiply-adds, fewer than ``_ONE_THREAD_VECTOR`` for a vector): a row's products are its own,
    and a product this thin does not pay for BLAS's threads, which wait for a free core on a busy
    machine. (m, 3) or (m,) float64."""
    points = np.asarray(points, np.float64)
    rows = _ONE_THREAD // 9 if np.ndim(matrix) == 2 else (_ONE_THREAD_VECTOR - 1) // 3
    if len(points) <= rows:
        return points @ matrix
    return np.concatenate([points[i:i + rows] @ matrix for i in range(0, len(points), rows)])


def _third_moments(x, w=None):
    """(3,) signs-only helper: sum w (x - mean)^3 per axis of x (n, 3)."""
    w = np.ones(len(x)) if w is None else w
    d = x - (w @ x) / w.sum()
    return w @ (d ** 3)


def _checked(vertices, faces):
    """(vertices as (n, 3) finite float64, faces as checked indices or as given where None or
    empty): InvalidInputError naming what is wrong."""
    check_concrete("vertices and faces", vertices, faces)
    v = np.asarray(check_array(vertices, "vertices", 1), np.float64)
    if faces is not None and len(faces):
        faces = check_faces(faces, len(v))
    return v, faces


def pre_frame(vertices, faces=None):
    """The grid frame of :func:`frame_solid`: principal axes of the input, signs by third moments.

    Meshes: the exact second moments of the surface (area-weighted, closed form per triangle);
    point clouds (``faces`` None): the covariance of the points. Each axis points to the positive
    third moment of the vertices along it, so the frame of a rotated input is the rotated frame.

    Args:
      vertices: (n, 3) finite floats; faces: (f, 3) int indices of them, or None.

    Returns:
      (3, 3) orthonormal rows (largest second moment first; not necessarily proper).

    Raises:
      InvalidInputError: vertices or faces of another shape or kind, NaN or inf vertices, indices
        past the vertices (were NumPy's LinAlgError "Eigenvalues did not converge" or IndexError).
    """
    v, faces = _checked(vertices, faces)
    if faces is not None and len(faces):
        t = v[np.asarray(faces, np.int64)]
        area = 0.5 * np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1)
        total = area.sum()
        if total > 0:
            c = (area @ t.sum(axis=1)) / (3.0 * total)
            t0 = t - c
            s0 = t0.sum(axis=1)
            cov = (np.einsum("f,fki,fkj->ij", area, t0, t0) + np.einsum("f,fi,fj->ij", area, s0, s0)) / (12.0 * total)
        else:
            faces = None
    if faces is None or not len(faces):
        d = v - v.mean(axis=0)
        cov = d.T @ d / len(v)
    _, axes = descending_axes(cov)
    skew = _third_moments(_turned(v, axes.T))
    return axes * np.where(skew >= 0, 1.0, -1.0)[:, None]


OFF_SOLID = 2  # voxels: a mesh's piece with no vertex this close to the solid is a stray part (frame_solid)


def frame_solid(vertices, faces=None, resolution=None):
    """The robust solid (:func:`jaxpose.occupancy.solid.robust_solid`) on a grid along the
    :func:`pre_frame` of its main body.

    The grid's axes are the principal axes of the input. Every complement component that touches
    the grid's border is outside (``reach=0``): the frame reads the body's parts from the necks and
    gaps between them, and a slit narrower than the grid resolves (a head resting on a leg, a tail
    along a thigh) is a gap here, where the center and scale's solid fills it (measured:
    docs/rotation.md). A mesh's separate pieces (connected by
    faces) that lie wholly off the solid (no vertex within :data:`OFF_SOLID` voxels of it: stray
    parts the solid dropped) are left out of them: the axes are taken again from the other pieces
    and the solid is built on those, so that a stray part turns neither the grid nor, through it,
    the frame read from the solid. (A point cloud has no pieces to tell apart: its axes are all
    its points'.)
    """
    resolution = solid.check_resolution(solid.RESOLUTION if resolution is None else resolution)  # 7.5 is not 7
    v, faces = _checked(vertices, faces)  # (NaN vertices: NumPy's LinAlgError in pre_frame)
    if faces is None or not len(faces):
        return solid.robust_solid(v, faces, resolution=resolution, frame=pre_frame(v, faces), reach=0)
    f = np.asarray(faces, np.int64)
    capped = solid.cap_holes(v, f)  # computed once for both grids
    sol = solid.robust_solid(v, f, resolution=resolution, frame=pre_frame(v, f), capped=capped, reach=0)
    if not sol.inside.any():
        return sol
    n = len(v)
    _, piece = surface_labels(n, f)
    on = solid.near_solid(_turned(v, sol.frame.T), sol.inside, sol.origin, sol.pitch, grow=OFF_SOLID)
    kept = np.zeros(piece.max() + 1, bool)
    kept[piece[on]] = True
    keep = kept[piece[f[:, 0]]]
    if keep.all() or not keep.any():
        return sol
    used = np.unique(f[keep])
    index = np.zeros(n, np.int64)
    index[used] = np.arange(len(used))
    return solid.robust_solid(v, f, resolution=resolution, frame=pre_frame(v[used], index[f[keep]]), capped=capped,
                              reach=0)


def _grid_centers(sol):
    """(n, 3) kept voxel centers in grid coordinates and their (n,) depths."""
    idx = np.stack(np.nonzero(sol.inside), axis=1)
    return sol.origin + sol.pitch * (idx + 0.5), sol.depth[sol.inside], idx


def _weights(d, power):
    top = d.max()
    return (d / top) ** float(power) if top > 0 else np.ones_like(d)


def _check_voxels(sol, what):
    """``sol`` a Solid with its depth (:func:`parts.check_solid`) and at least one voxel inside;
    InvalidInputError saying ``what`` an empty one has otherwise."""
    parts.check_solid(sol)
    if not np.any(sol.inside):
        raise InvalidInputError(f"sol has no voxel inside (its inside is {np.shape(sol.inside)}, 0 voxels set): an "
                                f"empty solid has {what}; core_frame and head_frame flag such a solid instead")


def symmetry_scores(sol, axes, center, power=SYMMETRY_POWER):
    """Mirror self-overlap (3,) of the depth^p-weighted solid about the plane through ``center``
    orthogonal to each row of ``axes`` (grid coordinates): s_a = sum min(w(x), w(M_a x)) / sum w(x),
    M_a the reflection, w read at the voxel nearest M_a x (0 outside). 1 for a mirror-symmetric solid.
    InvalidInputError for a ``sol`` that is no Solid with its depth (:func:`parts.check_solid`) or
    has no voxel inside (no score: NumPy's 'zero-size array to reduction'), ``axes`` not (3, 3),
    ``center`` not (3,), a power not a finite number >= 0 (NumPy's broadcast errors)."""
    _check_voxels(sol, "no mirror score")
    check_shape(axes, "axes", (3, 3), finite=True)
    center = check_shape(center, "center", (3,), finite=True)
    check_real(power, "power", 0)
    y, d, _ = _grid_centers(sol)
    w = _weights(d, power)
    grid = np.zeros(sol.inside.shape)
    grid[sol.inside] = w
    shape = np.array(sol.inside.shape)
    out = np.zeros(3)
    for a, e in enumerate(np.asarray(axes, np.float64)):
        ym = y - 2.0 * ((y - center) @ e)[:, None] * e
        ir = np.floor((ym - sol.origin) / sol.pitch).astype(np.int64)
        ok = np.all((ir >= 0) & (ir < shape), axis=1)
        wr = np.zeros(len(y))
        wr[ok] = grid[tuple(ir[ok].T)]
        out[a] = np.minimum(w, wr).sum() / w.sum()
    return out


def feet_offset(sol, axes, up=0, forward=2):
    """Where the feet point: the forward offset of each foot from its ankle, in units of the length.

    The slab of the solid within ``FOOT`` of the length L at the end axis ``up`` points to (the
    legs' end: it points to the far mass) is split into its connected parts (the feet, or whatever
    ends the body there); each part is compared with the solid just above it (within ``FOOT`` of L
    above the slab and ``2 FOOT`` of L sideways from the part's centroid): s = sum_parts n_p
    (f_part - f_above) / (L sum_p n_p), f the coordinate along ``forward``. Feet reach forward of
    the ankles (the foot centroid lies about 3 % of a person's height ahead of the ankle). A slab
    deeper than ``FEET_DEPTH`` of the solid's depth somewhere is not feet (a head, a trunk): no cue.

    Args:
      sol: Solid; axes: (3, 3) rows in grid coordinates (oriented: ``up`` toward the legs).

    Returns:
      () the offset s (0 when no part is found).

    Raises:
      InvalidInputError: ``sol`` no Solid with its depth, or one with no voxel inside (NumPy's
        'zero-size array to reduction'), ``axes`` not (3, 3), ``up`` and ``forward`` not two
        different axes 0, 1, 2 (NumPy's IndexError).
    """
    _check_voxels(sol, "no feet")
    check_shape(axes, "axes", (3, 3), finite=True)
    if check_int(up, "up", 0) > 2 or check_int(forward, "forward", 0) > 2 or up == forward:
        raise InvalidInputError(f"up and forward must be two different axes, 0, 1 or 2, got {up!r} and {forward!r}")
    y, d, idx = _grid_centers(sol)
    z = _turned(y - y.mean(axis=0), np.asarray(axes, np.float64).T)
    h, f = z[:, up], z[:, forward]
    side = z[:, 3 - up - forward]
    length = h.max() - h.min()
    slab = h >= h.max() - FOOT * length
    if d[slab].max() > FEET_DEPTH * d.max():  # too thick for feet (a head, a trunk, knees): no cue
        return 0.0
    grid = np.zeros(sol.inside.shape, bool)
    grid[tuple(idx[slab].T)] = True
    labels, count = ndimage.label(grid, np.ones((3, 3, 3), bool))
    part = labels[tuple(idx.T)]
    total, mass = 0.0, 0
    for p in range(1, count + 1):
        mine = part == p
        top = h[mine].min()
        near = (h < top) & (h >= top - FOOT * length) & \
            (np.hypot(f - f[mine].mean(), side - side[mine].mean()) < 2 * FOOT * length)
        if near.sum() == 0:
            continue
        total += mine.sum() * (f[mine].mean() - f[near].mean())
        mass += mine.sum()
    return total / (mass * length) if mass else 0.0


def _undetermined():
    return Frame(np.eye(3), 1.0, np.zeros(3), np.zeros(2), np.zeros(3), 2, np.full(3, np.nan))


def core_frame(sol, power=AXES_POWER, feet=True, cross_check=True) -> Frame:
    """The ``core`` frame (module docs, steps 2-6) of a solid from :func:`frame_solid`.

    Args:
      sol: :class:`jaxpose.occupancy.solid.Solid` (any grid frame; equivariant when laid out by :func:`pre_frame`).
      power: depth exponent of the axes' weights.
      feet: when the third moment leaves the sign of the minor non-mirror axis undetermined, take
        it from :func:`feet_offset`; when the mirror test is undetermined, the feet choose (step 5).
      cross_check: call the first axis's sign undetermined when the deep core's side (step 6)
        disagrees with its third moment.

    Returns:
      :class:`Frame`; ``mirror`` is the mirror axis; ``margins`` the sign cues' margins as
      multiples of their thresholds (< 1: undetermined).
    """
    parts.check_solid(sol)
    y, d, _ = _grid_centers(sol)
    if len(y) < 4:
        return _undetermined()
    w = _weights(d, power)
    c = (w @ y) / w.sum()
    z = y - c
    lam, axes = descending_axes((z * w[:, None]).T @ z / w.sum())
    zc = _turned(y - y.mean(axis=0), axes.T)
    stat = third_moments(zc) / SIGN_MIN  # signed, in multiples of the threshold
    conf = np.abs(stat)
    w2 = _weights(d, SYMMETRY_POWER)
    sym = symmetry_scores(sol, axes, (w2 @ y) / w2.sum())
    k = 1 if sym[1] >= sym[2] else 2  # the long axis lies in the mirror plane
    mirror_ratio = abs(sym[1] - sym[2]) / SYMMETRY_MIN
    h = zc[:, 0]
    if cross_check and (0.5 * (h.max() + h.min()) - (w @ h) / w.sum()) * stat[0] <= 0:
        conf[0] = 0.0
    if feet:
        oriented = axes.copy()
        oriented[0] *= 1.0 if stat[0] >= 0 else -1.0
        offset = {a: feet_offset(sol, oriented, 0, a) / FOOT_MIN for a in (1, 2)}
        split = abs(offset[1]) - abs(offset[2])  # the feet point along the forward axis, not the mirror axis
        if mirror_ratio < 1.0 and abs(split) > mirror_ratio:
            k, mirror_ratio = (2 if split > 0 else 1), abs(split)
        minor = 3 - k
        if conf[minor] < 1.0:
            stat[minor] = offset[minor]
            conf[minor] = abs(offset[minor])
    rot, _, k = complete_signs(axes, stat, completed=k, to_world=sol.frame)
    conf[k] = 0.0
    gaps = relative_gaps(lam)
    contrast = min(SYMMETRY_MIN * mirror_ratio, sym[k] - sym[0])  # the long axis lies in the mirror plane
    amb = ambiguity(gaps, np.min(np.delete(conf, k)), contrast)
    return Frame(rot, amb, lam, gaps, conf, k, sym)
