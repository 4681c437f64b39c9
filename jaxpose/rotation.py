"""Canonical axes of a shape: a rotation that holds under articulation, and every frame by name.

A frame (:class:`jaxpose.orientation.Frame`) is a proper rotation R (3, 3) whose rows are the
shape's canonical axes in world coordinates (det R = +1); canonical coordinates are
R (x - c) / s. :func:`frame_of` gives any of :data:`ROTATIONS` by name: ``core`` and ``head``
(built here), ``ocsvm`` (:func:`jaxpose.orientation.region_frame`, through :func:`jaxpose.normalize`) and the
baselines of :mod:`jaxpose.baselines`. The sign rule's pieces, the ambiguity and its thresholds
are in :mod:`jaxpose.orientation` (re-exported here).

``core`` (meshes and point clouds, :func:`core_frame`), on the robust voxel solid of
:mod:`jaxpose.solid`:

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
   sign comes from det R = +1.
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

``head`` (the default of ``rotation=True``; meshes and point clouds, :func:`head_frame`), on the
same solid: a frame tied to the head and the chest, the parts that move least with a person's
limbs and waist.

1. Parts. The head, the neck and the trunk (:func:`jaxpose.parts.find_parts`: the two thick parts
   of the depth field that meet at its most constricted saddle). No neck (a ball, a box, a shape
   whose parts are all thin beside its thickest): the ``core`` frame, with its own ambiguity.
2. Up. From the chest (the solid on the trunk's side of the neck within ``CHEST`` head depths of
   it, each voxel weighted by depth^``CHEST_POWER``) to the head's centroid; it points to the head.
3. Front-back and left-right. The chest's second moments across up: a chest is wider than it is
   deep, so the thinner direction is front-back; left-right completes det = +1.
4. Rows. As the ``core`` frame's for a person: axis 0 from the head toward the feet (-up),
   axis 2 back to front, axis 1 = axis 2 x axis 0 (det +1).
5. Front-back's sign. A majority vote of three offsets along it, each a habit of human bodies:
   the whole head beyond the neck lies ahead of the chest-to-head line (face and jaw ahead of the
   skull's deep core); the body's centroid lies ahead of the chest (legs and arms reach forward:
   sitting, walking, holding); the jaw, the solid just above the neck (up to ``JAW`` head
   depths), reaches farther forward than back.
6. Ambiguity (the formula of :func:`jaxpose.orientation.ambiguity`): the neck's distinctness
   (constriction - runner-up) / constriction and the chest's gap across up, each against
   ``GAP_MIN``, and the vote, which clears only when unanimous (2 of 3: ambiguity 2/3).

How the ``head`` and ``core`` frames do on real bodies, and when to prefer which:
docs/rotation.md.

Equivariance holds up to float rounding for inputs whose pre-frame third moments are not zero; an
exactly mirror-symmetric input leaves the sign of its pre-frame's mirror axis to rounding, and its
grid may then come out mirrored (voxel-level differences).
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy import ndimage

from . import baselines, parts, sample, solid
from ._validate import InvalidInputError, JaxposeError
from .orientation import (GAP_MIN, SIGN_MIN, SYMMETRY_MIN, Frame, ambiguity, complete_signs, descending_axes, proper,
                          region_frame, relative_gaps)
from .voxels import GRID_SHIFT

__all__ = ["Frame", "ROTATIONS", "DEFAULT_ROTATION", "GAP_MIN", "SIGN_MIN", "SYMMETRY_MIN", "FOOT", "FEET_DEPTH",
           "FOOT_MIN", "AXES_POWER", "SYMMETRY_POWER", "CHEST", "CHEST_POWER", "JAW", "pre_frame", "frame_solid",
           "core_frame", "HeadChest", "head_chest", "front_back_cues", "head_frame", "feet_offset",
           "symmetry_scores", "ambiguity", "complete_signs", "frame_of", "region_frame", "proper"]

ROTATIONS = ("core", "head", "ocsvm", "pca_vertices", "pca_surface", "inertia")
DEFAULT_ROTATION = "head"  # rotation=True: the head frame, the core frame where no neck is found
FOOT = 0.05  # the feet: this share of the length at the legs' end (ankles at about 4 % of a person's height)
FEET_DEPTH = 0.5  # feet are thinner than half the trunk's depth (ankle ~4 cm, head ~9 cm, trunk ~11 cm)
FOOT_MIN = 0.01  # feet offset (in lengths) below which it is called undetermined: about one voxel
AXES_POWER = 4.0  # depth exponent of the axes' weights
CHEST = 2.0  # head: the chest is the solid on the trunk's side of the neck within this many head depths of it
CHEST_POWER = 2.0  # head: depth exponent of the chest's weights
JAW = 0.5  # head: the jaw is the solid on the head's side of the neck up to this many head depths above it
SYMMETRY_POWER = 2.0  # depth exponent of the mirror test's weights


# ------------------------------------------------------------------ the core frame
def _third_moments(x, w=None):
    """(3,) signs-only helper: sum w (x - mean)^3 per axis of x (n, 3)."""
    w = np.ones(len(x)) if w is None else w
    d = x - (w @ x) / w.sum()
    return w @ (d ** 3)


def pre_frame(vertices, faces=None):
    """The grid frame of :func:`frame_solid`: principal axes of the input, signs by third moments.

    Meshes: the exact second moments of the surface (area-weighted, closed form per triangle);
    point clouds (``faces`` None): the covariance of the points. Each axis points to the positive
    third moment of the vertices along it, so the frame of a rotated input is the rotated frame.

    Args:
      vertices: (n, 3) float; faces: (f, 3) int or None.

    Returns:
      (3, 3) orthonormal rows (largest second moment first; not necessarily proper).
    """
    v = np.asarray(vertices, np.float64)
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
    skew = _third_moments(v @ axes.T)
    return axes * np.where(skew >= 0, 1.0, -1.0)[:, None]


def frame_solid(vertices, faces=None, resolution=None):
    """The robust solid (:func:`jaxpose.solid.robust_solid`) on a grid along :func:`pre_frame`."""
    resolution = solid.RESOLUTION if resolution is None else int(resolution)
    return solid.robust_solid(vertices, faces, resolution=resolution, frame=pre_frame(vertices, faces))


def _grid_centers(sol):
    """(n, 3) kept voxel centers in grid coordinates and their (n,) depths."""
    idx = np.stack(np.nonzero(sol.inside), axis=1)
    return sol.origin + sol.pitch * (idx + 0.5), sol.depth[sol.inside], idx


def _weights(d, power):
    top = d.max()
    return (d / top) ** float(power) if top > 0 else np.ones_like(d)


def symmetry_scores(sol, axes, center, power=SYMMETRY_POWER):
    """Mirror self-overlap (3,) of the depth^p-weighted solid about the plane through ``center``
    orthogonal to each row of ``axes`` (grid coordinates): s_a = sum min(w(x), w(M_a x)) / sum w(x),
    M_a the reflection, w read at the voxel nearest M_a x (0 outside). 1 for a mirror-symmetric solid."""
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
    """
    y, d, idx = _grid_centers(sol)
    z = (y - y.mean(axis=0)) @ np.asarray(axes, np.float64).T
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


