"""Named estimators of a shape's center and scale, for meshes and point clouds, one interface.

A method is a (center, scale) pair; the two can also be chosen independently
(``estimate(mesh, center="solid_centroid", scale="sqrt_area")``).

The default, ``"robust"``, is the depth^p-weighted centroid of a robust solid and the cube root of
that solid's volume (:mod:`jaxpose.occupancy.solid`): the solid is found with or without a closed surface
(holes are capped and voted over by rays along 3 axes; point clouds are closed morphologically),
stray parts separated from the body are dropped, and each voxel weighs its depth to the outside to
the power p (:data:`jaxpose.config.ROBUST`), so the deep part of the shape (a body's torso), which
moves least under articulation, sets the center. The volume is nearly invariant under articulation of
soft bodies. See ``docs/estimators.md`` for the measurements behind the choice. The solid is built on the host
(NumPy) for meshes and for concrete point clouds alike, and so are its depth, weights and moments
(:func:`solid_center_volume`: scipy's exact distance transform, then the functions of
:mod:`jaxpose.weighted` that :func:`jaxpose.moments.robust_moments` runs in JAX): the robust
estimator of a concrete input needs no JAX. The pure-JAX point-cloud solid of
:func:`jaxpose.normalize` (``jaxpose.occupancy.points``) computes the same solid (tested against
this one) for traced, vmapped and differentiated inputs; :func:`jaxpose.moments.solid_moments`
differentiates a host solid's moments in the power.

``"ocsvm"`` is the paper's method (:func:`jaxpose.normalize` on ``count`` surface samples), the
only one differentiable in (gamma, nu). The others are the classical baselines of
:mod:`jaxpose.baselines`.

Every estimator runs on a copy of the input moved by one of its own vertices (:func:`centered`):
the move is exact in float64 (a difference of nearby floats), so results are equivariant under
translation to the last digit the output can hold, wherever the shape sits.
"""
from __future__ import annotations

import time
import warnings

import numpy as np
from scipy import ndimage

from .. import _validate, baselines, sample
from ..occupancy import solid, voxels
from .._validate import InvalidInputError, InvalidPoseWarning, JaxposeError, is_name
from ..config import OCSVM, ROBUST, PoseConfig
from ..geometry import Surface, surface_labels, triangle_areas
from ..host import anchor
from ..weighted import depth_power_weights, grid_axes, solid_occupancy, weighted_center
from .result import MIN_POINT_VOXELS, SECOND_BODY, Pose, host, status_message

__all__ = ["METHODS", "CENTERS", "SCALES", "DEFAULT_METHOD", "ROBUST_POWER", "POWERED", "default_power", "method_key",
           "CLOSED_FORMS", "resolve",
           "parse_method", "check_strict", "strict_unread", "estimate",
           "estimate_many", "robust_center_scale", "solid_center_volume", "centered", "check_ocsvm_unused"]

METHODS = {
    "robust": ("robust_depth", "robust_volume"),
    "ocsvm": ("ocsvm", "ocsvm"),
    "surface_centroid": ("surface_centroid", "mean_distance"),
    "vertex_mean": ("vertex_mean", "mean_distance"),
    "bbox": ("bbox_center", "unit_cube"),
    "min_ball": ("min_ball", "unit_sphere"),
    "solid": ("solid_centroid", "gyration_radius"),
    "solid_sqrt_area": ("solid_centroid", "sqrt_area"),
    "depth_weighted_solid": ("depth_weighted_solid", "sqrt_area"),
}
DEFAULT_METHOD = "robust"
CENTERS = ("robust_depth", "ocsvm") + baselines.CENTERS
SCALES = ("robust_volume", "ocsvm") + baselines.SCALES
ROBUST_POWER = ROBUST.power  # depth exponent of the robust center (jaxpose.config.ROBUST)
_OCSVM_KEYS = ("gamma", "nu", "count", "seed", "sampling")


def resolve(method=None, center=None, scale=None):
    """The (center, scale) names of a method and/or explicit choices; validated.

    ``method`` (default ``"robust"``) gives both; ``center`` / ``scale`` replace either. Raises
    InvalidInputError naming an unknown name.
    """
    if method is not None and not is_name(method, METHODS):
        name, colon, power = str(method).partition(":")
        hint = (f" (the 'name:power' form is evaluate's; here pass method={name!r}, power={power})"
                if colon and name in METHODS else "")
        raise InvalidInputError(f"unknown method {method!r}; valid: {', '.join(METHODS)}{hint}")
    c, s = METHODS[method or DEFAULT_METHOD]
    c = c if center is None or (isinstance(center, str) and not center) else center
    s = s if scale is None or (isinstance(scale, str) and not scale) else scale
    if not is_name(c, CENTERS):  # (an array: NumPy's "truth value of an array" ValueError)
        raise InvalidInputError(f"unknown center {c!r}; valid: {', '.join(CENTERS)}")
    if not is_name(s, SCALES):
        raise InvalidInputError(f"unknown scale {s!r}; valid: {', '.join(SCALES)}")
    return c, s


POWERED = ("robust_depth", "depth_weighted_solid")  # the centers whose depth weights take a power


