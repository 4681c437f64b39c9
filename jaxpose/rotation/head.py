"""The ``head`` frame of a shape: axes tied to its head and chest, on the solid of :func:`.core.frame_solid`.

``head`` (the default of ``rotation=True``; meshes and point clouds, :func:`head_frame`), on the
same solid: a frame tied to the head and the chest, the parts that move least with a person's
limbs and waist.

1. Parts. The head, the neck and the trunk (:func:`jaxpose.rotation.parts.find_head`: the two thick
   parts of the depth field that meet at its most constricted saddle where that head ends the
   body; else the thickest part beyond a saddle that ends the body: an animal's head, thinner than
   half its trunk). No head (a ball, a box, a capsule): the ``core`` frame, flagged (ambiguity 1):
   a frame of the trunk's mass turns with the waist and follows a person's build in its signs, and
   no head vouches for it (rotation="core" asks for it unflagged where its own cues hold).
2. Up. From the chest (the solid on the trunk's side of the neck within ``CHEST`` head depths of
   it, each voxel weighted by depth^``CHEST_POWER``) to the head's centroid; it points to the head.
   A head with a snout (step 5) has an up of its own, across the snout in its mirror plane (a
   long neck bends against it); there up is the bisector of the two.
3. Left-right (:func:`left_right`). A head is rigid and bilaterally symmetric in every pose: the
   normal of its surface's best mirror plane across up (:func:`head_mirror`; on a point cloud the
   surface more than ``MIRROR_BEYOND`` head depths beyond the neck: its closed solid's neck lies
   low on the neck, and the neck may turn against the head) is its left-right axis, whatever the
   body's build (a person's chest is wider than deep, a dog's or a horse's
   deeper than wide). A body's frame is its head's and its chest's together: where the head's
   normal lies within ``TURN`` degrees of one of the chest's two second-moment axes across up,
   left-right is the bisector of the two; where it does not, the head is turned against the chest
   and left-right is the chest axis whose plane mirrors the depth^2 solid better; where neither
   mirrors clearly better, the chest's flatter direction is front-back (a person's build), flagged.
   Front-back is up x left-right.
4. Rows. As the ``core`` frame's for a person: axis 0 from the head toward the feet (-up),
   axis 2 back to front, axis 1 = axis 2 x axis 0 (det +1).
5. Front-back's sign: the face, or a muzzle. The head's surface is the input's points above the
   neck within ``FACE`` head depths of the head blob's balls (:func:`head_surface`; a mesh's
   vertices and points on its faces every ``CELL`` pitches), pooled in cells of ``CELL`` pitches,
   each cell that holds points one point at their mean: area at that scale, not the sampling
   density. Where a mesh is open, its holes are read from the solid's boundary, which the ray
   votes close (:func:`hole_points`): a point whose mirror image falls in a hole is then no
   evidence against the head's mirror plane, and a face with a hole in it still hangs where it did.
   The skull's center is the head blob's depth^2-weighted centroid. The neck holds the
   skull from behind and below, and the face hangs in front of it: the head's surface below the
   skull's center (jaw, mouth, chin) lies ahead of that center (:func:`front_back_cues`). A pose
   cannot turn this around; the neck's bend only tilts it. A second reading checks it: the
   surface reaches farther ahead of the center than behind it (its 98th plus its 2nd percentile
   along the axis). A snout is the other face: where the part beyond the neck (the head as cut
   off across its neck, :func:`jaxpose.rotation.parts.find_head`; none where it could not be cut
   off) reaches at least ``MUZZLE`` head depths ahead of the skull and farther than the jaw
   hangs, it decides (a person's head is round about its
   skull; a horse's muzzle is a head depth long). Where it does not, but the same part reaches at
   least ``MUZZLE`` head depths ahead of the neck that holds the head (its saddle), farther than
   the jaw hangs, and at least ``FACE_MIN`` head depths ahead of the skull's center too (a round
   head set ahead of its neck is no snout), that reading gives front-back's sign (the axes stay the chest's): the
   skull's center is the deepest blob's, and a filled notch (a hole's cap across throat and jaw)
   moves it, with the jaw reading; the neck's saddle, where the head is held, it leaves. Where
   the jaw and the reach both read the other way, the frame is flagged. Where the jaw decides and its two readings
   disagree, what was found may not be a head (a hand on it, holes in it), or a long neck's
   surface hangs below the skull: the part beyond the neck breaks the tie where it reaches at
   least ``FACE_MIN`` head depths ahead or behind (flagged, ambiguity 1), else the frame is the
   ``core`` frame, flagged.
6. Ambiguity (the formula of :func:`jaxpose.orientation.ambiguity`): the neck's distinctness
   (constriction - runner-up) / constriction (not asked of a head found to end the body) and the
   head's mirror contrast (:func:`head_mirror`), each against ``GAP_MIN``; the deciding reading's
   lead in head depths (less the other reading of step 5 where it disagrees) against
   ``FACE_MIN``; and the mirror test: a bilateral body's left-right axis is the normal of its best
   mirror plane, so the mirror score (:func:`symmetry_scores`, depth^``SYMMETRY_POWER`` weights,
   about the planes through their centroid) of axis 1 less the larger of the other two, against
   ``SYMMETRY_MIN`` (a body bent sideways, a crouching child: flagged, though the head's frame
   may be right). Flagged outright (ambiguity 1): on an incomplete surface (a point cloud, or a
   mesh that is not closed: :func:`jaxpose.geometry.is_closed`) a head found only as an end of
   the body (no thick neck: it may be a limb, a tail or a rump where the surface is missing); on a
   point cloud a head that could not be cut off at its neck (the cloud's closed solid may join it
   to another part); and a snout's up more than ``UP_SPLIT`` degrees from the chest's (their
   bisector is neither).

The cells make the sign a property of the shape: with each vertex counted once instead,
a registered mesh, meshed finer on the face than on the skull, reads a stronger cue that a
uniformly sampled scan would not give (docs/rotation.md).
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy.spatial import cKDTree

from .. import sample
from .._validate import InvalidInputError, check_array, check_shape
from ..geometry import is_closed
from . import parts
from ..orientation import GAP_MIN, SYMMETRY_MIN, Frame, ambiguity
from ..occupancy.voxels import GRID_SHIFT
from .core import SYMMETRY_POWER, _grid_centers, _turned, _weights, core_frame, symmetry_scores

__all__ = ["CHEST", "CHEST_POWER", "FACE", "CELL", "FACE_MIN", "MUZZLE", "TURN", "HEAD_MIRROR", "UP_SPLIT",
           "MIRROR_STEPS", "MIRROR_BEYOND", "GAP", "HeadChest", "head_surface", "hole_points", "head_chest",
           "front_back_cues", "mirror_error", "head_mirror", "left_right", "head_frame"]

CHEST = 2.0  # head: the chest is the solid on the trunk's side of the neck within this many head depths of it
CHEST_POWER = 2.0  # head: depth exponent of the chest's weights
FACE = 0.5  # head: its surface is the input's points within this many head depths of the head blob's balls
CELL = 0.5  # head: the head's surface is read in cells of this many pitches, each holding points counted once
FACE_MIN = 0.1  # head: the face's offset (head depths) below which front-back is called undetermined
MUZZLE = 0.5  # head: the part beyond the neck this many head depths ahead of the skull is a muzzle (a snout)
TURN = 30.0  # head: degrees; the head's mirror normal farther than this from both chest axes turns against the chest
HEAD_MIRROR = 0.25  # head: a head found only as the part that ends the body must mirror itself at least this clearly
UP_SPLIT = 60.0  # head: degrees; a snout's up farther than this from the chest's: flagged
MIRROR_STEPS = 36  # head: the head's mirror plane is searched over half a turn in this many steps, then refined
MIRROR_BEYOND = 1.0  # head, point clouds: the mirror plane is read from the surface this many head depths beyond the neck
GAP = 1.0  # head: the solid's boundary farther than this many pitches from an open mesh's surface lies in a hole


class HeadChest(NamedTuple):
    """The geometry of the ``head`` frame on a solid's grid (grid coordinates; :func:`head_chest`).

    Attributes:
      parts: :class:`jaxpose.rotation.parts.Parts` (head, trunk, neck).
      centers: (n, 3) the kept voxels' centers; depth: (n,) their depths; index: (n, 3) their voxels.
      chest: (n,) bool, the chest (the solid on the trunk's side of the neck within ``CHEST`` head depths).
      chest_center: (3,) its depth^``CHEST_POWER``-weighted centroid; cov: (3, 3) its second moment.
      head_center: (3,) the head blob's centroid.
      up: (3,) unit, from ``chest_center`` to ``head_center``.
      front_back: (3,) unit, the thinner of the chest's second moments across ``up`` (sign unset).
      spread: (2,) the chest's second moments across ``up``: front-back, left-right (units^2).
      skull: (3,) the head blob's depth^2-weighted centroid (the center of the skull).
      surface: (k, 3) the head's surface, one point per cell holding input points (:func:`head_surface`).
      eps: the offset (``GRID_SHIFT`` of a pitch) that keeps planes and spheres off voxel centers.
      beyond: (3,) the centroid of the part beyond the neck as cut off there
        (:attr:`jaxpose.rotation.parts.Parts.beyond`); the skull where the head could not be cut off.
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
    skull: np.ndarray
    surface: np.ndarray
    eps: float
    beyond: np.ndarray


def _head_reach(sol, found, eps):
    """The head blob's voxel centers (k, 3) and depths (k,) (its balls), the reach ``FACE`` head
    depths (+ eps) beyond them, their center (3,) and the radius about it that holds every ball
    grown by the reach (grid coordinates, units)."""
    balls = sol.origin + sol.pitch * (np.argwhere(found.head) + 0.5)
    radii = sol.depth[found.head]
    reach = FACE * found.head_depth + eps
    center = balls.mean(axis=0)
    return balls, radii, reach, center, np.max(np.linalg.norm(balls - center, axis=1) + radii) + reach


def _near_faces(sol, vertices, faces, center, bound):
    """The faces (k, 3) of ``faces`` (f, 3) whose points may lie within ``bound`` + (``GAP`` + 1)
    pitches of ``center`` (grid coordinates; :func:`_head_reach`): every point of the head's surface
    (:func:`head_surface`) and of the surface about its holes (:func:`hole_points`) lies there. A
    face's points lie within its vertices' largest distance from their mean; one more pitch is left
    for rounding. :func:`jaxpose.sample.lattice_points` of these faces holds the same points near
    the head, in the same order, as of all the faces (each face's points are its own). None or
    empty ``faces``: returned as given."""
    if faces is None or not len(faces):
        return faces
    f = np.asarray(faces, np.int64)
    t = _turned(vertices, sol.frame.T)[f]
    mid = t.mean(axis=1)
    spread = np.max(np.linalg.norm(t - mid[:, None], axis=2), axis=1)
    return f[np.linalg.norm(mid - center, axis=1) - spread < bound + (GAP + 2.0) * sol.pitch]


def head_surface(points, sol, found, up, eps, cell=CELL):
    """The head's surface as points (module docs, step 5): each cell that holds input points, once.

    A point belongs to the head when it lies above the plane through the neck across ``up`` and
    within ``FACE`` head depths of one of the head blob's balls (the ball about each voxel of
    ``found.head`` with that voxel's depth as radius: the blob grown back to the head's surface).
    The points are first pooled in cells of ``cell`` pitches, each cell one point at their mean:
    the result measures surface area at that scale, whatever the input's sampling density (a
    registered mesh's face is meshed finer than its skull).

    Args:
      points: (m, 3) the input's points (a mesh's vertices) in the solid's grid coordinates.
      sol: the solid; found: its :class:`jaxpose.rotation.parts.Parts`; up: (3,) unit; eps: plane offset.
      cell: the cells' edge in pitches; None keeps every point (each counted once).

    Returns:
      (k, 3) grid coordinates (k = 0 where no point is on the head).
    """
    balls, radii, reach, center, bound = _head_reach(sol, found, eps)
    p = points[(np.linalg.norm(points - center, axis=1) < bound) & (_turned(points - found.neck, up) > eps)]
    if cell is not None and len(p):
        key = np.floor((p - sol.origin) / (cell * sol.pitch) + GRID_SHIFT).astype(np.int64)
        key -= key.min(axis=0)
        span = key.max(axis=0) + 1
        _, inverse, counts = np.unique((key[:, 0] * span[1] + key[:, 1]) * span[2] + key[:, 2],
                                       return_inverse=True, return_counts=True)
        p = np.stack([np.bincount(inverse, weights=p[:, j]) for j in range(3)], axis=1) / counts[:, None]
    q, b = p - center, balls - center  # |q - b| < radius + reach, as one matrix product
    near = np.sum(q * q, axis=1)[:, None] - 2.0 * q @ b.T + np.sum(b * b, axis=1)[None] < ((radii + reach) ** 2)[None]
    return p[near.any(axis=1)]


def hole_points(sol, points, gap=GAP, cell=CELL, near=None):
    """Points of the solid's boundary where the input's surface is missing (an open mesh's holes).

    The solid's boundary is the voxel faces between its kept voxels and the outside; each face is
    sampled on a lattice of ``cell`` pitches (a 2 x 2 grid of points at the default 0.5: the
    density of the mesh's own points in :func:`head_surface`'s cells). On a surface that is
    present every such point lies within about half a pitch of one of the input's points (the
    faces are at most half a pitch from the surface); one farther than ``gap`` pitches from all of
    them lies in a hole, where the solid (closed by its votes) stands in for the missing surface.

    Args:
      sol: the solid of :func:`.core.frame_solid`; points: (m, 3) the input's surface points, world
        coordinates (:func:`jaxpose.sample.lattice_points`).
      gap: pitches; cell: the boundary's sampling step in pitches.
      near: optional ((3,) center, radius) in grid coordinates: only the boundary within that
        ball (the same points as without it, inside the ball; cheaper).

    Returns:
      (k, 3) world coordinates (k = 0 on a closed surface).
    """
    y = _turned(points, sol.frame.T)
    if near is not None:
        y = y[np.linalg.norm(y - near[0], axis=1) < near[1] + (gap + 1.0) * sol.pitch]
    n = max(1, int(round(1.0 / cell)))
    offsets = (np.arange(n) + 0.5) / n - 0.5  # the sample points within a face, in pitches
    pad = np.pad(sol.inside, 1)
    out = []
    for a in range(3):
        b, c = [x for x in range(3) if x != a]
        for s in (-1, 1):
            face = np.argwhere(sol.inside & ~np.roll(pad, -s, axis=a)[1:-1, 1:-1, 1:-1]).astype(np.float64)
            face[:, a] += 0.5 * s
            for u in offsets:
                for v in offsets:
                    q = face.copy()
                    q[:, b] += u
                    q[:, c] += v
                    out.append(q)
    q = sol.origin + sol.pitch * (np.concatenate(out) + 0.5)
    if near is not None:
        q = q[np.linalg.norm(q - near[0], axis=1) < near[1]]
    if not len(y):
        return _turned(q, sol.frame)
    far = cKDTree(y).query(q, distance_upper_bound=gap * sol.pitch)[0] > gap * sol.pitch
    return _turned(q[far], sol.frame)


def head_chest(sol, found, points):
    """The head, chest, axes and head surface of the ``head`` frame (module docs, steps 2-5) on a
    solid from :func:`.core.frame_solid`, its :func:`jaxpose.rotation.parts.find_parts` and the input's (m, 3)
    points (world coordinates); None where no chest lies below the neck. Every plane and sphere is
    moved off the voxel centers by ``GRID_SHIFT`` of a pitch, so that no voxel lies on one (where
    rounding, not the shape, would decide: lattice-aligned shapes)."""
    y, d, idx = _grid_centers(sol)
    hd, neck = found.head_depth, found.neck
    blob = found.head[tuple(idx.T)]
    hc = y[blob].mean(axis=0)
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
    ws = d[blob] ** 2
    skull = (ws @ y[blob]) / ws.sum()
    surface = head_surface(_turned(points, sol.frame.T), sol, found, up, eps)
    beyond = skull if found.beyond is None else y[found.beyond[tuple(idx.T)]].mean(axis=0)
    return HeadChest(found, y, d, idx, chest, cc, cov, hc, up, vec[:, 1], lam[1:], skull, surface, eps, beyond)


def front_back_cues(geo, front_back):
    """(3,) the face's offsets along ``front_back`` (module docs, step 5), in units: the centroid
    of the head's surface below the skull's center (jaw, mouth, chin) ahead of that center; the
    whole surface's reach ahead of the center plus its reach behind it (its 98th plus its 2nd
    percentile: nose and chin against the back of the skull); and the centroid of the part beyond
    the neck ahead of the skull's center (a muzzle; 0 where the head was not cut off). The first two are 0 where the head has no
    surface points (below its center)."""
    muzzle = (geo.beyond - geo.skull) @ front_back
    if not len(geo.surface):
        return np.array([0.0, 0.0, muzzle])
    rel = geo.surface - geo.skull
    z, low = rel @ front_back, rel @ geo.up < 0
    return np.array([z[low].mean() if low.any() else 0.0, np.quantile(z, 0.02) + np.quantile(z, 0.98), muzzle])


def mirror_error(points, center, normal):
    """Mean distance (units) from each of the (n, 3) points reflected in the plane through
    ``center`` normal to ``normal`` (any length: its direction) to the nearest of the points: 0 for
    a mirror-symmetric set. InvalidInputError for points not (n, 3) finite with n >= 1 (none: a
    NaN), ``center`` or ``normal`` not (3,) finite (NumPy's broadcast errors), a zero ``normal`` (no
    plane: it read 0, a perfect mirror; a normal of another length reflected off the plane)."""
    points = np.asarray(check_array(points, "points", 1), np.float64)
    center = check_shape(center, "center", (3,), finite=True)
    normal = np.asarray(check_shape(normal, "normal", (3,), finite=True), np.float64)
    top = float(np.max(np.abs(normal)))
    if top > 0 and not 1e-150 < top < 1e150:  # (its norm over- or underflowed: 1e200 read 0, a mirror; 1e-170 zero)
        normal = normal / top
    length = float(np.linalg.norm(normal))
    if not length > 0:
        raise InvalidInputError("normal is zero: no plane to mirror in; give the plane's normal direction")
    normal = normal / length
    reflected = points - 2.0 * ((points - center) @ normal)[:, None] * normal
    return float(cKDTree(points).query(reflected)[0].mean())


def head_mirror(surface, a, b, steps=MIRROR_STEPS):
    """The normal of the best mirror plane of the head's surface (k, 3) through its centroid,
    among the directions cos t a + sin t b (a, b orthonormal, across up), and its contrast.

    Searched over half a turn in ``steps`` steps, then twice within one step of the best (each time
    ``steps // 3`` finer steps). A head is rigid and bilaterally symmetric in every pose: the
    normal is its left-right axis. The contrast (e_perp - e) / e_perp compares the best plane's
    :func:`mirror_error` e with that about the plane at right angles across up (e_perp): 0 where
    the head mirrors as well either way (a ball), near 1 for a clear plane.

    Returns:
      ((3,) unit normal, contrast).
    """
    tree, center = cKDTree(surface), surface.mean(axis=0)
    rel, read = surface - center, {}  # read: angle -> error (a refinement's middle angle and the final best are read before)

    def error(t):
        if t not in read:
            e = np.cos(t) * a + np.sin(t) * b
            read[t] = float(tree.query(surface - 2.0 * (rel @ e)[:, None] * e)[0].mean())
        return read[t]

    angles, step = np.linspace(0.0, np.pi, steps, endpoint=False), np.pi / steps
    for _ in range(3):
        best = angles[int(np.argmin([error(t) for t in angles]))]
        angles = best + np.linspace(-step, step, steps // 3 + 1)
        step = 2.0 * step / (steps // 3)
    e, e_perp = error(best), error(best + 0.5 * np.pi)
    return np.cos(best) * a + np.sin(best) * b, (e_perp - e) / max(e_perp, 1e-300)


def left_right(sol, geo, beyond=None):
    """The left-right axis of the ``head`` frame (module docs, step 3), grid coordinates.

    A body's frame is its head's and its chest's together. The head's own mirror plane
    (:func:`head_mirror`) gives the head's left-right; the one of the chest's two axes across up
    nearest it, the chest's. With ``beyond`` (head depths; :func:`head_frame`: :data:`MIRROR_BEYOND`
    on a point cloud) the head's mirror plane is read from its surface more than that far beyond
    the neck along up (all of it where fewer than 4 points lie there): the closed solid of a point
    cloud fills in the throat, so its neck's saddle lies lower on the neck than the mesh's, and
    the neck below the head, which may turn against it, would tilt the plane. Where the two lie
    within ``TURN`` degrees of each other, left-right is their bisector; where they do not, the
    head is turned against the chest and left-right is
    the one of the chest's two axes whose plane mirrors the depth^``SYMMETRY_POWER`` solid better
    (:func:`symmetry_scores`), as also for a head with fewer than 4 surface points; where those
    two scores are within ``SYMMETRY_MIN`` of each other, no mirror decides, and left-right is the
    chest's wider axis (a person's chest is flatter front to back than across; a habit of one
    build, so :func:`head_frame` flags it).

    Returns:
      ((3,) unit, the head's mirror contrast (0 where it has no surface), True where the head took
      part, False where the body's mirror plane chose, None where neither decided).
    """
    thin = geo.front_back
    wide = np.cross(geo.up, thin)
    w2 = _weights(geo.depth, SYMMETRY_POWER)
    if len(geo.surface) < 4:
        sym = symmetry_scores(sol, np.stack([thin, wide, geo.up]), (w2 @ geo.centers) / w2.sum())
        return (thin if sym[0] >= sym[1] else wide), 0.0, (False if abs(sym[0] - sym[1]) >= SYMMETRY_MIN else None)
    head = geo.surface
    if beyond is not None:
        head = head[(head - geo.parts.neck) @ geo.up > beyond * geo.parts.head_depth]
    normal, contrast = head_mirror(head if len(head) >= 4 else geo.surface, thin, wide)
    near = thin if abs(normal @ thin) >= abs(normal @ wide) else wide
    if np.degrees(np.arccos(min(1.0, abs(normal @ near)))) <= TURN:
        both = normal + np.sign(normal @ near) * near
        return both / np.linalg.norm(both), contrast, True
    sym = symmetry_scores(sol, np.stack([thin, wide, geo.up]), (w2 @ geo.centers) / w2.sum())
    if abs(sym[0] - sym[1]) < SYMMETRY_MIN:  # no mirror decides: the chest's flatter direction is front-back
        return wide, contrast, None
    return (thin if sym[0] >= sym[1] else wide), contrast, False


def head_frame(sol, vertices, faces=None) -> Frame:
    """The ``head`` frame (module docs) of a solid from :func:`.core.frame_solid` and its input.

    Args:
      sol: the solid of :func:`.core.frame_solid` of the input.
      vertices: (n, 3) the input's vertices (a point cloud's points), world coordinates.
      faces: (f, 3) int, a mesh's faces (None for a point cloud): the head's surface is read from
        the vertices and from points on the faces every ``CELL`` pitches
        (:func:`jaxpose.sample.lattice_points`).

    Returns:
      :class:`Frame`: ``eigenvalues`` the chest's second moments along the final axes (units^2);
      ``gaps`` the neck's distinctness (constriction - runner-up) / constriction (1 for a head
      found to end the body, :func:`jaxpose.rotation.parts.find_head`) and the head's mirror contrast (:func:`head_mirror`);
      ``margins`` (neck gap / GAP_MIN, 0, the face's lead in head depths / FACE_MIN); ``mirror`` 1
      (left-right, completed by det); ``symmetry`` the mirror scores about the planes normal to the
      three axes (step 6). A solid with no head, or whose jaw decides and disagrees with the
      surface's reach, gets :func:`core_frame` flagged (ambiguity 1).

    Example:
      >>> v, f = baselines.split_geometry(person)                     # doctest: +SKIP
      >>> head_frame(frame_solid(v, f), v, f).rotation[2]  # back to front, world coordinates  # doctest: +SKIP
    """
    parts.check_solid(sol)
    found = parts.find_head(sol)
    cloud = faces is None
    closed = not cloud and is_closed(np.asarray(faces))
    if found is not None:
        _, _, _, center, bound = _head_reach(sol, found, GRID_SHIFT * sol.pitch)
        points = sample.lattice_points(vertices, _near_faces(sol, vertices, faces, center, bound), CELL * sol.pitch)
        if not cloud and not closed:  # an open mesh: its holes read from the solid's boundary
            points = np.concatenate([points, hole_points(sol, points, near=(center, bound))])
    geo = None if found is None else head_chest(sol, found, points)
    if geo is None:  # no head, or no chest below it: the core frame, flagged (no head vouches for it)
        return core_frame(sol)._replace(ambiguity=1.0)
    # an incomplete surface (a point cloud; a mesh that is not closed): a part found only as an end
    # of the body may be a limb, a tail or a rump where the surface is missing, and on a point
    # cloud's closed solid a head that cannot be cut off may be joined to one: flagged
    settled = not ((cloud or not closed) and found.end_only) and not (cloud and not found.terminal)
    lr, contrast, chosen = left_right(sol, geo, MIRROR_BEYOND if cloud else None)
    # not mirror-symmetric: a hand? Asked of a head found only as an end of the body, and of every
    # head of an open mesh (a hole can fill a neck or cut a part off; the holes are read from the solid)
    if (found.end_only or not (cloud or closed)) and contrast < HEAD_MIRROR:
        return core_frame(sol)._replace(ambiguity=1.0)
    up = geo.up
    fb = np.cross(up, lr)
    fb /= np.linalg.norm(fb)
    jaw, reach, muzzle = front_back_cues(geo, fb)
    held = (geo.beyond - found.neck) @ fb  # the part beyond the neck ahead of the neck that holds it
    settled = settled and chosen is not None  # no mirror chose left-right: flagged
    if abs(muzzle) >= max(abs(jaw), MUZZLE * found.head_depth):  # a snout: it reaches farther than the face hangs
        snout = geo.beyond - geo.skull
        snout -= (snout @ lr) * lr  # in the head's mirror plane
        own = np.cross(lr, snout)  # the head's own up: across its snout, in its mirror plane
        own *= np.sign(own @ up) / np.linalg.norm(own)
        settled = settled and own @ up >= np.cos(np.radians(UP_SPLIT))  # two ups far apart: their bisector is neither
        up = (up + own) / np.linalg.norm(up + own)  # the head's and the chest's together
        fb = np.cross(up, lr)
        fb /= np.linalg.norm(fb)
        muzzle = snout @ fb
        cue, other = muzzle, jaw
    elif (found.beyond is not None and abs(held) >= max(abs(jaw), MUZZLE * found.head_depth)
          and muzzle * held > 0 and abs(muzzle) >= FACE_MIN * found.head_depth):
        cue, other = held, jaw  # a snout read from where the neck holds the head (and ahead of the skull): its sign only
        settled = settled and not (jaw * reach > 0 and jaw * held < 0)  # the face's two readings against it: flagged
    elif jaw * reach > 0:
        cue, other = jaw, muzzle
    elif abs(muzzle) >= FACE_MIN * found.head_depth:  # the face's readings disagree; the part beyond the neck breaks the tie
        cue, other, settled = muzzle, (jaw if jaw * muzzle < 0 else reach), False
    else:  # the face's readings disagree (what was found may not be a head): the core frame
        return core_frame(sol)._replace(ambiguity=1.0)
    fb = fb if cue > 0 else -fb
    axes = np.stack([-up, np.cross(fb, -up), fb])  # axis 0 points to the feet, as the core frame's
    down, fb_w = -up @ sol.frame, fb @ sol.frame
    rot = np.stack([down, np.cross(fb_w, down), fb_w])  # det +1 also where the grid frame is improper
    neck = 1.0 if found.terminal else found.neck_gap
    gaps = np.array([neck, contrast])
    lead = abs(cue) - (abs(other) if cue * other < 0 else 0.0)  # the other reading, where it disagrees, takes from it
    sign = max(lead, 0.0) / found.head_depth / FACE_MIN
    moments = np.einsum("ai,ij,aj->a", axes, geo.cov, axes)
    w2 = _weights(geo.depth, SYMMETRY_POWER)
    sym = symmetry_scores(sol, axes, (w2 @ geo.centers) / w2.sum())
    contrast = sym[1] - max(sym[0], sym[2])  # left-right must be the normal of the body's best mirror plane
    amb = ambiguity(gaps, sign, contrast) if settled else 1.0
    return Frame(rot, amb, moments, gaps, np.array([gaps[0] / GAP_MIN, 0.0, sign]), 1, sym)
