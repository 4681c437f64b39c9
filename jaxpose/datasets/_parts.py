"""Parts of the procedural objects: the ``Part`` record, primitive meshes, the ``Body`` builder.

A procedural object is a tree of named parts: a rigid *core* (``joint is None``, never moved)
and movable parts hanging from joints. Primitives are trimesh meshes in reference coordinates.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh


@dataclass(frozen=True)
class Part:
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


def seg_part(a, b, r):
    """Capsule from a to b."""
    length, matrix = _segment_transform(a, b)
    return trimesh.creation.capsule(height=length, radius=r, count=[10, 10], transform=matrix)


def rod_part(a, b, r):
    """Closed cylinder from a to b."""
    return trimesh.creation.cylinder(radius=r, segment=[a, b], sections=14)


def cone_part(base, tip, r):
    length, matrix = _segment_transform(base, tip)
    matrix[:3, 3] = base
    return trimesh.creation.cone(radius=r, height=length, sections=14, transform=matrix)


def box_part(center, extents):
    return trimesh.creation.box(extents=extents, transform=trimesh.transformations.translation_matrix(center))


def ball_part(center, radii):
    mesh = trimesh.creation.icosphere(subdivisions=2)
    mesh.vertices = mesh.vertices * np.broadcast_to(np.asarray(radii, float), (3,)) + np.asarray(center, float)
    return mesh


def revolve_part(profile, base=(0.0, 0.0, 0.0)):
    """Surface of revolution about +z of a (radius, height) profile."""
    mesh = trimesh.creation.revolve(np.asarray(profile, float), sections=24)
    mesh.vertices = mesh.vertices + np.asarray(base, float)
    return mesh


class Body:
    """Builder of a part list (core parts first)."""

    def __init__(self):
        self.parts: list[Part] = []

    def add(self, name, *meshes, parent=None, joint=None, axis=None, angles=None, removable=False):
        mesh = trimesh.util.concatenate(list(meshes)) if len(meshes) > 1 else meshes[0]
        self.parts.append(Part(
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