def default_power(center, options=None):
    """The depth power a :data:`POWERED` center runs at where its method's name gives none: the
    ``"power"`` of ``options`` where given, else the center's own, :data:`ROBUST_POWER` (4) for
    ``robust_depth`` and :data:`jaxpose.occupancy.voxels.DEPTH_POWER` (2) for
    ``depth_weighted_solid``. None for a center without depth weights."""
    if center not in POWERED:
        return None
    if options and options.get("power") is not None:  # (a NaN, a bool or 1e400: refused by name)
        return _validate.check_real(options["power"], "power", 0)
    return ROBUST_POWER if center == "robust_depth" else voxels.DEPTH_POWER


def method_key(spec, options=None):
    """The method ``spec`` (``"name"`` or ``"name:p"``, :func:`parse_method`) as it runs, telling two
    spellings of one method apart: its name, and for a depth-weighted center the power it runs at
    (:func:`default_power` where none is given): ``"robust"``, ``"robust:4"`` and ``"robust:4.0"``
    are all ``"robust at power 4"``; with ``options={"power": 3}``, ``"robust"`` is ``"robust at
    power 3"``. Powers are compared exactly (``4`` and ``4.000001`` are two methods).

    Raises:
      InvalidInputError: as :func:`parse_method`: an unknown name or a bad power.

    Example:
      >>> method_key("robust"), method_key("depth_weighted_solid:2.0"), method_key("bbox")
      ('robust at power 4', 'depth_weighted_solid at power 2', 'bbox')
    """
    name, power = parse_method(spec)
    power = default_power(METHODS[name][0], options) if power is None else power
    if power is None:  # (no power to compare)
        return name
    text = repr(float(power) + 0.0)  # (the shortest text that reads back as this float: 4.0, 2.5, 1e-05; -0 is 0)
    return f"{name} at power {text[:-2] if text.endswith('.0') else text}"
CLOSED_FORMS = ("solid_centroid", "gyration_radius", "depth_weighted_solid")  # what strict=True applies to


def check_strict(strict, c_name, s_name):
    """``strict`` checked (a bool) and refused where neither estimator reads it: only the
    closed-surface ones (:data:`CLOSED_FORMS`) refuse an open mesh, so ``strict=True`` with
    another center and scale would do nothing (as the command line's ``--strict`` is refused).

    Raises:
      InvalidInputError: not a bool, or ``True`` for estimators that ignore it
        (:func:`strict_unread`'s wording).
    """
    strict = _validate.check_bool(strict, "strict")
    if strict and not set(CLOSED_FORMS) & {c_name, s_name}:
        raise InvalidInputError(strict_unread([(c_name, s_name)]))
    return strict


def strict_unread(pairs, methods=None, name="strict"):
    """The one wording of ``strict=True`` refused where no closed-surface estimator reads it
    (:func:`check_strict`, :func:`estimate`, :func:`estimate_many`, ``jaxpose normalize --strict``
    with ``name="--strict"``): ``pairs`` the (center, scale) names chosen, ``methods`` the names of
    several methods (:func:`estimate_many`'s) or None. Returns the message."""
    return (f"{name} applies to the closed-surface estimators ({', '.join(CLOSED_FORMS)}), which "
            f"{_chosen(pairs, methods)}; leave it out")


def power_unread(parsed, methods=None):
    """The one wording of a ``power`` refused where no depth-weighted center (:data:`POWERED`) takes
    it (:func:`estimate`, :func:`estimate_many`, :func:`jaxpose.normalize_mesh`): ``parsed``
    (((center, scale), the power of ``"name:p"`` or None), ...), ``methods`` as
    :func:`strict_unread`'s. A method whose center takes a power of its own (``"robust:2"``) is
    named as replacing it, the others as not using it. Returns the message."""
    if methods is None:
        return f"power applies to the {' and '.join(POWERED)} centers, which {_chosen([parsed[0][0]])}; leave it out"
    own = [m for m, ((c_name, _), key) in zip(methods, parsed) if c_name in POWERED and key is not None]
    unused = [m for m, ((c_name, _), _key) in zip(methods, parsed) if c_name not in POWERED]
    parts = [_chosen(None, unused)] if unused else []
    if own:
        parts.append(f"the method {own[0]} replaces with its own" if len(own) == 1 else
                     f"the methods {', '.join(own)} replace with their own")
    return (f"power applies to the {' and '.join(POWERED)} centers where a method gives none as 'name:p', which "
            f"{' and '.join(parts)}; leave it out")


def reads_resolution(c_name, s_name):
    """Whether the center ``c_name`` or the scale ``s_name`` builds the robust solid, whose
    ``resolution`` it reads (the ``robust_depth`` center, the ``robust_volume`` scale)."""
    return c_name == "robust_depth" or s_name == "robust_volume"


