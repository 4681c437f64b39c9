"""One mesh or point cloud: sample its surface, normalize it, and the matrix of its pose.

:func:`normalize_mesh` reads a file or takes a geometry (:mod:`jaxpose.io.mesh`), estimates the
center and scale by name (:mod:`jaxpose.pose.estimators`), optionally the rotation
(:mod:`jaxpose.rotation.rotation`), and returns the transformed copy with its :class:`~jaxpose.Pose`.
File reading and writing live in :mod:`jaxpose.io.mesh`; their names are re-exported here.
"""
from __future__ import annotations


import numpy as np

from . import sample
from ._validate import InvalidInputError, check_gamma, check_int, check_nu, check_real, is_name
from .config import OCSVM, OCSVM_ONLY, PoseConfig
from .geometry import Surface
from .io import mesh as io_mesh
from .io.mesh import MESH_FORMATS, OUTPUT_FORMATS, POINT_FORMATS, encode, example_shape, export, load, output_format, read
from .io.atomic import write_atomic
from .occupancy import solid
from .pose import estimators
from .pose.result import host
from .rotation.rotation import DEFAULT_ROTATION, ROTATIONS, SOLID_FRAMES, frame_of
from .sample import SAMPLING

# its own names, and the names it re-exports: OCSVM_ONLY from jaxpose.config, the file I/O from jaxpose.io.mesh
__all__ = ["SAMPLING", "OCSVM_ONLY", "sample_surface", "normalize_mesh", "check_arguments", "ocsvm_arguments", "pose_matrix", "normalized_points",
           *io_mesh.__all__]


# --------------------------------------------------------------------------- sample
def sample_surface(mesh, count, seed=0, method="even"):
    """Area-weighted points on the surface of a mesh or a file, deterministic per seed.

    :func:`jaxpose.sample.sample_surface` of :func:`load` ``(mesh)``: method "even" (stratified
    per-face counts) or "random"; point clouds give ``count`` of their points.

    mesh : path | Trimesh | PointCloud | (n, 3) array, count : int >= 4, seed : int
    Returns samples : (count, 3) float64

    Example::

        points = sample_surface("body.ply", 2000, seed=0)
    """
    return sample.sample_surface(load(mesh), count, seed=seed, method=method)


# --------------------------------------------------------------------------- normalize
def ocsvm_arguments(gamma=None, nu=None, count=None, seed=None, sampling=None) -> dict:
    """{name: value} of :data:`jaxpose.config.OCSVM_ONLY`, each None replaced by its default in :data:`jaxpose.config.OCSVM`."""
    given = dict(gamma=gamma, nu=nu, count=count, seed=seed, sampling=sampling)
    return {name: getattr(OCSVM, name) if value is None else value for name, value in given.items()}