def core_frame(sol, power=AXES_POWER, feet=True, cross_check=True) -> Frame:
    """The ``core`` frame (module docs, steps 2-6) of a solid from :func:`frame_solid`.

    Args:
      sol: :class:`jaxpose.solid.Solid` (any grid frame; equivariant when laid out by :func:`pre_frame`).
      power: depth exponent of the axes' weights.
      feet: when the third moment leaves the sign of the minor non-mirror axis undetermined, take
        it from :func:`feet_offset`; when the mirror test is undetermined, the feet choose (step 5).
      cross_check: call the first axis's sign undetermined when the deep core's side (step 6)
        disagrees with its third moment.

    Returns:
      :class:`Frame`; ``mirror`` is the mirror axis; ``margins`` the sign cues' margins as
      multiples of their thresholds (< 1: undetermined).
    """
    y, d, _ = _grid_centers(sol)
    if len(y) < 4:
        return _undetermined()
    w = _weights(d, power)
    c = (w @ y) / w.sum()
    z = y - c
    lam, axes = descending_axes((z * w[:, None]).T @ z / w.sum())
    zc = (y - y.mean(axis=0)) @ axes.T
    r = np.sqrt(np.mean(np.sum(zc * zc, axis=1)))
    stat = np.mean(zc ** 3, axis=0) / r ** 3 / SIGN_MIN  # signed, in multiples of the threshold
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
    amb = ambiguity(gaps, np.min(np.delete(conf, k)), SYMMETRY_MIN * mirror_ratio)
    return Frame(rot, amb, lam, gaps, conf, k, sym)