def resolution_unread(pairs, methods=None, ocsvm=False, frame=None):
    """The one wording of a ``resolution`` refused where no estimator reads it: the robust solid's
    (the robust_depth center, the robust_volume scale), and with ``ocsvm`` (:func:`jaxpose.normalize_mesh`,
    where it is also the core and head frames' solid's and the OCSVM grid's) those; ``pairs``, ``methods`` as
    :func:`strict_unread`'s; ``frame``: the rotation's frame method, named beside the estimators where
    one is chosen (it reads none either). Returns the message."""
    also = ", the core and head frames, and the ocsvm estimator and frame" if ocsvm else ""
    hint = "leave it out" if ocsvm else "for ocsvm give it in ocsvm={'resolution': ...}"
    return (f"resolution applies to the robust solid (the robust_depth center, the robust_volume scale){also}, "
            f"which {_chosen(pairs, methods, frame)}; {hint}")


def _chosen(pairs, methods=None, frame=None):
    """How a refusal names the estimators that do not use an option: one (center, scale) pair (and
    the rotation's ``frame`` method, if any), or ``methods``, with the verb."""
    if methods is None:
        (c_name, s_name), = pairs
        also = f" and the {frame} frame" if frame else ""
        return f"the chosen estimators (center {c_name}, scale {s_name}){also} do not use"
    return f"the method {methods[0]} does not use" if len(methods) == 1 else \
        f"the methods {', '.join(methods)} do not use"


def parse_method(spec):
    """A method with an optional depth power, ``"name"`` or ``"name:p"`` (``"robust:2"``), as
    (name, p or None); p a finite number >= 0, given only to a method whose center is depth
    weighted (:data:`POWERED`).

    Raises:
      InvalidInputError: an unknown name, a power that is not such a number, or a power given to a
        method that has none (it was ignored: ``vertex_mean:2`` measured the vertex mean).
    """
    name, colon, power = str(spec).partition(":")
    if name not in METHODS:
        raise InvalidInputError(f"unknown method {spec!r}; valid: {', '.join(METHODS)} (optionally name:power)")
    if not colon:
        return name, None
    try:
        value = float(power)
    except ValueError:
        raise InvalidInputError(f"method {spec!r}: the power after ':' must be a number") from None
    _validate.check_real(value, f"method {spec!r}: the power after ':'", 0)
    if METHODS[name][0] not in POWERED:
        powered = ", ".join(m for m, (c, _) in METHODS.items() if c in POWERED)
        raise InvalidInputError(f"method {spec!r}: {name} takes no power (its center has no depth weights); "
                                f"a power goes with {powered}")
    return name, value


def centered(geometry):
    """A copy of a mesh or point cloud translated so that its vertex nearest the middle of its
    bounding box sits at the origin, and that vertex.

    Args:
      geometry: Trimesh, :class:`~jaxpose.geometry.Surface`, PointCloud or (n, 3) points.

    Returns:
      moved: Trimesh (same faces, ``process=False``), a Surface for a Surface, or PointCloud, in
      float64; shift (3,) float64 with ``moved.vertices == vertices - shift``. Far from the origin the subtraction is exact
      (Sterbenz), so ``shift`` plus a result computed on ``moved`` keeps every digit.

    Raises:
      InvalidInputError: bad vertices or faces; a mesh whose faces have no area.
    """
    vertices, faces = baselines.split_geometry(geometry)
    shift = anchor(vertices)
    moved = vertices - shift
    if isinstance(geometry, Surface):  # (no trimesh object where none was given)
        return Surface(moved, faces), shift
    import trimesh

    if faces is None:
        return trimesh.PointCloud(moved), shift
    return trimesh.Trimesh(moved, faces, process=False), shift


def robust_center_scale(geometry, power=ROBUST_POWER, resolution=solid.RESOLUTION):
    """The robust center and scale (module docs) of a mesh or point cloud.

    Args:
      geometry: Trimesh, PointCloud or (n, 3) points.
      power: depth exponent p >= 0 of the center's weights.
      resolution: voxels along the main body's largest extent (>= 8).

    Returns:
      center (3,) float64 = sum_v d_v^p x_v / sum_v d_v^p over the kept voxels, scale () =
      V^(1/3), both in the input's units, and the :class:`jaxpose.occupancy.solid.Solid` (its ``depth``
      None: the depth is taken in JAX).

    Raises:
      JaxposeError: the shape has no robust pose, with the reason: it encloses no volume (a flat
        sheet), or none its grid resolves (no voxel deeper than the surface layer: a sheet, or a body
        thin against its largest extent), it is mostly open (hole caps would add more than :data:`MAX_CAP_SHARE` of its
        area, flat sheets apart from the body left out; where those sheets cut the body off its
        grid, saying so), it is several separate bodies of equal size (:data:`EQUAL_BODIES`), a point cloud
        too sparse for a closing (its solid under :data:`MIN_POINT_VOXELS` voxels across; where points
        far from the body, not the spacing, set the voxel, saying so), a point
        cloud of several separate bodies (a second part of at least :data:`SECOND_BODY` of the
        largest, :func:`jaxpose.occupancy.solid.linked_parts`).
    """
    sol = _robust_solid(geometry, resolution)
    center, volume = solid_center_volume(sol, power)
    return center, volume ** (1.0 / 3.0), sol


_OTHER = "use the surface_centroid or ocsvm method (method='surface_centroid'; on the command line --method " \
         "surface_centroid)"