def check_arguments(gamma=None, nu=None, count=None, seed=None, sampling=None, method=None, *, center=None,
                    scale=None, strict=False, power=None, resolution=None, rotation=False, **options):
    """Check every argument of :func:`normalize_mesh` (same names and defaults) without reading
    anything or compiling: names against the known ones, ranges, which options apply to which
    estimator (``gamma``, ``nu``, ``count``, ``seed``, ``sampling`` given to an estimator and frame
    that are not the OCSVM are refused, as the command line refuses ``--gamma`` ...), and the
    memory of the grid a resolution asks for.

    Returns:
      (center name, scale name, the robust/depth options (``power``; ``resolution``, the robust
      solid's: the estimators' where :func:`jaxpose.pose.estimators.reads_resolution`, else the
      ``head`` or ``core`` frame's alone), the ocsvm options (with the OCSVM grid's ``resolution``),
      the rotation's frame method or None).

    Raises:
      InvalidInputError: the first bad argument, named, with its allowed range.
    """
    given = [name for name, value in zip(OCSVM_ONLY, (gamma, nu, count, seed, sampling)) if value is not None]
    ocsvm = ocsvm_arguments(gamma, nu, count, seed, sampling)
    check_gamma(ocsvm["gamma"])
    check_nu(ocsvm["nu"])
    sample.check_count(ocsvm["count"])  # validated whatever the method
    check_int(ocsvm["seed"], "seed", minimum=0)
    if not is_name(ocsvm["sampling"], SAMPLING):
        raise InvalidInputError(f"unknown sampling {ocsvm['sampling']!r}; valid: {', '.join(SAMPLING)}")
    c_name, s_name = estimators.resolve(method, center, scale)
    estimators.check_strict(strict, c_name, s_name)  # refused where ignored, as the command line's --strict
    uses_ocsvm = "ocsvm" in (c_name, s_name)
    ocsvm_runs = uses_ocsvm or _rotation_name(rotation) == "ocsvm"  # as the center, the scale or the frame
    if not ocsvm_runs:
        estimators.check_ocsvm_unused(given, c_name, s_name, frame=True)
    unknown = sorted(set(options) - set(PoseConfig.FLAT))
    if unknown:
        raise InvalidInputError(
            f"normalize_mesh got unknown argument{'s' if len(unknown) > 1 else ''} {', '.join(unknown)}; its own: "
            f"gamma, nu, count, seed, sampling, method, center, scale, strict, power, resolution, rotation; "
            f"ocsvm options: {', '.join(PoseConfig.FLAT)}"
        )
    if options and not ocsvm_runs:  # (the ocsvm frame reads them too: they reach frame_of)
        raise InvalidInputError(f"options {sorted(options)} apply to the ocsvm estimator only (pass method='ocsvm', "
                                "center or scale 'ocsvm', or rotation='ocsvm'; or leave them out)")
    extra = {}
    frame_name = _rotation_name(rotation)
    if power is not None:
        if c_name not in estimators.POWERED:
            raise InvalidInputError(estimators.power_unread([((c_name, s_name), None)]))
        check_real(power, "power", 0)
        extra["power"] = power
    if resolution is not None:
        if uses_ocsvm:
            options = {**options, "resolution": resolution}
        elif estimators.reads_resolution(c_name, s_name) or frame_name in SOLID_FRAMES:
            extra["resolution"] = solid.check_resolution(resolution)  # the robust solid's: estimators' and frame's
        elif ocsvm_runs:  # the ocsvm frame alone: its option, as the other options reach it
            options = {**options, "resolution": resolution}
        else:
            raise InvalidInputError(estimators.resolution_unread([(c_name, s_name)], ocsvm=True, frame=frame_name))
    if ocsvm_runs:
        PoseConfig.create(**options)  # every option's value and the grid's memory
    return c_name, s_name, extra, options, frame_name


