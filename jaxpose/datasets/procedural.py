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
"""
from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
import trimesh

from jaxpose._validate import InvalidInputError

__all__ = ["CLASSES", "DEFORMATIONS", "make_object", "make_dataset"]

CLASSES = (
    "human", "dolphin", "chair", "tree", "pot", "desktop_computer",
    "hand", "dog", "guitar", "piano", "spider", "horse",
)
# deformation of instances 1..9 (instance 0 is the reference; later ones are drawn at random)
DEFORMATIONS = ("articulation",) * 5 + ("extrusion",) * 2 + ("outlier_added", "outlier_removed")

_ANGLES = (25.0, 60.0)  # degrees, articulation magnitude
_STRETCH = (1.3, 1.6)  # extrusion factor
_OUTLIER_RADIUS = 0.07  # relative to the reference's largest extent
_OUTLIER_GAP = 0.12


@dataclass(frozen=True)
class _Part:
    name: str
    vertices: np.ndarray  # (n, 3) float, reference coordinates
    faces: np.ndarray  # (k, 3) int, local indices
    parent: str | None = None  # articulated parts move their children with them
    joint: np.ndarray | None = None  # pivot; None for core parts
    axis: np.ndarray | None = None  # hinge axis; None: random, perpendicular to the part
    angles: tuple[float, float] | None = None  # signed range (degrees) for hinged parts
    removable: bool = False

    @property
    def core(self) -> bool:
        return self.joint is None


# ---------------------------------------------------------------- primitives
def _segment_transform(a, b):
    a, b = np.asarray(a, float), np.asarray(b, float)
    d = b - a
    length = float(np.linalg.norm(d))
    matrix = trimesh.geometry.align_vectors([0.0, 0.0, 1.0], d / length)
    matrix[:3, 3] = (a + b) / 2.0
    return length, matrix


def _seg(a, b, r):
    """Capsule from a to b."""
    length, matrix = _segment_transform(a, b)
    return trimesh.creation.capsule(height=length, radius=r, count=[10, 10], transform=matrix)


def _rod(a, b, r):
    """Closed cylinder from a to b."""
    return trimesh.creation.cylinder(radius=r, segment=[a, b], sections=14)


def _cone(base, tip, r):
    length, matrix = _segment_transform(base, tip)
    matrix[:3, 3] = base
    return trimesh.creation.cone(radius=r, height=length, sections=14, transform=matrix)


def _box(center, extents):
    return trimesh.creation.box(extents=extents, transform=trimesh.transformations.translation_matrix(center))


def _ball(center, radii):
    mesh = trimesh.creation.icosphere(subdivisions=2)
    mesh.vertices = mesh.vertices * np.broadcast_to(np.asarray(radii, float), (3,)) + np.asarray(center, float)
    return mesh


def _revolve(profile, base=(0.0, 0.0, 0.0)):
    """Surface of revolution about +z of a (radius, height) profile."""
    mesh = trimesh.creation.revolve(np.asarray(profile, float), sections=24)
    mesh.vertices = mesh.vertices + np.asarray(base, float)
    return mesh


class _Body:
    """Builder of a part list (core parts first)."""

    def __init__(self):
        self.parts: list[_Part] = []

    def add(self, name, *meshes, parent=None, joint=None, axis=None, angles=None, removable=False):
        mesh = trimesh.util.concatenate(list(meshes)) if len(meshes) > 1 else meshes[0]
        self.parts.append(_Part(
            name, np.asarray(mesh.vertices, float), np.asarray(mesh.faces, np.int64), parent,
            None if joint is None else np.asarray(joint, float),
            None if axis is None else np.asarray(axis, float) / np.linalg.norm(axis),
            angles, removable,
        ))
        return self

    def core(self, name, *meshes):
        return self.add(name, *meshes)

    def done(self):
        return tuple(sorted(self.parts, key=lambda p: not p.core))  # stable: core first


# ---------------------------------------------------------------- the 12 references
def _human():
    b = _Body().core("pelvis", _ball((0, 0, 0.95), (0.11, 0.17, 0.1)))
    b.core("torso", _ball((0, 0, 1.22), (0.11, 0.19, 0.27)))
    b.add("head", _rod((0, 0, 1.44), (0, 0, 1.56), 0.05), _ball((0, 0, 1.66), (0.1, 0.09, 0.12)),
          joint=(0, 0, 1.46))
    for s, side in ((1, "left"), (-1, "right")):
        b.add(f"{side}_upper_arm", _seg((0, s * 0.23, 1.4), (0, s * 0.26, 1.12), 0.045),
              joint=(0, s * 0.23, 1.4), removable=True)
        b.add(f"{side}_forearm", _seg((0, s * 0.26, 1.12), (0, s * 0.28, 0.86), 0.04),
              _ball((0, s * 0.28, 0.8), (0.03, 0.03, 0.06)), parent=f"{side}_upper_arm",
              joint=(0, s * 0.26, 1.12))
        b.add(f"{side}_thigh", _seg((0, s * 0.1, 0.9), (0, s * 0.11, 0.5), 0.07),
              joint=(0, s * 0.1, 0.9), removable=True)
        b.add(f"{side}_shin", _seg((0, s * 0.11, 0.5), (0, s * 0.11, 0.1), 0.055),
              _box((0.05, s * 0.11, 0.04), (0.22, 0.09, 0.06)), parent=f"{side}_thigh",
              joint=(0, s * 0.11, 0.5))
    return b.done()


def _dolphin():
    b = _Body().core("body", _ball((0, 0, 0), (0.9, 0.22, 0.25)))
    b.add("snout", _seg((0.82, 0, -0.03), (1.15, 0, -0.06), 0.05), joint=(0.82, 0, -0.03))
    b.add("tail", _seg((-0.75, 0, 0), (-1.25, 0, 0.05), 0.09), joint=(-0.75, 0, 0))
    b.add("flukes", _ball((-1.33, 0, 0.05), (0.12, 0.3, 0.03)), parent="tail",
          joint=(-1.25, 0, 0.05), removable=True)
    b.add("dorsal_fin", _cone((0, 0, 0.2), (-0.15, 0, 0.45), 0.1), joint=(0, 0, 0.2), removable=True)
    for s, side in ((1, "left"), (-1, "right")):
        b.add(f"{side}_fin", _ball((0.3, s * 0.3, -0.15), (0.12, 0.12, 0.025)),
              joint=(0.35, s * 0.18, -0.1), removable=True)
    return b.done()


def _chair():
    b = _Body().core("seat", _box((0, 0, 0.45), (0.45, 0.45, 0.05)))
    b.add("backrest", _box((-0.21, 0, 0.75), (0.04, 0.45, 0.55)), joint=(-0.21, 0, 0.475),
          axis=(0, 1, 0), angles=(-35.0, 20.0))
    for x in (0.2, -0.2):
        for y in (0.2, -0.2):
            b.add(f"leg_{x:+.1f}_{y:+.1f}", _rod((x, y, 0.43), (x, y, 0.0), 0.02),
                  joint=(x, y, 0.43), removable=True)
    for s, side in ((1, "left"), (-1, "right")):
        b.add(f"{side}_armrest", _box((0.0, s * 0.22, 0.65), (0.4, 0.04, 0.03)),
              _rod((0.18, s * 0.22, 0.47), (0.18, s * 0.22, 0.65), 0.015),
              joint=(-0.2, s * 0.22, 0.65), axis=(0, 1, 0), removable=True)
    return b.done()


def _tree():
    b = _Body().core("trunk", _rod((0, 0, 0), (0, 0, 0.9), 0.07), _cone((0, 0, 0), (0, 0, 0.25), 0.13))
    b.add("crown", _ball((0, 0, 1.08), (0.25, 0.25, 0.22)), joint=(0, 0, 0.9))
    for k, (h, theta) in enumerate(((0.4, 0.3), (0.52, 2.4), (0.62, 4.4), (0.72, 1.2), (0.8, 3.4))):
        tip = np.array([0.38 * np.cos(theta), 0.38 * np.sin(theta), h + 0.28])
        b.add(f"branch_{k}", _seg((0, 0, h), tip, 0.03), _ball(tip, 0.14), joint=(0, 0, h), removable=True)
    return b.done()


def _pot():
    profile = [(0, 0), (0.3, 0), (0.42, 0.15), (0.45, 0.3), (0.35, 0.5), (0.22, 0.6), (0.25, 0.68), (0, 0.68)]
    b = _Body().core("body", _revolve(profile))
    b.add("spout", _seg((0.36, 0, 0.25), (0.7, 0, 0.55), 0.045), joint=(0.36, 0, 0.25), removable=True)
    handle = trimesh.creation.torus(0.15, 0.03, major_sections=24, minor_sections=8,
                                    transform=trimesh.transformations.rotation_matrix(np.pi / 2, (1, 0, 0)))
    handle.vertices += (-0.47, 0, 0.35)
    b.add("handle", handle, joint=(-0.4, 0, 0.35), axis=(0, 0, 1), removable=True)
    b.add("knob", _ball((0, 0, 0.73), 0.05), joint=(0, 0, 0.68))
    return b.done()


def _desktop_computer():
    b = _Body().core("monitor", _box((0, 0, 0.45), (0.05, 0.6, 0.38)), _rod((-0.03, 0, 0.3), (-0.03, 0, 0.02), 0.025),
                     _box((-0.03, 0, 0.01), (0.2, 0.25, 0.02)))
    b.add("keyboard", _box((0.35, 0, 0.015), (0.16, 0.45, 0.03)), joint=(0.27, 0, 0.015), axis=(0, 0, 1))
    b.add("mouse", _ball((0.35, 0.35, 0.02), (0.05, 0.03, 0.02)), joint=(0.3, 0.3, 0.02), axis=(0, 0, 1),
          removable=True)
    b.add("tower", _box((0, -0.55, 0.22), (0.4, 0.18, 0.44)), joint=(0, -0.45, 0), axis=(0, 0, 1), removable=True)
    b.add("speaker", _box((0, 0.42, 0.1), (0.08, 0.08, 0.2)), joint=(0, 0.42, 0), axis=(0, 0, 1), removable=True)
    return b.done()


def _hand():
    b = _Body().core("palm", _box((0, 0, 5), (8.5, 2.5, 9)))
    b.core("wrist", _seg((0, 0, 0.5), (0, 0, -4), 2.8))
    fingers = (("index", 3.0, 4.5, 3.5), ("middle", 1.0, 5.0, 4.0), ("ring", -1.0, 4.7, 3.7), ("little", -3.0, 3.5, 3.0))
    for name, x, l1, l2 in fingers:
        b.add(f"{name}_proximal", _seg((x, 0, 9.5), (x, 0, 9.5 + l1), 0.9), joint=(x, 0, 9.5),
              axis=(1, 0, 0), removable=True)
        b.add(f"{name}_distal", _seg((x, 0, 9.5 + l1), (x, 0, 9.5 + l1 + l2), 0.8), parent=f"{name}_proximal",
              joint=(x, 0, 9.5 + l1), axis=(1, 0, 0))
    b.add("thumb_proximal", _seg((4, 0, 2), (6.5, 0, 5.5), 1.1), joint=(4, 0, 2), removable=True)
    b.add("thumb_distal", _seg((6.5, 0, 5.5), (7.5, 0, 8), 0.95), parent="thumb_proximal", joint=(6.5, 0, 5.5))
    return b.done()


def _quadruped(body, neck, head, ears, legs, tail, thick):
    """Dog and horse: body core, a neck+head, four two-segment legs, a tail."""
    b = _Body().core("body", _seg(*body))
    b.add("head", _seg(*neck), *head, joint=neck[0])
    for k, (a, t) in enumerate(ears):
        b.add(f"ear_{k}", _cone(a, t, 0.03 * thick), parent="head", joint=a, removable=True)
    for name, (x, y, top, knee, r) in legs.items():
        b.add(f"{name}_upper", _seg((x, y, top), (x, y, knee), r), joint=(x, y, top), axis=(0, 1, 0),
              removable=True)
        b.add(f"{name}_lower", _seg((x, y, knee), (x + 0.02, y, 0.03), 0.75 * r),
              _ball((x + 0.03, y, 0.03), (1.3 * r, r, 0.6 * r)), parent=f"{name}_upper", joint=(x, y, knee),
              axis=(0, 1, 0))
    b.add("tail", _seg(*tail), joint=tail[0], removable=True)
    return b.done()


def _dog():
    legs = {f"{fb}_{side}": (x, s * 0.09, 0.45, 0.25, 0.045)
            for fb, x in (("front", 0.25), ("back", -0.3)) for side, s in (("left", 1), ("right", -1))}
    return _quadruped(((-0.35, 0, 0.5), (0.3, 0, 0.52), 0.15), ((0.3, 0, 0.55), (0.45, 0, 0.75), 0.07),
                      (_ball((0.52, 0, 0.8), (0.12, 0.08, 0.08)), _ball((0.65, 0, 0.77), (0.08, 0.05, 0.05))),
                      (((0.5, 0.05, 0.86), (0.48, 0.07, 0.96)), ((0.5, -0.05, 0.86), (0.48, -0.07, 0.96))),
                      legs, ((-0.48, 0, 0.55), (-0.7, 0, 0.75), 0.025), 1.0)


def _horse():
    legs = {f"{fb}_{side}": (x, s * 0.14, 1.1, 0.6, 0.07)
            for fb, x in (("front", 0.35), ("back", -0.45)) for side, s in (("left", 1), ("right", -1))}
    return _quadruped(((-0.5, 0, 1.2), (0.4, 0, 1.25), 0.25), ((0.45, 0, 1.3), (0.75, 0, 1.75), 0.12),
                      (_seg((0.75, 0, 1.8), (0.98, 0, 1.55), 0.08),),
                      (((0.73, 0.05, 1.85), (0.7, 0.06, 1.98)), ((0.73, -0.05, 1.85), (0.7, -0.06, 1.98))),
                      legs, ((-0.72, 0, 1.3), (-0.95, 0, 0.7), 0.05), 1.5)


def _guitar():
    ry = trimesh.transformations.rotation_matrix(np.pi / 2, (1, 0, 0))
    lower = trimesh.creation.cylinder(radius=0.2, height=0.1, sections=32, transform=ry)
    upper = trimesh.creation.cylinder(radius=0.15, height=0.1, sections=32, transform=ry)
    upper.vertices += (0, 0, 0.28)
    b = _Body().core("body", lower, upper, _box((0, 0, 0.14), (0.26, 0.1, 0.12)), _box((0, 0.055, -0.08), (0.15, 0.02, 0.03)))
    b.add("neck", _box((0, 0.02, 0.65), (0.06, 0.03, 0.55)), joint=(0, 0.02, 0.38))
    b.add("headstock", _box((0, 0.02, 1.0), (0.09, 0.025, 0.16)), parent="neck", joint=(0, 0.02, 0.92),
          axis=(1, 0, 0), removable=True)
    for s, side in ((1, "left"), (-1, "right")):
        b.add(f"{side}_pegs", *(_rod((s * 0.045, 0.02, z), (s * 0.075, 0.02, z), 0.008) for z in (0.96, 1.0, 1.04)),
              parent="headstock", joint=(s * 0.045, 0.02, 1.0), axis=(0, 0, 1))
    return b.done()


def _piano():
    tail = trimesh.creation.cylinder(radius=0.7, height=0.3, sections=32)
    tail.vertices += (-0.5, 0, 0.85)
    b = _Body().core("case", _box((0, 0, 0.85), (1.0, 1.4, 0.3)), tail)
    b.core("keyboard", _box((0.6, 0, 0.78), (0.3, 1.4, 0.12)))
    b.add("lid", _box((-0.25, 0, 1.01), (1.6, 1.4, 0.02)), joint=(-0.25, 0.7, 1.01), axis=(1, 0, 0),
          angles=(-50.0, -10.0))
    b.add("music_stand", _box((0.35, 0, 1.13), (0.02, 0.8, 0.25)), joint=(0.35, 0, 1.0), axis=(0, 1, 0))
    for k, (x, y) in enumerate(((0.4, 0.6), (0.4, -0.6), (-0.9, 0.0))):
        b.add(f"leg_{k}", _rod((x, y, 0.7), (x, y, 0.0), 0.05), joint=(x, y, 0.7), removable=True)
    b.add("pedals", _rod((0.55, 0, 0.7), (0.55, 0, 0.1), 0.03), _box((0.6, 0, 0.08), (0.15, 0.25, 0.04)),
          joint=(0.55, 0, 0.7), removable=True)
    b.add("bench", _box((1.1, 0, 0.25), (0.3, 0.8, 0.5)), joint=(1.0, 0, 0), axis=(0, 0, 1), removable=True)
    return b.done()


def _spider():
    b = _Body().core("cephalothorax", _ball((0.15, 0, 0.3), (0.18, 0.15, 0.1)))
    b.core("abdomen", _ball((-0.25, 0, 0.35), (0.28, 0.22, 0.18)))
    for s, side in ((1, "left"), (-1, "right")):
        for k, theta in enumerate(np.radians((40.0, 75.0, 105.0, 140.0))):
            u = np.array([np.cos(theta), s * np.sin(theta), 0.0])
            base = np.array([0.15, 0.0, 0.3]) + 0.12 * u
            knee = base + 0.35 * u + (0, 0, 0.25)
            foot = base + 0.7 * u - (0, 0, 0.3)
            b.add(f"{side}_femur_{k}", _seg(base, knee, 0.025), joint=base, removable=True)
            b.add(f"{side}_tibia_{k}", _seg(knee, foot, 0.02), parent=f"{side}_femur_{k}", joint=knee)
    return b.done()


_BUILDERS = dict(zip(CLASSES, (_human, _dolphin, _chair, _tree, _pot, _desktop_computer,
                               _hand, _dog, _guitar, _piano, _spider, _horse)))


@functools.lru_cache(maxsize=None)
def _reference(class_name):
    """Parts of a class's reference, mapped to a centred box with largest extent 1."""
    parts = _BUILDERS[class_name]()
    vertices = np.concatenate([p.vertices for p in parts])
    lo, hi = vertices.min(0), vertices.max(0)
    center, scale = (lo + hi) / 2.0, 1.0 / float(np.max(hi - lo))

    def fit(x):
        return None if x is None else (x - center) * scale

    return tuple(_Part(p.name, fit(p.vertices), p.faces, p.parent, fit(p.joint), p.axis, p.angles, p.removable)
                 for p in parts)


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
        parts = [_Part(q.name, (q.vertices - pivot) @ rot.T + pivot, q.faces, q.parent,
                       (q.joint - pivot) @ rot.T + pivot, q.axis if q.axis is None else rot @ q.axis,
                       q.angles, q.removable) if q.name in moved else q for q in parts]
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
            q = _Part(q.name, stretch(q.vertices), q.faces, q.parent, q.joint, q.axis, q.angles, q.removable)
        elif q.name in below:  # children ride along with the stretched tip
            shift = stretch(q.joint) - q.joint
            q = _Part(q.name, q.vertices + shift, q.faces, q.parent, q.joint + shift, q.axis, q.angles, q.removable)
        out.append(q)
    return out, f"extrusion: {part.name} x{factor:.2f}"