def _robust_solid(geometry, resolution):
    """The robust solid, or a JaxposeError saying why the shape has no robust pose (the edges of
    the estimator, checked here at its boundary: no volume, :data:`MAX_CAP_SHARE`,
    :data:`EQUAL_BODIES`, :data:`MIN_POINT_VOXELS`)."""
    resolution = solid.check_resolution(resolution)
    vertices, faces = baselines.split_geometry(geometry)
    capped = None if faces is None else solid.cap_holes(vertices, faces)
    sol = solid.robust_solid(vertices, faces, resolution=resolution, with_depth=False, capped=capped)
    if not sol.inside.any():
        _no_resolved_volume(sol, resolution)
    if faces is not None:
        _check_mostly_closed(faces, *capped, sol)
    if faces is not None:  # a point cloud's closing can break thin parts into pieces of any size
        _check_one_body(sol)
    else:
        idx = np.nonzero(sol.inside)
        across = max(int(i.max() - i.min()) + 1 for i in idx)
        if across < MIN_POINT_VOXELS and _stretched(vertices, sol):
            raise JaxposeError(f"the point cloud's solid spans {across} voxels (at least {MIN_POINT_VOXELS} are needed): "
                               f"its grid, {resolution} voxels across, spans the points its first pass kept, "
                               f"{_spread(vertices, sol):.3g} times the solid's extent, so points apart from the body (a "
                               "stray point or cluster far away), not its spacing, set the voxel; remove them, or use "
                               "the vertex_mean or ocsvm method")
        if across < MIN_POINT_VOXELS:
            raise JaxposeError(f"the point cloud is too sparse for a closing: at the voxel size its spacing allows "
                               f"(the 90th percentile of the 4-neighbour distance / {solid.MAX_CLOSING}) its solid "
                               f"spans {across} voxels (at least {MIN_POINT_VOXELS} are needed); use more points, or "
                               "the vertex_mean or ocsvm method")
        _check_one_cloud(sol)
    if not ndimage.binary_erosion(sol.inside).any():  # the point pipeline's EMPTY_SOLID rule (erode6)
        _no_resolved_volume(sol, resolution)
    return sol


def _no_resolved_volume(sol, resolution):
    """Raise the JaxposeError of a robust solid that is empty or nowhere deeper than its surface
    layer (every voxel has a face neighbour outside): its volume and depth would be the voxels'."""
    raise JaxposeError(f"the shape encloses no volume its grid resolves: its robust solid is "
                       f"{'nowhere deeper than its surface layer (every voxel has a face neighbour outside)' if sol.inside.any() else 'empty'} "
                       f"at {resolution} voxels along the body's largest extent ({sol.pitch:.3g} units each): a flat "
                       f"or open sheet, a scan of one side, or a body thin against its extent (a long spike or wire "
                       f"sets the grid); raise resolution, or {_OTHER}")


def _stretched(points, sol):
    """Whether a point solid's voxel is finer than the points' spacing asks (the 90th percentile
    of the 4-neighbour distance / ``MAX_CLOSING``, :func:`jaxpose.occupancy.solid.robust_solid`'s
    floor), so that the grid's extent, not the spacing, set it."""
    gap = solid.neighbour_distances(np.asarray(points, np.float64), 4, samples=solid.SPACING_SAMPLES)[:, 3]
    return sol.pitch > float(np.quantile(gap, 0.9)) / solid.MAX_CLOSING * (1 + 1e-9)


def _spread(points, sol):
    """How many times the kept solid's largest extent the points within the grid spread."""
    inside = np.nonzero(sol.inside)
    solid_extent = max(int(i.max() - i.min()) + 1 for i in inside) * sol.pitch
    x = np.asarray(points, np.float64) @ np.asarray(sol.frame).T
    upper = sol.origin + sol.pitch * np.asarray(sol.inside.shape)
    x = x[np.all((x >= sol.origin) & (x <= upper), axis=1)]
    return float((x.max(0) - x.min(0)).max()) / solid_extent


MAX_CAP_SHARE = 0.6  # meshes: closing the holes may add at most this share of the surface's own area
EQUAL_BODIES = 0.1  # separate bodies whose sizes (voxels) differ by less than this share are equal


def _check_mostly_closed(faces, capped, caps, sol=None):
    """Refuse a mesh whose hole caps (``capped, caps = jaxpose.occupancy.solid.cap_holes(vertices,
    faces)``) would make much of its solid: an open sheet, a bowl-less scan; small holes (a few %
    to a third of the area) pass. Separate surfaces that enclose no volume with their caps (a flat
    sheet: a floor under a scanned body, a stray plane; :func:`_open_share` at the voxel of ``sol``,
    the robust solid) make none of the solid, capped or not, and are left out of the share; where
    they are left out, the solid must lie inside its grid (one that reaches the grid's edge was cut
    off by a box the sheets misled: refused, saying so)."""
    faces = np.asarray(faces, np.int64)
    if len(caps) == 0:
        return
    share = float(triangle_areas(capped[caps]).sum() / max(triangle_areas(capped[faces]).sum(), 1e-300))
    if share > MAX_CAP_SHARE and sol is not None:
        rest, sheets = _open_share(faces, capped, caps, sol.pitch)
        if rest <= MAX_CAP_SHARE and solid.reaches_edge(sol.inside):
            raise JaxposeError(f"the mesh holds flat sheets apart from its body ({100 * sheets:.0f} % of its area: a "
                               "floor, a stray plane), and the robust solid's box, found among them, cuts the body "
                               f"off (its solid reaches the edge of its grid); remove the sheets, or {_OTHER}")
        share = rest
    if share > MAX_CAP_SHARE:
        raise JaxposeError(f"the mesh is mostly open (a sheet, or a scan of one side): closing its holes would add "
                           f"{100 * share:.0f} % of its own area (at most {100 * MAX_CAP_SHARE:.0f} %), so the caps, "
                           f"not the shape, would make the robust solid; {_OTHER}")