def normalize_mesh(
    mesh_or_path,
    gamma=None,
    nu=None,
    count=None,
    seed=None,
    sampling=None,
    method=None,
    *,
    center=None,
    scale=None,
    strict=False,
    power=None,
    resolution=None,
    rotation=False,
    **options,
):
    """Normalize the position and size (and orientation) of a mesh or point cloud; the input is untouched.

    Args:
      mesh_or_path: a path (anything trimesh reads), Trimesh, PointCloud,
        :class:`~jaxpose.geometry.Surface` or (n, 3) points.
      method: one of :data:`jaxpose.pose.estimators.METHODS`; default ``"robust"``, the depth^p-weighted
        centroid (p: ``power``) of a robust solid and its volume's cube root (works on closed meshes, meshes with
        holes or stray parts, and point clouds; the most consistent under articulation, see
        ``docs/estimators.md``). ``"ocsvm"`` is the paper's method: ``count`` surface samples
        (``seed``, ``sampling``) -> :func:`jaxpose.normalize` (``gamma``, ``nu``, ``options``).
      gamma, nu, count, seed, sampling: the OCSVM's (center, scale or ``rotation="ocsvm"``); None:
        the defaults of :data:`jaxpose.config.OCSVM`. Given when no OCSVM is asked for, they are
        refused (InvalidInputError), not ignored.
      center, scale: choose either part independently (``center="solid_centroid",
        scale="sqrt_area"``; names in :data:`jaxpose.pose.estimators.CENTERS` / ``SCALES``).
      strict: closed-surface estimators raise on an open mesh instead of warning.
      power: depth exponent (robust_depth: ``jaxpose.config.ROBUST.power``; depth_weighted_solid: 2).
      resolution: for the robust solid, voxels along the body's largest extent (96); for
        ``ocsvm``, the grid resolution of :func:`jaxpose.normalize` (64). It is the center's and
        scale's, and the frame's where it builds their grid (``head`` and ``core`` with the robust
        solid); where the center and scale read none (``vertex_mean``, ``solid``) it is the
        frame's alone: the ``head`` and ``core`` frames' robust solid, the ``ocsvm`` frame's grid
        (as the other OCSVM options reach that frame). With an ``ocsvm`` center or scale the
        ``head`` and ``core`` frames run at their default (96 voxels, a robust solid, not the
        OCSVM's grid), and with the robust one the ``ocsvm`` frame at the OCSVM's (64).
      rotation: False (default: translation and scale only, exactly as without the option), True
        (the ``head`` frame of :mod:`jaxpose.rotation.head`: the head and chest of the robust solid, or
        its depth^4-weighted ``core`` frame, flagged, where no neck is found; meshes and point clouds) or a
        name of :data:`jaxpose.rotation.rotation.ROTATIONS` (``head``, ``core``, ``ocsvm``,
        ``pca_vertices``, ``pca_surface``, ``inertia``). Sets ``Pose.rotation`` (rows =
        canonical axes, det +1) and ``Pose.ambiguity`` / ``Pose.flagged``; the center and scale
        are the same as without it.

    Returns:
      normalized: a transformed copy (Trimesh or PointCloud; a Surface for a Surface), pose:
      :class:`jaxpose.Pose` (its center in float64, exact under translation:
      :func:`jaxpose.pose.estimators.centered`).

    Raises:
      InvalidInputError: any bad argument (named, with its range), before the file is read; an
        unreadable file; a mesh with no area.
      JaxposeError: no valid pose (for ``ocsvm`` with the reason of :mod:`jaxpose.pose.validity`; for
        ``robust`` a shape that encloses no volume).

    Example::

        mesh, pose = jaxpose.normalize_mesh("body.ply")              # robust default
        mesh, pose = jaxpose.normalize_mesh("body.ply", method="ocsvm")
    """
    c_name, s_name, extra, options, frame_name = check_arguments(
        gamma, nu, count, seed, sampling, method, center=center, scale=scale, strict=strict, power=power,
        resolution=resolution, rotation=rotation, **options)
    ocsvm = ocsvm_arguments(gamma, nu, count, seed, sampling)
    geometry = load(mesh_or_path)
    # each estimator gets the options it reads, the OCSVM's with their defaults filled in (estimate and
    # frame_of refuse the others, as check_arguments refuses them given where no OCSVM runs)
    fit = {"ocsvm": options, **ocsvm} if "ocsvm" in (c_name, s_name) else {}
    # a resolution for the frame's robust solid alone (center and scale read none) is the frame's
    own = {k: v for k, v in extra.items() if k != "resolution" or estimators.reads_resolution(c_name, s_name)}
    pose = estimators.estimate(geometry, method, center=center, scale=scale, strict=strict, **fit, **own)
    if frame_name is not None:
        frame = ({"ocsvm": {**ocsvm, "options": options}} if frame_name == "ocsvm" else
                 {"resolution": extra.get("resolution")} if frame_name in SOLID_FRAMES else {})
        found = frame_of(estimators.centered(geometry)[0], frame_name, **frame)
        pose = pose._replace(ambiguity=np.asarray(found.ambiguity, np.float64),
                             rotation=np.asarray(found.rotation, np.float64))
    return _transformed(geometry, pose), pose


def normalized_points(points, pose):
    """R (x - center) / scale of points (n, 3) in float64 on the host: ``host(pose).apply``
    (:meth:`jaxpose.Pose.apply`; x - center first, which is exact far from the origin, where a
    4 x 4 matrix would round x / scale first). What :func:`normalize_mesh` writes.

    Args:
      points: (n, 3) coordinates; pose: a concrete :class:`jaxpose.Pose`.

    Returns:
      (n, 3) float64.
    """
    return host(pose).apply(np.asarray(points, np.float64))


def _transformed(geometry, pose):
    """A copy of the geometry with vertices :func:`normalized_points`."""
    if isinstance(geometry, Surface):
        return Surface(normalized_points(geometry.vertices, pose), geometry.faces)
    normalized = geometry.copy()
    normalized.vertices = normalized_points(geometry.vertices, pose)
    return normalized


def _rotation_name(rotation):
    """None (no rotation), or the frame method a ``rotation=`` argument names."""
    if rotation is None or isinstance(rotation, (bool, np.bool_)):
        return DEFAULT_ROTATION if rotation else None
    if isinstance(rotation, str) and rotation in ROTATIONS:
        return rotation
    raise InvalidInputError(f"rotation must be True, False or one of {', '.join(ROTATIONS)}; got {rotation!r}")


def pose_matrix(pose):
    """The 4 x 4 matrix of a concrete pose, in float64 on the host: ``host(pose).matrix``
    (:attr:`jaxpose.Pose.matrix` of x -> R (x - center) / scale; meshes are transformed, and
    transforms reported, in float64 whatever JAX's default precision).

    Returns matrix : (4, 4) float64
    """
    return host(pose).matrix
