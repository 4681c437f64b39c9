"""Procedural 12-class deformation dataset, an open equivalent of the paper's (sec. 4.1).

Each class is one reference object assembled from trimesh primitives as a tree of named
parts: a rigid *core* (never touched) and movable parts hanging from joints. Instance 0 is
the reference; the others are made from it by non-rigid changes only, in proportions like
the paper's (per 10 instances: 5 articulations, 2 extrusions, 1 outlying part added,
1 part removed):

* articulation: 2-4 parts (with their children) rotated by 25-60 degrees about their joint;
* extrusion: a part stretched 1.3-1.6 times along its direction from its joint;
* outlier added: a small detached ball (radius 0.07) beside the body; outlier removed: a leg, a finger... .

No similarity transform is applied, so all instances of a class share the pose of their rigid
core: its vertices come first in every mesh and are identical across the class
(``mesh.metadata["core_vertex_count"]`` of them). Every class is scaled once, from its
reference, so that the reference's bounding box is centred at the origin with largest extent 1.
Meshes are plain concatenations of overlapping primitives (no boolean operations).

Objects are generated, never stored: deterministic per ``(seed, class, instance)``.
The parts and primitives live in ``_parts``, the 12 reference builders in ``_classes``.
"""
from __future__ import annotations

import dataclasses
import functools

import numpy as np
import trimesh

from jaxpose._validate import InvalidInputError, check_int, check_names
from jaxpose.config import check_instances
from jaxpose.datasets._classes import BUILDERS as _BUILDERS
from jaxpose.datasets._classes import CLASSES
from jaxpose.datasets._parts import ball_part, Part

__all__ = ["CLASSES", "DEFORMATIONS", "make_object", "make_dataset"]

# deformation of instances 1..9 (instance 0 is the reference; later ones are drawn at random)
DEFORMATIONS = ("articulation",) * 5 + ("extrusion",) * 2 + ("outlier_added", "outlier_removed")

_ANGLES = (25.0, 60.0)  # degrees, articulation magnitude
_STRETCH = (1.3, 1.6)  # extrusion factor
_OUTLIER_RADIUS = 0.07  # relative to the reference's largest extent
_OUTLIER_GAP = 0.12
_EDGE = 0.05  # longest edge of a reference's parts after subdivision, relative to its largest extent


# ---------------------------------------------------------------- the references, scaled
def _bounds(parts):
    """(lo, hi): the bounding box of all the parts' vertices, (3,) each."""
    vertices = np.concatenate([p.vertices for p in parts])
    return vertices.min(0), vertices.max(0)


@functools.lru_cache(maxsize=None)
def _reference(class_name):
    """Parts of a class's reference, mapped to a centred box with largest extent 1.

    Every part's triangles are split until no edge is longer than ``_EDGE``, so that the
    vertices sample each surface densely (a box is not only its 8 corners), as a scan's do.
    """
    parts = _BUILDERS[class_name]()
    lo, hi = _bounds(parts)
    center, scale = (lo + hi) / 2.0, 1.0 / float(np.max(hi - lo))

    def fit(x):
        return None if x is None else (x - center) * scale

    def dense(part):
        vertices, faces = trimesh.remesh.subdivide_to_size(fit(part.vertices), part.faces, max_edge=_EDGE)
        return dataclasses.replace(part, vertices=vertices, faces=np.asarray(faces, np.int64), joint=fit(part.joint))

    return tuple(dense(p) for p in parts)


# ---------------------------------------------------------------- deformations
def _descendants(parts, name):
    """Names of `name` and all parts hanging from it."""
    out, frontier = {name}, [name]
    while frontier:
        children = [p.name for p in parts if p.parent in frontier and p.name not in out]
        out.update(children)
        frontier = children
    return out


def _direction(part):
    d = part.vertices.mean(0) - part.joint
    n = np.linalg.norm(d)
    return d / n if n > 1e-12 else np.array([0.0, 0.0, 1.0])


def _rotation(axis, angle):
    return trimesh.transformations.rotation_matrix(angle, axis)[:3, :3]


def _articulate(parts, rng):
    movable = [i for i, p in enumerate(parts) if not p.core]
    chosen = sorted(rng.choice(movable, size=min(len(movable), int(rng.integers(2, 5))), replace=False))
    names = []
    for i in chosen:  # parents come before children in the part list
        part = parts[i]
        if part.angles is not None:
            angle = rng.uniform(*part.angles)
        else:
            angle = rng.uniform(*_ANGLES) * rng.choice((-1.0, 1.0))
        axis = part.axis
        if axis is None:  # random hinge perpendicular to the part
            d = _direction(part)
            axis = np.cross(d, rng.normal(size=3))
            axis /= np.linalg.norm(axis)
        rot, pivot = _rotation(axis, np.radians(angle)), part.joint
        moved = _descendants(parts, part.name)
        parts = [dataclasses.replace(q, vertices=(q.vertices - pivot) @ rot.T + pivot,
                                     joint=(q.joint - pivot) @ rot.T + pivot,
                                     axis=q.axis if q.axis is None else rot @ q.axis)
                 if q.name in moved else q for q in parts]
        names.append(f"{part.name} {angle:+.0f}deg")
    return parts, "articulation: " + ", ".join(names)