class HeadChest(NamedTuple):
    """The geometry of the ``head`` frame on a solid's grid (grid coordinates; :func:`head_chest`).

    Attributes:
      parts: :class:`jaxpose.parts.Parts` (head, trunk, neck).
      centers: (n, 3) the kept voxels' centers; depth: (n,) their depths; index: (n, 3) their voxels.
      chest: (n,) bool, the chest (the solid on the trunk's side of the neck within ``CHEST`` head depths).
      chest_center: (3,) its depth^``CHEST_POWER``-weighted centroid; cov: (3, 3) its second moment.
      head_center: (3,) the head blob's centroid.
      up: (3,) unit, from ``chest_center`` to ``head_center``.
      front_back: (3,) unit, the thinner of the chest's second moments across ``up`` (sign unset).
      spread: (2,) the chest's second moments across ``up``: front-back, left-right (units^2).
      eps: the offset (``GRID_SHIFT`` of a pitch) that keeps planes and spheres off voxel centers.
    """

    parts: parts.Parts
    centers: np.ndarray
    depth: np.ndarray
    index: np.ndarray
    chest: np.ndarray
    chest_center: np.ndarray
    cov: np.ndarray
    head_center: np.ndarray
    up: np.ndarray
    front_back: np.ndarray
    spread: np.ndarray
    eps: float


def head_chest(sol, found):
    """The head, chest and axes of the ``head`` frame (module docs, steps 2-3) on a solid from
    :func:`frame_solid` and its :func:`jaxpose.parts.find_parts`; None where no chest lies below
    the neck. Every plane and sphere is moved off the voxel centers by ``GRID_SHIFT`` of a pitch, so
    that no voxel lies on one (where rounding, not the shape, would decide: lattice-aligned shapes)."""
    y, d, idx = _grid_centers(sol)
    hd, neck = found.head_depth, found.neck
    hc = y[found.head[tuple(idx.T)]].mean(axis=0)
    eps = GRID_SHIFT * sol.pitch
    saddle = np.rint((neck - sol.origin) / sol.pitch - 0.5)
    reach = (CHEST * hd + eps) / sol.pitch
    toward = (hc - neck) / np.linalg.norm(hc - neck)
    chest = ((y - neck) @ toward < -eps) & (np.sum((idx - saddle) ** 2, axis=1) < reach ** 2)
    w = d[chest] ** CHEST_POWER
    if chest.sum() < 4 or not w.sum() > 0:
        return None
    cc = (w @ y[chest]) / w.sum()
    up = (hc - cc) / np.linalg.norm(hc - cc)
    z = y[chest] - cc
    cov = (z * w[:, None]).T @ z / w.sum()
    across = np.eye(3) - np.outer(up, up)
    lam, vec = np.linalg.eigh(across @ cov @ across)  # ascending: ~0 along up, front-back, left-right
    return HeadChest(found, y, d, idx, chest, cc, cov, hc, up, vec[:, 1], lam[1:], eps)


def front_back_cues(geo, front_back):
    """(3,) the vote's offsets along ``front_back`` (module docs, step 5), in units: the whole head
    beyond the neck ahead of the chest, the body's centroid ahead of the chest, and the jaw's
    reach ahead of the neck (its 98th plus its 2nd percentile)."""
    rel = geo.centers - geo.parts.neck
    height, ahead = rel @ geo.up, rel @ front_back
    hd, eps = geo.parts.head_depth, geo.eps
    beyond = height > eps  # the whole head, beyond the neck
    jaw = beyond & (height < JAW * hd + eps) & (np.abs(rel @ np.cross(front_back, geo.up)) < hd + eps)
    return np.array([(geo.centers[beyond].mean(axis=0) - geo.chest_center) @ front_back if beyond.any() else 0.0,
                     (geo.centers.mean(axis=0) - geo.chest_center) @ front_back,
                     np.quantile(ahead[jaw], 0.98) + np.quantile(ahead[jaw], 0.02) if jaw.any() else 0.0])