def _add_outlier(parts, rng):
    vertices = np.concatenate([p.vertices for p in parts])
    lo, hi = vertices.min(0), vertices.max(0)
    theta = rng.uniform(0.0, 2.0 * np.pi)
    u = np.array([np.cos(theta), np.sin(theta), 0.0])
    half = (hi - lo) / 2.0
    reach = min(half[i] / abs(u[i]) for i in range(2) if abs(u[i]) > 1e-9)  # to the box side
    height = rng.uniform(0.0, 1.0)
    center = (lo + hi) / 2.0 + (reach + _OUTLIER_GAP) * u
    center[2] = lo[2] + height * (hi[2] - lo[2])
    ball = _ball(center, _OUTLIER_RADIUS)
    extra = _Part("outlier", np.asarray(ball.vertices, float), np.asarray(ball.faces, np.int64), None,
                  center, None, None, True)
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
    seed : deformations (chosen parts, angles, factors) are drawn from
        ``numpy.random.default_rng([seed, class index, instance])``.

    Returns
    -------
    mesh : trimesh.Trimesh, not processed (parts overlap; vertices are not merged), with
        ``metadata``: ``class_name``, ``instance``, ``deformation`` (a description) and
        ``core_vertex_count`` (the first vertices, identical within the class).
    """
    _check_class(class_name)
    if int(instance) != instance or instance < 0:
        raise InvalidInputError(f"instance must be an integer >= 0, got {instance!r}")
    instance = int(instance)
    parts = list(_reference(class_name))
    rng = np.random.default_rng([int(seed), CLASSES.index(class_name), instance])
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
    """``{class_name: [instance 0, ..., instance instances-1]}`` for `classes` (default: all 12)."""
    classes = CLASSES if classes is None else tuple(classes)
    for name in classes:
        _check_class(name)
    if int(instances) != instances or instances < 1:
        raise InvalidInputError(f"instances must be an integer >= 1, got {instances!r}")
    return {name: [make_object(name, i, seed) for i in range(int(instances))] for name in classes}