def _open_share(faces, capped, caps, pitch):
    """The caps' share of the area of a mesh (as :func:`_check_mostly_closed`'s) without its flat
    sheets: each face-connected surface with its own caps closes a volume V (the divergence
    theorem) and has an area A (faces and caps); one with 2 V / A, its mean thickness, under one
    voxel (``pitch``) holds on average less than one layer of voxel centers: it is a sheet that
    makes no solid (a flat sheet and its cap close none), and its faces and caps are left out.
    Where every surface is such a sheet, the share over all of them. Returns (share, the sheets'
    share of the faces' area)."""
    tri = np.vstack([faces, caps])
    k, lab = surface_labels(len(capped), tri)
    part = lab[tri[:, 0]]
    t = capped[tri]
    t = t - np.stack([np.bincount(lab, capped[:, a], minlength=k) / np.maximum(np.bincount(lab, minlength=k), 1)
                      for a in range(3)], axis=1)[part][:, None, :]  # from each surface's own vertex mean
    volume = np.abs(np.bincount(part, np.einsum("ij,ij->i", t[:, 0], np.cross(t[:, 1], t[:, 2])) / 6.0, minlength=k))
    area = triangle_areas(capped[tri])
    is_cap = np.arange(len(tri)) >= len(faces)
    total = np.bincount(part, area, minlength=k)
    solid_part = 2.0 * volume >= pitch * total
    if not solid_part.any():
        solid_part[:] = True
    keep = solid_part[part]
    faces_area = max(area[~is_cap].sum(), 1e-300)
    return (float(area[keep & is_cap].sum() / max(area[keep & ~is_cap].sum(), 1e-300)),
            float(area[~keep & ~is_cap].sum() / faces_area))


def _check_one_cloud(sol):
    """Refuse a point cloud of several separate bodies: a part apart from the largest holds at
    least :data:`SECOND_BODY` of its occupied voxels (:func:`jaxpose.occupancy.solid.linked_parts`,
    a dilation of the points, so a thin limb that the closing cuts off stays linked). Stray
    parts smaller than that pass (they are dropped, or kept with the body as for meshes)."""
    sizes = solid.linked_parts(sol.occupied, sol.radius)
    if len(sizes) >= 2 and sizes[1] >= SECOND_BODY * sizes[0]:
        several = int(np.sum(sizes >= SECOND_BODY * sizes[0]))
        raise JaxposeError(f"the point cloud is {several} separate bodies: apart from the largest, "
                           f"{'a part holds' if several == 2 else 'parts hold'} {100 * sizes[1] / sizes[0]:.0f} % of "
                           f"its occupied voxels (at least {100 * SECOND_BODY:.0f} %): no single body sets the pose; "
                           "normalize each body on its own, or, if it is one body sampled too sparsely for its "
                           "parts to link (a few points per part, such as the corners of a model built from boxes), "
                           "sample its surface densely or use the vertex_mean or ocsvm method (method='vertex_mean'; on the "
                           "command line --method vertex_mean)")


def _check_one_body(sol):
    """Refuse a mesh solid of several separate bodies of equal size (within :data:`EQUAL_BODIES`): no
    single body sets the pose, and which one leads flips with a small change of either. Bodies
    of different sizes pass (a stray part is dropped; a comparable part is kept with the body)."""
    if sol.components - sol.dropped < 2:
        return
    labels, n = ndimage.label(sol.inside, structure=np.ones((3, 3, 3), bool))
    sizes = np.sort(np.bincount(labels.ravel())[1:])[::-1]
    if n >= 2 and sizes[1] >= (1 - EQUAL_BODIES) * sizes[0]:
        equal = int(np.sum(sizes >= (1 - EQUAL_BODIES) * sizes[0]))
        raise JaxposeError(f"the shape is {equal} separate bodies of equal size (within {100 * EQUAL_BODIES:.0f} %): "
                           f"no single body sets the pose; normalize each body on its own, or {_OTHER}")