def head_frame(sol) -> Frame:
    """The ``head`` frame (module docs) of a solid from :func:`frame_solid`.

    Returns:
      :class:`Frame`: ``eigenvalues`` the chest's second moments along the final axes (units^2);
      ``gaps`` the neck's distinctness (constriction - runner-up) / constriction and the chest's
      relative gap across ``up``; ``margins`` (neck gap / GAP_MIN, 0, agreeing cues / 3); ``mirror``
      1 (left-right, completed by det). A solid with no neck gets :func:`core_frame`.
    """
    found = parts.find_parts(sol)
    geo = None if found is None else head_chest(sol, found)
    if geo is None:  # no neck, or no chest below it: no frame of the head and chest
        return core_frame(sol)
    votes = float(np.sign(front_back_cues(geo, geo.front_back)).sum())
    fb = geo.front_back if votes >= 0 else -geo.front_back
    axes = np.stack([-geo.up, np.cross(fb, -geo.up), fb])  # axis 0 points to the feet, as the core frame's
    down, fb_w = -geo.up @ sol.frame, fb @ sol.frame
    rot = np.stack([down, np.cross(fb_w, down), fb_w])  # det +1 also where the grid frame is improper
    gaps = np.array([(found.constriction - found.runner_up) / found.constriction,
                     (geo.spread[1] - geo.spread[0]) / max(geo.spread[1], 1e-300)])
    agree = abs(votes) / 3.0
    moments = np.einsum("ai,ij,aj->a", axes, geo.cov, axes)
    return Frame(rot, ambiguity(gaps, agree), moments, gaps, np.array([gaps[0] / GAP_MIN, 0.0, agree]), 1,
                 np.full(3, np.nan))


def _undetermined():
    return Frame(np.eye(3), 1.0, np.zeros(3), np.zeros(2), np.zeros(3), 2, np.full(3, np.nan))


# ------------------------------------------------------------------ dispatch (host)
def frame_of(geometry, method=DEFAULT_ROTATION, *, resolution=None, sol=None, ocsvm=None) -> Frame:
    """The canonical frame of a mesh or point cloud by name (one of :data:`ROTATIONS`).

    Args:
      geometry: Trimesh, PointCloud or (n, 3) points.
      method: ``head`` (default; ``core`` where it finds no neck), ``core``, ``ocsvm`` or a baseline of
        :mod:`jaxpose.baselines`
        (``pca_vertices``, ``pca_surface``, ``inertia``: meshes only).
      resolution: voxels of the robust solid along the body's largest extent (``core``).
      sol: a solid from :func:`frame_solid` to reuse (``core``).
      ocsvm: for ``ocsvm``, a dict of ``gamma``, ``nu``, ``count``, ``seed``, ``sampling`` and
        ``options`` (of :func:`jaxpose.normalize`).

    Returns:
      :class:`Frame` (rotation in the input's world coordinates).
    """
    if method not in ROTATIONS:
        raise InvalidInputError(f"unknown rotation {method!r}; valid: {', '.join(ROTATIONS)}")
    if method in ("core", "head"):
        if sol is None:
            vertices, faces = baselines.split_geometry(geometry)
            sol = frame_solid(vertices, faces, resolution)
        if not sol.inside.any():
            raise JaxposeError(f"the shape encloses no volume: the {method} frame is undefined; "
                               "use rotation='pca_surface' or 'ocsvm'")
        return core_frame(sol) if method == "core" else head_frame(sol)
    if method == "ocsvm":
        from .pose import normalize  # JAX only when asked for

        o = dict(ocsvm or {})
        points = sample.sample_surface(geometry, o.get("count", 2000), seed=o.get("seed", 0),
                                       method=o.get("sampling", "even"))
        pose = normalize(points, o.get("gamma", 47.0), o.get("nu", 0.5), rotation=True, **o.get("options", {}))
        return Frame(np.asarray(pose.rotation, np.float64), float(np.asarray(pose.ambiguity)),
                     np.full(3, np.nan), np.full(2, np.nan), np.full(3, np.nan), -1, np.full(3, np.nan))
    return baselines.frame(geometry, method)