def _extrude(parts, rng):
    movable = [p for p in parts if not p.core]
    reach = [float(np.max(np.linalg.norm(p.vertices - p.joint, axis=1))) for p in movable]
    movable = [p for p, r in zip(movable, reach) if r >= 0.5 * max(reach)]  # no ears or pegs
    part = movable[int(rng.integers(len(movable)))]
    factor = rng.uniform(*_STRETCH)
    d, pivot = _direction(part), part.joint

    def stretch(x):
        return x + (factor - 1.0) * ((x - pivot) @ d)[..., None] * d

    below = _descendants(parts, part.name) - {part.name}
    out = []
    for q in parts:
        if q.name == part.name:
            q = dataclasses.replace(q, vertices=stretch(q.vertices))
        elif q.name in below:  # children ride along with the stretched tip
            shift = stretch(q.joint) - q.joint
            q = dataclasses.replace(q, vertices=q.vertices + shift, joint=q.joint + shift)
        out.append(q)
    return out, f"extrusion: {part.name} x{factor:.2f}"


def _add_outlier(parts, rng):
    lo, hi = _bounds(parts)
    theta = rng.uniform(0.0, 2.0 * np.pi)
    u = np.array([np.cos(theta), np.sin(theta), 0.0])
    half = (hi - lo) / 2.0
    reach = min(half[i] / abs(u[i]) for i in range(2) if abs(u[i]) > 1e-9)  # to the box side
    height = rng.uniform(0.0, 1.0)
    center = (lo + hi) / 2.0 + (reach + _OUTLIER_GAP) * u
    center[2] = lo[2] + height * (hi[2] - lo[2])
    ball = ball_part(center, _OUTLIER_RADIUS)
    extra = Part("outlier", np.asarray(ball.vertices, float), np.asarray(ball.faces, np.int64),
                  joint=center, removable=True)
    return [*parts, extra], "outlier added"


def _remove_part(parts, rng):
    removable = [p for p in parts if p.removable]
    if not removable:
        return _add_outlier(parts, rng)
    part = removable[int(rng.integers(len(removable)))]
    gone = _descendants(parts, part.name)
    return [p for p in parts if p.name not in gone], f"outlier removed: {part.name}"


_APPLY = {"articulation": _articulate, "extrusion": _extrude,
          "outlier_added": _add_outlier, "outlier_removed": _remove_part}


def _check_class(class_name):
    if class_name not in _BUILDERS:
        raise InvalidInputError(f"unknown class {class_name!r}; expected one of {', '.join(CLASSES)}")


def make_object(class_name: str, instance: int, seed: int = 0) -> trimesh.Trimesh:
    """One object of the procedural dataset.

    Parameters
    ----------
    class_name : one of :data:`CLASSES`
    instance : int >= 0; 0 is the class's reference, 1..9 follow :data:`DEFORMATIONS`,
        later ones draw a deformation at random (articulations 60%, extrusions 20%, outliers 20%).
    seed : int >= 0; deformations (chosen parts, angles, factors) are drawn from
        ``numpy.random.default_rng([seed, class index, instance])``.

    Returns
    -------
    mesh : trimesh.Trimesh, not processed (parts overlap; vertices are not merged), with
        ``metadata``: ``class_name``, ``instance``, ``deformation`` (a description) and
        ``core_vertex_count`` (the first vertices, identical within the class).
    """
    _check_class(class_name)
    instance = check_int(instance, "instance", 0)
    seed = check_int(seed, "seed", 0)
    parts = list(_reference(class_name))
    rng = np.random.default_rng([seed, CLASSES.index(class_name), instance])
    if instance == 0:
        kind, description = None, "reference"
    else:
        if instance <= len(DEFORMATIONS):
            kind = DEFORMATIONS[instance - 1]
        else:
            kind = str(rng.choice(list(_APPLY), p=[0.6, 0.2, 0.1, 0.1]))
        parts, description = _APPLY[kind](parts, rng)
    offsets = np.cumsum([0] + [len(p.vertices) for p in parts])
    vertices = np.concatenate([p.vertices for p in parts])
    faces = np.concatenate([p.faces + o for p, o in zip(parts, offsets)])
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    mesh.metadata.update(class_name=class_name, instance=instance, deformation=description,
                         core_vertex_count=int(sum(len(p.vertices) for p in parts if p.core)))
    return mesh


def make_dataset(seed: int = 0, instances: int = 10, classes=None) -> dict[str, list[trimesh.Trimesh]]:
    """``{class_name: [instance 0, ..., instance instances-1]}`` for `classes` (default: all 12).

    Raises:
      InvalidInputError: an unknown class, one named twice, none, `instances` below 1 or above
        :data:`jaxpose.config.DATASET_INSTANCES` (the dataset is built in memory), a bad `seed`.
    """
    classes = CLASSES if classes is None else check_names(classes, "classes")
    if not classes:  # (an empty dict was returned)
        raise InvalidInputError(f"classes names no class; give some of {', '.join(CLASSES)}, or None for all")
    for name in classes:
        _check_class(name)
    instances = check_instances(instances, "instances", 1)  # (at most config.DATASET_INSTANCES: built in memory)
    seed = check_int(seed, "seed", 0)  # before any object is built
    return {name: [make_object(name, i, seed) for i in range(instances)] for name in classes}