def solid_center_volume(sol, power=ROBUST_POWER):
    """The depth^p-weighted center (3,) float64 NumPy, in world units, and the volume (float) of a
    host :class:`jaxpose.occupancy.solid.Solid`, computed on the host in float64 without JAX.

    The pipeline of :func:`jaxpose.moments.robust_moments` on the host's backend: scipy's exact
    distance transform (``scipy.ndimage.distance_transform_edt``, which
    :func:`jaxpose.depth.distance` equals), then the same
    :func:`jaxpose.weighted.depth_power_weights`, :func:`jaxpose.weighted.solid_occupancy` and
    weighted center of the cell centers (:func:`jaxpose.weighted.grid_axes`), on the box of the
    solid plus one cell (:func:`_crop`: the same distances, fewer cells), taken from the grid's
    middle and mapped to the world (``sol.origin``, ``sol.pitch``, ``sol.frame``). Use
    :func:`jaxpose.moments.solid_moments` for a derivative in ``power``.

    Raises:
      InvalidInputError: a power that is not a finite number >= 0; ``sol`` no Solid
        (:func:`jaxpose.occupancy.solid.check_solid`; was an AttributeError), or one with no voxel
        inside (no center: its center was a number of no voxel beside a volume 0).
    """
    solid.check_solid(sol)
    _validate.check_real(power, "power", 0)
    inside = np.asarray(sol.inside, bool)
    if inside.ndim != 3 or not inside.any():
        raise InvalidInputError(f"sol has no voxel inside (its inside is {inside.shape}, {int(inside.sum())} voxels "
                                "set): an empty solid has no center; robust_center_scale says why a shape has none")
    occupied = np.zeros_like(inside) if sol.occupied is None else np.asarray(sol.occupied, bool)
    crop = _crop(inside)
    inside, occupied = inside[crop], occupied[crop]
    w = depth_power_weights(ndimage.distance_transform_edt(inside), inside, float(power), float(sol.bias))
    half = _HALF * np.asarray(sol.inside.shape, np.float64)
    corner = np.asarray([s.start for s in crop], np.float64) - half  # the crop's corner, from the grid's middle
    _, center = weighted_center(grid_axes(inside.shape, corner, 1.0, np.float64), w)
    volume = float(np.sum(solid_occupancy(inside, occupied, np.float64)))
    center = sol.origin + sol.pitch * (center + half)
    return center @ np.asarray(sol.frame, np.float64), volume * sol.pitch**3


_HALF = 0.5  # the moments are taken from the grid's middle (smaller numbers, as in jaxpose.moments.solid_moments)


def _crop(inside):
    """Slices of the box of the True cells of a grid plus one cell on each side (within the grid):
    the distance transform of the crop equals the grid's on every True cell (a False cell outside
    the crop is never nearer than the crop's own border layer, which is all False), and every
    other cell weighs 0."""
    if not inside.any():
        return tuple(slice(0, n) for n in inside.shape)
    crop = []
    for axis, n in enumerate(inside.shape):
        cells = np.flatnonzero(inside.any(axis=tuple(b for b in range(inside.ndim) if b != axis)))
        crop.append(slice(max(int(cells[0]) - 1, 0), min(int(cells[-1]) + 2, n)))
    return tuple(crop)


_SHARED = ("_robust_solid", "_ocsvm", "_voxels", "_moments")  # what does not depend on the power


class _Shape:
    """One input with the intermediate results that several estimators share, computed once."""

    def __init__(self, geometry, options):
        self.geometry = geometry
        self.options = options
        self._robust_solid = None
        self._ocsvm = None
        self._voxels = None
        self._moments = None
        self._robust = None

    def robust(self):
        """World center and volume of the robust solid at this shape's power."""
        if self._robust is None:
            sol = self.robust_solid()
            self._robust = solid_center_volume(sol, default_power("robust_depth", self.options))
        return self._robust

    def solid_moments(self, strict):
        if self._moments is None:
            self._moments = baselines.solid_moments(self.geometry, strict)
        return self._moments

    def robust_solid(self):
        if self._robust_solid is None:
            self._robust_solid = _robust_solid(self.geometry, self.options.get("resolution", solid.RESOLUTION))
        return self._robust_solid

    def ocsvm(self):
        if self._ocsvm is None:
            from .pose import normalize  # JAX: imported only by the estimators that use it
            o = self.options
            points = sample.sample_surface(self.geometry, o.get("count", OCSVM.count), seed=o.get("seed", OCSVM.seed),
                                           method=o.get("sampling", OCSVM.sampling))
            with warnings.catch_warnings():  # an invalid pose is raised below, with its reason
                warnings.simplefilter("ignore", InvalidPoseWarning)
                pose = normalize(points, method="ocsvm", gamma=o.get("gamma", OCSVM.gamma), nu=o.get("nu", OCSVM.nu), **o.get("ocsvm", {}))
            if not bool(np.asarray(pose.valid)):
                raise JaxposeError(f"the ocsvm estimator gave no valid pose: {status_message(pose.status)}")
            self._ocsvm = pose
        return self._ocsvm

    def center(self, name, strict):
        """The center of one name: a shared computation of this shape, or a baseline's closed form."""
        own = _SHAPE_CENTERS.get(name)
        return own(self, strict) if own else baselines.center(self.geometry, name)

    def scale(self, name, center, strict):
        """The scale of one name about `center`: a shared computation, or a baseline's closed form."""
        own = _SHAPE_SCALES.get(name)
        return own(self, center, strict) if own else baselines.scale(self.geometry, name, center=center)

    def depth_weighted_center(self, strict):
        if self._voxels is None:
            self._voxels = voxels.filled_voxels(self.geometry, strict=strict)
        x, d = self._voxels
        return voxels.weighted_centroid(x, d ** float(default_power("depth_weighted_solid", self.options)))

    def gyration_radius(self, center, strict):
        _, c, second = self.solid_moments(strict)
        return float(np.sqrt(np.trace(second) + np.sum((np.asarray(center) - c) ** 2)))


