"""Canonical axes of a shape: a rotation that holds under articulation, and every frame by name.

A frame (:class:`jaxpose.orientation.Frame`) is a proper rotation R (3, 3) whose rows are the
shape's canonical axes in world coordinates (det R = +1); canonical coordinates are
R (x - c) / s. :func:`frame_of` gives any of :data:`ROTATIONS` by name: ``core`` and ``head``
(:mod:`jaxpose.rotation.core` and :mod:`jaxpose.rotation.head`, each with its steps; their names
re-exported here), ``ocsvm`` (:func:`jaxpose.orientation.region_frame`, through
:func:`jaxpose.normalize`) and the baselines of :mod:`jaxpose.baselines`. The sign rule's pieces, the ambiguity and its thresholds
are in :mod:`jaxpose.orientation` (re-exported here).

How the ``head`` and ``core`` frames do on real bodies, and when to prefer which:
docs/rotation.md.
"""
from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from .. import baselines, sample
from .._validate import InvalidInputError, JaxposeError, check_known, is_name
from ..config import OCSVM
from ..occupancy import solid
from ..orientation import (GAP_MIN, SIGN_MIN, SYMMETRY_MIN, Frame, ambiguity, complete_signs, proper, region_frame,
                           relative_gaps)
from .core import (AXES_POWER, FEET_DEPTH, FOOT, FOOT_MIN, OFF_SOLID, SYMMETRY_POWER, core_frame, feet_offset, frame_solid,
                   pre_frame, symmetry_scores)
from .head import (CELL, CHEST, CHEST_POWER, FACE, FACE_MIN, GAP, HEAD_MIRROR, MIRROR_BEYOND, MIRROR_STEPS, MUZZLE, TURN,
                   UP_SPLIT, HeadChest, front_back_cues, head_chest, head_frame, head_mirror, head_surface, hole_points,
                   left_right, mirror_error)

__all__ = ["Frame", "ROTATIONS", "SOLID_FRAMES", "DEFAULT_ROTATION", "GAP_MIN", "SIGN_MIN", "SYMMETRY_MIN", "FOOT", "FEET_DEPTH",
           "FOOT_MIN", "AXES_POWER", "SYMMETRY_POWER", "CHEST", "CHEST_POWER", "FACE", "CELL", "FACE_MIN",
           "MUZZLE", "TURN", "HEAD_MIRROR", "UP_SPLIT", "MIRROR_STEPS", "MIRROR_BEYOND", "GAP", "hole_points", "mirror_error", "head_mirror", "left_right", "pre_frame", "frame_solid",
           "core_frame", "HeadChest", "head_chest", "head_surface", "front_back_cues",
           "head_frame", "feet_offset", "symmetry_scores", "ambiguity", "complete_signs", "frame_of", "region_frame",
           "proper", "check_frame_options", "OCSVM_FRAME_KEYS"]

ROTATIONS = ("core", "head", "ocsvm", "pca_vertices", "pca_surface", "inertia")
SOLID_FRAMES = ("core", "head")  # the frames of the robust solid: they read its resolution
DEFAULT_ROTATION = "head"  # rotation=True: the head frame, the core frame (flagged) where no head is found
OCSVM_FRAME_KEYS = ("gamma", "nu", "count", "seed", "sampling", "options")  # frame_of's ocsvm dict


def check_frame_options(resolution=None, ocsvm=None):
    """:func:`frame_of`'s ``resolution`` (None or :func:`jaxpose.occupancy.solid.check_resolution`'s)
    and ``ocsvm`` (None or a dict of :data:`OCSVM_FRAME_KEYS`, their values checked; ``options`` a
    dict, checked by :func:`jaxpose.normalize`, without ``gamma``, ``nu`` and ``points``: the dict's own
    keys and the samples), as (resolution, ocsvm); InvalidInputError naming the first bad one (a
    misspelt key was ignored: the default ran)."""
    if resolution is not None:
        resolution = solid.check_resolution(resolution)
    if ocsvm is None:
        return resolution, None
    if not isinstance(ocsvm, Mapping):
        raise InvalidInputError(f"ocsvm must be a dict of {', '.join(OCSVM_FRAME_KEYS)}, got {ocsvm!r:.80}")
    check_known(ocsvm, OCSVM_FRAME_KEYS, "ocsvm key", repr)
    sample.check_fit_values(ocsvm)
    options = ocsvm.get("options", {})
    if not isinstance(options, Mapping):
        raise InvalidInputError(f"ocsvm['options'] must be a dict of jaxpose.normalize's ocsvm options, got "
                                f"{options!r:.80}")
    # what frame_of passes itself (was frame_ocsvm's TypeError 'got multiple values for keyword argument')
    own = [key for key in ("gamma", "nu", "points") if key in options]
    if own:
        where = "the points are sampled from the geometry" if own[0] == "points" else f"give it as ocsvm[{own[0]!r}]"
        raise InvalidInputError(f"ocsvm['options'] must not hold {own[0]!r}: {where} (options are "
                                "jaxpose.normalize's other ocsvm options)")
    return resolution, dict(ocsvm)


# ------------------------------------------------------------------ dispatch (host)
def frame_of(geometry, method=DEFAULT_ROTATION, *, resolution=None, sol=None, ocsvm=None) -> Frame:
    """The canonical frame of a mesh or point cloud by name (one of :data:`ROTATIONS`).

    Args:
      geometry: Trimesh, PointCloud or (n, 3) points.
      method: ``head`` (default; ``core``, flagged, where it finds no neck), ``core``, ``ocsvm`` or a baseline of
        :mod:`jaxpose.baselines`
        (``pca_vertices``, ``pca_surface``: a point cloud's points; ``inertia``: meshes only).
      resolution: voxels of the robust solid along the body's largest extent (``core``, ``head``).
      sol: a solid from :func:`frame_solid` to reuse (``core``, ``head``; instead of ``resolution``).
      ocsvm: for ``ocsvm``, a dict of ``gamma``, ``nu``, ``count``, ``seed``, ``sampling`` and
        ``options`` (of :func:`jaxpose.normalize`).

      Each option is for the frames named; given to another frame it is refused, not ignored.

    Returns:
      :class:`Frame` (rotation in the input's world coordinates). ``ocsvm``: the rotation and
      ambiguity of :func:`jaxpose.normalize` (``rotation=True``) of the samples; the OCSVM region's
      eigenvalues (input units^2), their gaps, the sign margins |E[z^3] / r^3| / ``SIGN_MIN`` (0 on
      ``mirror``, the axis det completed), no mirror scores (NaN); eigenvalues, gaps and margins
      NaN and mirror -1 (not reported) where the frame was not finite (the identity, ambiguity 1).

    Raises:
      InvalidInputError: an unknown method, a bad resolution or ``ocsvm`` (:func:`check_frame_options`),
        an option the method does not read (it would be ignored): ``resolution`` or ``sol`` for a
        frame other than ``core`` and ``head``, ``ocsvm`` for a frame other than ``ocsvm``, a
        ``resolution`` beside a ``sol``.
    """
    if not is_name(method, ROTATIONS):
        raise InvalidInputError(f"unknown rotation {method!r}; valid: {', '.join(ROTATIONS)}")
    checked = check_frame_options(resolution, ocsvm)  # values first, as estimate's
    _check_read(method, resolution=resolution, sol=sol, ocsvm=ocsvm)
    resolution, ocsvm = checked
    if method in SOLID_FRAMES:
        if sol is None or method == "head":
            vertices, faces = baselines.split_geometry(geometry)
        if sol is None:
            sol = frame_solid(vertices, faces, resolution)
        solid.check_solid(sol, depth=True)  # (a sol that is no Solid: AttributeError on sol.inside)
        if not sol.inside.any():
            raise JaxposeError(f"the shape encloses no volume: the {method} frame is undefined; "
                               "use rotation='pca_surface' or 'ocsvm'")
        return core_frame(sol) if method == "core" else head_frame(sol, vertices, faces)
    if method == "ocsvm":
        from ..pose.pose import frame_ocsvm  # JAX only when asked for

        o = dict(ocsvm or {})
        points = sample.sample_surface(geometry, o.get("count", OCSVM.count), seed=o.get("seed", OCSVM.seed),
                                       method=o.get("sampling", OCSVM.sampling))
        pose, found = frame_ocsvm(points, gamma=o.get("gamma", OCSVM.gamma), nu=o.get("nu", OCSVM.nu),
                                  **o.get("options", {}))
        return _region_frame(pose, found)
    return baselines.frame(geometry, method)


_READERS = {"resolution": SOLID_FRAMES, "sol": SOLID_FRAMES, "ocsvm": ("ocsvm",)}  # frame_of's options


def _check_read(method, **given):
    """Refuse an option of :func:`frame_of` (not None) that the frame ``method`` does not read
    (:data:`_READERS`; a ``resolution`` beside a ``sol``, whose grid is its own): InvalidInputError
    naming it (it was ignored: the frame ran without it)."""
    unread = [name for name, value in given.items() if value is not None and method not in _READERS[name]]
    if unread:
        name = unread[0]
        raise InvalidInputError(f"{name} is an option of the {' and '.join(_READERS[name])} frame"
                                f"{'s' if len(_READERS[name]) > 1 else ''}; rotation {method!r} does not read it "
                                f"(leave it out)")
    if given["resolution"] is not None and given["sol"] is not None:
        raise InvalidInputError("give resolution or sol, not both: a solid's grid is its own (frame_solid(vertices, "
                                "faces, resolution) builds one at a resolution)")


def _region_frame(pose, found):
    """The ``ocsvm`` :class:`Frame` of :func:`jaxpose.pose.pose.frame_ocsvm`'s (pose, diagnostics):
    normalize's rotation and ambiguity as they are; the region's eigenvalues (input units^2), their
    :func:`relative_gaps`, the sign margins |E[z^3] / r^3| / ``SIGN_MIN`` (0 on the axis det
    completed) and that axis; NaN and mirror -1 where the frame fell back to the identity (not
    finite). No mirror scores (NaN)."""
    rot, amb = np.asarray(pose.rotation, np.float64), float(np.asarray(pose.ambiguity))
    if not found["ok"]:
        return Frame(rot, amb, np.full(3, np.nan), np.full(2, np.nan), np.full(3, np.nan), -1, np.full(3, np.nan))
    k = found["completed"]
    margins = np.abs(found["stat"]) / SIGN_MIN
    margins[k] = 0.0
    lam = found["eigenvalues"]
    return Frame(rot, amb, lam, relative_gaps(lam), margins, k, np.full(3, np.nan))