# the centers and scales that share this shape's intermediate results: name -> (shape, [center,] strict) -> value;
# every other name is a closed form of jaxpose.baselines
_SHAPE_CENTERS = {
    "robust_depth": lambda shape, strict: shape.robust()[0],
    "ocsvm": lambda shape, strict: np.asarray(shape.ocsvm().center, np.float64),
    "solid_centroid": lambda shape, strict: shape.solid_moments(strict)[1],
    "depth_weighted_solid": _Shape.depth_weighted_center,
}
_SHAPE_SCALES = {
    "robust_volume": lambda shape, center, strict: shape.robust()[1] ** (1.0 / 3.0),
    "ocsvm": lambda shape, center, strict: float(np.asarray(shape.ocsvm().scale)),
    "gyration_radius": _Shape.gyration_radius,
}


def estimate(geometry, method=None, *, center=None, scale=None, strict=False, **options):
    """Center and scale of a mesh or point cloud by name, as a :class:`jaxpose.Pose`.

    Args:
      geometry: Trimesh, PointCloud or (n, 3) points (already loaded).
      method: one of :data:`METHODS` (default ``"robust"``).
      center, scale: override either part (names in :data:`CENTERS`, :data:`SCALES`).
      strict: closed-surface estimators (``solid_centroid``, ``gyration_radius``,
        ``depth_weighted_solid``) raise on an open mesh instead of warning.
      options: ``power`` (depth exponent: robust_depth ``ROBUST.power``, depth_weighted_solid 2), ``resolution``
        (robust solid voxels, 96); for ``ocsvm``: ``gamma``, ``nu``, ``count``, ``seed``,
        ``sampling`` and ``ocsvm`` (a dict of :func:`jaxpose.normalize` options).

    Returns:
      Pose (center (3,), scale ()), in the input's units: the scales of different methods are
      different sizes (a mean distance, a volume's cube root, an extent), consistent within a method.

    Raises:
      InvalidInputError: unknown names or options, an option's bad value (before any work), an
        option the chosen estimators do not read (it would be ignored): a ``power`` for a center
        without depth weights, a ``resolution`` for estimators without a robust solid,
        ``strict=True`` for estimators that are not closed-surface ones, ``gamma``, ``nu``,
        ``count``, ``seed``, ``sampling`` or ``ocsvm`` where neither the center nor the scale is
        ``ocsvm`` (:func:`check_ocsvm_unused`); a surface estimator on points.
      JaxposeError: no valid pose (e.g. a shape that encloses no volume for ``robust``).
    """
    c_name, s_name = resolve(method, center, scale)
    _check_options(options)
    strict = _validate.check_bool(strict, "strict")
    _check_read(strict, options, [((c_name, s_name), None)])
    moved, shift = centered(geometry)
    return _shifted(_pose(_Shape(moved, options), c_name, s_name, strict), shift)


def check_ocsvm_unused(given, c_name, s_name, frame=False):
    """Refuse the OCSVM's options ``given`` (names: ``gamma``, ``nu``, ``count``, ``seed``,
    ``sampling``, ``ocsvm``) where no OCSVM reads them, center ``c_name`` and scale ``s_name`` not
    ``"ocsvm"`` (and, with ``frame``, no ``rotation="ocsvm"``): InvalidInputError naming them, the
    one wording of :func:`estimate`, :func:`estimate_many` and :func:`jaxpose.normalize_mesh` (they
    were ignored: the estimator named ran with nothing of them). Nothing given: returns None."""
    where = "method='ocsvm', center or scale 'ocsvm', or rotation='ocsvm'" if frame else \
        "method='ocsvm', or center or scale 'ocsvm'"
    _refuse_ocsvm_unused(given, _chosen([(c_name, s_name)]), where)


def check_ocsvm_unread(given, methods, where):
    """:func:`check_ocsvm_unused` for a list of ``methods`` (names, none of them an OCSVM one), the
    refusal of :func:`estimate_many` and :func:`jaxpose.evaluation.evaluate`: InvalidInputError
    naming the options ``given`` and the methods, ``where`` saying how the OCSVM would read them.
    Nothing given: returns None."""
    _refuse_ocsvm_unused(given, _chosen(None, methods), where)


def _refuse_ocsvm_unused(given, chosen, where):
    if not given:
        return
    many = len(given) > 1
    raise InvalidInputError(
        f"{', '.join(given)} {'are options' if many else 'is an option'} of the ocsvm estimator, which {chosen} "
        f"(pass {where}; or leave {'them' if many else 'it'} out)")


def _check_read(strict, options, parsed, methods=None):
    """Refuse what none of the estimators ``parsed`` (((center, scale), power of ``"name:p"`` or
    None), ...) reads: ``strict=True`` without a closed-surface estimator, a ``power`` without a
    depth-weighted center (that takes no ``"name:p"`` of its own), a ``resolution`` without the robust
    solid, the OCSVM's options without an ``ocsvm`` center or scale. One rule and wording for
    :func:`estimate` (one pair) and :func:`estimate_many` (its ``methods``)."""
    pairs = [pair for pair, _ in parsed]
    chosen = _chosen(pairs, methods)
    if strict and not any(set(CLOSED_FORMS) & set(pair) for pair in pairs):
        raise InvalidInputError(strict_unread(pairs, methods))
    if "power" in options and not any(c_name in POWERED and key is None for (c_name, _), key in parsed):
        raise InvalidInputError(power_unread(parsed, methods))
    if "resolution" in options and not any(reads_resolution(*pair) for pair in pairs):
        raise InvalidInputError(resolution_unread(pairs, methods))
    if not any("ocsvm" in pair for pair in pairs):
        given = [k for k in (*_OCSVM_KEYS, "ocsvm") if k in options]
        if methods is None:
            _refuse_ocsvm_unused(given, chosen, "method='ocsvm', or center or scale 'ocsvm'")
        else:
            check_ocsvm_unread(given, methods, "'ocsvm' among the methods")


def _check_options(options):
    """The options' names and values, before any work (a bad value was an error of each method that
    read it, or none where no method read it: gamma=-1 with bbox, ocsvm=5)."""
    _validate.check_known(options, ("power", "resolution", "ocsvm", *_OCSVM_KEYS))
    if "power" in options:
        _validate.check_real(options["power"], "power", 0)
    if "resolution" in options:
        solid.check_resolution(options["resolution"])
    sample.check_fit_values(options)
    if "ocsvm" in options:
        if not isinstance(options["ocsvm"], dict):
            raise InvalidInputError(f"ocsvm must be a dict of jaxpose.normalize's ocsvm options, got {options['ocsvm']!r:.80}")
        PoseConfig.create(**options["ocsvm"])  # names and values


def _shifted(pose, shift):
    """The pose of a geometry moved by -shift, for the geometry itself, as a host pose (NumPy
    fields, floats float64: :func:`jaxpose.pose.result.host`, whatever the method)."""
    return host(pose)._replace(center=np.asarray(pose.center, np.float64) + shift)


def _pose(shape, c_name, s_name, strict):
    c = np.asarray(shape.center(c_name, strict), np.float64)
    s = float(shape.scale(s_name, c, strict))
    if c_name == s_name == "ocsvm":
        pose = shape.ocsvm()
    else:
        pose = Pose.from_center_scale(c, s)
    if not bool(np.all(np.asarray(pose.valid))):
        raise JaxposeError(f"{c_name} / {s_name} gave no valid pose (center {c}, scale {s})")
    return pose


def estimate_many(geometry, methods, strict=False, timings=False, **options):
    """Several methods on one input, sharing what they have in common (the robust solid, the
    voxels of the depth-weighted solid, the OCSVM fit).

    Args:
      geometry: as :func:`estimate`; methods: names of :data:`METHODS`, each optionally with a depth
        power as ``"name:p"`` (``"depth_weighted_solid:4"``, :func:`parse_method`); strict, options:
        as :func:`estimate`.

      timings: also return each method's seconds (shared work counted where first done).

    Returns:
      {method: Pose, or the JaxposeError it raised (e.g. a surface estimator on points)}, with
      ``timings`` {method: (that, seconds)}.

    Raises:
      InvalidInputError: as :func:`estimate`, before any work: unknown names or options, a method
        named twice (two spellings of one method alike: ``"robust"``, ``"robust:4"``, ``"robust:4.0"``;
        :func:`method_key`), a bad value, ``strict=True``, a ``power``, a ``resolution`` or an OCSVM option (``gamma``, ``nu``,
        ``count``, ``seed``, ``sampling``, ``ocsvm``) that none of the methods reads.
    """
    _check_options(options)
    strict, timings = _validate.check_bool(strict, "strict"), _validate.check_bool(timings, "timings")
    methods = _validate.check_names(methods, "methods", key=lambda spec: method_key(spec, options))  # each once
    parsed = [(resolve(name), key) for name, key in map(parse_method, methods)]  # every name before any work
    _check_read(strict, options, parsed, methods)
    geometry, shift = centered(geometry)
    shapes, out = {}, {}
    for spec in methods:
        name, key = parse_method(spec)
        c_name, s_name = resolve(name)
        if key not in shapes:  # one shared input per power (the solids do not depend on it)
            base = next(iter(shapes.values()), None)
            shapes[key] = shape = _Shape(geometry, options if key is None else {**options, "power": key})
            if base is not None:
                for attr in _SHARED:
                    setattr(shape, attr, getattr(base, attr))
        start = time.perf_counter()
        try:
            out[spec] = _shifted(_pose(shapes[key], c_name, s_name, strict), shift)
        except JaxposeError as exc:
            out[spec] = exc
        if timings:
            out[spec] = (out[spec], time.perf_counter() - start)
        for other in shapes.values():  # share what was computed
            for attr in _SHARED:
                if getattr(other, attr) is None:
                    setattr(other, attr, getattr(shapes[key], attr))
    return out
