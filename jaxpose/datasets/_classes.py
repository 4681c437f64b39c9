"""The 12 reference objects of the procedural dataset, one builder per class.

Each builder returns the class's parts (core parts first) in its own reference coordinates;
``procedural`` maps them to a centred box of largest extent 1 and deforms them.
"""
from __future__ import annotations

import numpy as np
import trimesh

from jaxpose.datasets._parts import ball_part, Body, box_part, cone_part, revolve_part, rod_part, seg_part

__all__ = ["CLASSES", "BUILDERS"]

CLASSES = (
    "human", "dolphin", "chair", "tree", "pot", "desktop_computer",
    "hand", "dog", "guitar", "piano", "spider", "horse",
)


def _human():
    b = Body().core("pelvis", ball_part((0, 0, 0.95), (0.11, 0.17, 0.1)))
    b.core("torso", ball_part((0, 0, 1.22), (0.11, 0.19, 0.27)))
    b.add("head", rod_part((0, 0, 1.44), (0, 0, 1.56), 0.05), ball_part((0, 0, 1.66), (0.1, 0.09, 0.12)),
          joint=(0, 0, 1.46))
    for s, side in ((1, "left"), (-1, "right")):
        b.add(f"{side}_upper_arm", seg_part((0, s * 0.23, 1.4), (0, s * 0.26, 1.12), 0.045),
              joint=(0, s * 0.23, 1.4), removable=True)
        b.add(f"{side}_forearm", seg_part((0, s * 0.26, 1.12), (0, s * 0.28, 0.86), 0.04),
              ball_part((0, s * 0.28, 0.8), (0.03, 0.03, 0.06)), parent=f"{side}_upper_arm",
              joint=(0, s * 0.26, 1.12))
        b.add(f"{side}_thigh", seg_part((0, s * 0.1, 0.9), (0, s * 0.11, 0.5), 0.07),
              joint=(0, s * 0.1, 0.9), removable=True)
        b.add(f"{side}_shin", seg_part((0, s * 0.11, 0.5), (0, s * 0.11, 0.1), 0.055),
              box_part((0.05, s * 0.11, 0.04), (0.22, 0.09, 0.06)), parent=f"{side}_thigh",
              joint=(0, s * 0.11, 0.5))
    return b.done()


def _dolphin():
    b = Body().core("body", ball_part((0, 0, 0), (0.9, 0.22, 0.25)))
    b.add("snout", seg_part((0.82, 0, -0.03), (1.15, 0, -0.06), 0.05), joint=(0.82, 0, -0.03))
    b.add("tail", seg_part((-0.75, 0, 0), (-1.25, 0, 0.05), 0.09), joint=(-0.75, 0, 0))
    b.add("flukes", ball_part((-1.33, 0, 0.05), (0.12, 0.3, 0.03)), parent="tail",
          joint=(-1.25, 0, 0.05), removable=True)
    b.add("dorsal_fin", cone_part((0, 0, 0.2), (-0.15, 0, 0.45), 0.1), joint=(0, 0, 0.2), removable=True)
    for s, side in ((1, "left"), (-1, "right")):
        b.add(f"{side}_fin", ball_part((0.3, s * 0.3, -0.15), (0.12, 0.12, 0.025)),
              joint=(0.35, s * 0.18, -0.1), removable=True)
    return b.done()


def _chair():
    b = Body().core("seat", box_part((0, 0, 0.45), (0.45, 0.45, 0.05)))
    b.add("backrest", box_part((-0.21, 0, 0.75), (0.04, 0.45, 0.55)), joint=(-0.21, 0, 0.475),
          axis=(0, 1, 0), angles=(-35.0, 20.0))
    for x in (0.2, -0.2):
        for y in (0.2, -0.2):
            b.add(f"leg_{x:+.1f}_{y:+.1f}", rod_part((x, y, 0.43), (x, y, 0.0), 0.02),
                  joint=(x, y, 0.43), removable=True)
    for s, side in ((1, "left"), (-1, "right")):
        b.add(f"{side}_armrest", box_part((0.0, s * 0.22, 0.65), (0.4, 0.04, 0.03)),
              rod_part((0.18, s * 0.22, 0.47), (0.18, s * 0.22, 0.65), 0.015),
              joint=(-0.2, s * 0.22, 0.65), axis=(0, 1, 0), removable=True)
    return b.done()


def _tree():
    b = Body().core("trunk", rod_part((0, 0, 0), (0, 0, 0.9), 0.07), cone_part((0, 0, 0), (0, 0, 0.25), 0.13))
    b.add("crown", ball_part((0, 0, 1.08), (0.25, 0.25, 0.22)), joint=(0, 0, 0.9))
    for k, (h, theta) in enumerate(((0.4, 0.3), (0.52, 2.4), (0.62, 4.4), (0.72, 1.2), (0.8, 3.4))):
        tip = np.array([0.38 * np.cos(theta), 0.38 * np.sin(theta), h + 0.28])
        b.add(f"branch_{k}", seg_part((0, 0, h), tip, 0.03), ball_part(tip, 0.14), joint=(0, 0, h), removable=True)
    return b.done()


def _pot():
    profile = [(0, 0), (0.3, 0), (0.42, 0.15), (0.45, 0.3), (0.35, 0.5), (0.22, 0.6), (0.25, 0.68), (0, 0.68)]
    b = Body().core("body", revolve_part(profile))
    b.add("spout", seg_part((0.36, 0, 0.25), (0.7, 0, 0.55), 0.045), joint=(0.36, 0, 0.25), removable=True)
    handle = trimesh.creation.torus(0.15, 0.03, major_sections=24, minor_sections=8,
                                    transform=trimesh.transformations.rotation_matrix(np.pi / 2, (1, 0, 0)))
    handle.vertices += (-0.47, 0, 0.35)
    b.add("handle", handle, joint=(-0.4, 0, 0.35), axis=(0, 0, 1), removable=True)
    b.add("knob", ball_part((0, 0, 0.73), 0.05), joint=(0, 0, 0.68))
    return b.done()


def _desktop_computer():
    b = Body().core("monitor", box_part((0, 0, 0.45), (0.05, 0.6, 0.38)), rod_part((-0.03, 0, 0.3), (-0.03, 0, 0.02), 0.025),
                     box_part((-0.03, 0, 0.01), (0.2, 0.25, 0.02)))
    b.add("keyboard", box_part((0.35, 0, 0.015), (0.16, 0.45, 0.03)), joint=(0.27, 0, 0.015), axis=(0, 0, 1))
    b.add("mouse", ball_part((0.35, 0.35, 0.02), (0.05, 0.03, 0.02)), joint=(0.3, 0.3, 0.02), axis=(0, 0, 1),
          removable=True)
    b.add("tower", box_part((0, -0.55, 0.22), (0.4, 0.18, 0.44)), joint=(0, -0.45, 0), axis=(0, 0, 1), removable=True)
    b.add("speaker", box_part((0, 0.42, 0.1), (0.08, 0.08, 0.2)), joint=(0, 0.42, 0), axis=(0, 0, 1), removable=True)
    return b.done()


def _hand():
    b = Body().core("palm", box_part((0, 0, 5), (8.5, 2.5, 9)))
    b.core("wrist", seg_part((0, 0, 0.5), (0, 0, -4), 2.8))
    fingers = (("index", 3.0, 4.5, 3.5), ("middle", 1.0, 5.0, 4.0), ("ring", -1.0, 4.7, 3.7), ("little", -3.0, 3.5, 3.0))
    for name, x, l1, l2 in fingers:
        b.add(f"{name}_proximal", seg_part((x, 0, 9.5), (x, 0, 9.5 + l1), 0.9), joint=(x, 0, 9.5),
              axis=(1, 0, 0), removable=True)
        b.add(f"{name}_distal", seg_part((x, 0, 9.5 + l1), (x, 0, 9.5 + l1 + l2), 0.8), parent=f"{name}_proximal",
              joint=(x, 0, 9.5 + l1), axis=(1, 0, 0))
    b.add("thumb_proximal", seg_part((4, 0, 2), (6.5, 0, 5.5), 1.1), joint=(4, 0, 2), removable=True)
    b.add("thumb_distal", seg_part((6.5, 0, 5.5), (7.5, 0, 8), 0.95), parent="thumb_proximal", joint=(6.5, 0, 5.5))
    return b.done()


def _quadruped(body, neck, head, ears, legs, tail, thick):
    """Dog and horse: body core, a neck+head, four two-segment legs, a tail."""
    b = Body().core("body", seg_part(*body))
    b.add("head", seg_part(*neck), *head, joint=neck[0])
    for k, (a, t) in enumerate(ears):
        b.add(f"ear_{k}", cone_part(a, t, 0.03 * thick), parent="head", joint=a, removable=True)
    for name, (x, y, top, knee, r) in legs.items():
        b.add(f"{name}_upper", seg_part((x, y, top), (x, y, knee), r), joint=(x, y, top), axis=(0, 1, 0),
              removable=True)
        b.add(f"{name}_lower", seg_part((x, y, knee), (x + 0.02, y, 0.03), 0.75 * r),
              ball_part((x + 0.03, y, 0.03), (1.3 * r, r, 0.6 * r)), parent=f"{name}_upper", joint=(x, y, knee),
              axis=(0, 1, 0))
    b.add("tail", seg_part(*tail), joint=tail[0], removable=True)
    return b.done()


def _dog():
    legs = {f"{fb}_{side}": (x, s * 0.09, 0.45, 0.25, 0.045)
            for fb, x in (("front", 0.25), ("back", -0.3)) for side, s in (("left", 1), ("right", -1))}
    return _quadruped(((-0.35, 0, 0.5), (0.3, 0, 0.52), 0.15), ((0.3, 0, 0.55), (0.45, 0, 0.75), 0.07),
                      (ball_part((0.52, 0, 0.8), (0.12, 0.08, 0.08)), ball_part((0.65, 0, 0.77), (0.08, 0.05, 0.05))),
                      (((0.5, 0.05, 0.86), (0.48, 0.07, 0.96)), ((0.5, -0.05, 0.86), (0.48, -0.07, 0.96))),
                      legs, ((-0.48, 0, 0.55), (-0.7, 0, 0.75), 0.025), 1.0)


def _horse():
    legs = {f"{fb}_{side}": (x, s * 0.14, 1.1, 0.6, 0.07)
            for fb, x in (("front", 0.35), ("back", -0.45)) for side, s in (("left", 1), ("right", -1))}
    return _quadruped(((-0.5, 0, 1.2), (0.4, 0, 1.25), 0.25), ((0.45, 0, 1.3), (0.75, 0, 1.75), 0.12),
                      (seg_part((0.75, 0, 1.8), (0.98, 0, 1.55), 0.08),),
                      (((0.73, 0.05, 1.85), (0.7, 0.06, 1.98)), ((0.73, -0.05, 1.85), (0.7, -0.06, 1.98))),
                      legs, ((-0.72, 0, 1.3), (-0.95, 0, 0.7), 0.05), 1.5)


def _guitar():
    ry = trimesh.transformations.rotation_matrix(np.pi / 2, (1, 0, 0))
    lower = trimesh.creation.cylinder(radius=0.2, height=0.1, sections=32, transform=ry)
    upper = trimesh.creation.cylinder(radius=0.15, height=0.1, sections=32, transform=ry)
    upper.vertices += (0, 0, 0.28)
    b = Body().core("body", lower, upper, box_part((0, 0, 0.14), (0.26, 0.1, 0.12)), box_part((0, 0.055, -0.08), (0.15, 0.02, 0.03)))
    b.add("neck", box_part((0, 0.02, 0.65), (0.06, 0.03, 0.55)), joint=(0, 0.02, 0.38))
    b.add("headstock", box_part((0, 0.02, 1.0), (0.09, 0.025, 0.16)), parent="neck", joint=(0, 0.02, 0.92),
          axis=(1, 0, 0), removable=True)
    for s, side in ((1, "left"), (-1, "right")):
        b.add(f"{side}_pegs", *(rod_part((s * 0.045, 0.02, z), (s * 0.075, 0.02, z), 0.008) for z in (0.96, 1.0, 1.04)),
              parent="headstock", joint=(s * 0.045, 0.02, 1.0), axis=(0, 0, 1))
    return b.done()


def _piano():
    tail = trimesh.creation.cylinder(radius=0.7, height=0.3, sections=32)
    tail.vertices += (-0.5, 0, 0.85)
    b = Body().core("case", box_part((0, 0, 0.85), (1.0, 1.4, 0.3)), tail)
    b.core("keyboard", box_part((0.6, 0, 0.78), (0.3, 1.4, 0.12)))
    b.add("lid", box_part((-0.25, 0, 1.01), (1.6, 1.4, 0.02)), joint=(-0.25, 0.7, 1.01), axis=(1, 0, 0),
          angles=(-50.0, -10.0))
    b.add("music_stand", box_part((0.35, 0, 1.13), (0.02, 0.8, 0.25)), joint=(0.35, 0, 1.0), axis=(0, 1, 0))
    for k, (x, y) in enumerate(((0.4, 0.6), (0.4, -0.6), (-0.9, 0.0))):
        b.add(f"leg_{k}", rod_part((x, y, 0.7), (x, y, 0.0), 0.05), joint=(x, y, 0.7), removable=True)
    b.add("pedals", rod_part((0.55, 0, 0.7), (0.55, 0, 0.1), 0.03), box_part((0.6, 0, 0.08), (0.15, 0.25, 0.04)),
          joint=(0.55, 0, 0.7), removable=True)
    b.add("bench", box_part((1.1, 0, 0.25), (0.3, 0.8, 0.5)), joint=(1.0, 0, 0), axis=(0, 0, 1), removable=True)
    return b.done()


def _spider():
    b = Body().core("cephalothorax", ball_part((0.15, 0, 0.3), (0.18, 0.15, 0.1)))
    b.core("abdomen", ball_part((-0.25, 0, 0.35), (0.28, 0.22, 0.18)))
    for s, side in ((1, "left"), (-1, "right")):
        for k, theta in enumerate(np.radians((40.0, 75.0, 105.0, 140.0))):
            u = np.array([np.cos(theta), s * np.sin(theta), 0.0])
            base = np.array([0.15, 0.0, 0.3]) + 0.12 * u
            knee = base + 0.35 * u + (0, 0, 0.25)
            foot = base + 0.7 * u - (0, 0, 0.3)
            b.add(f"{side}_femur_{k}", seg_part(base, knee, 0.025), joint=base, removable=True)
            b.add(f"{side}_tibia_{k}", seg_part(knee, foot, 0.02), parent=f"{side}_femur_{k}", joint=knee)
    return b.done()


BUILDERS = dict(zip(CLASSES, (_human, _dolphin, _chair, _tree, _pot, _desktop_computer,
                              _hand, _dog, _guitar, _piano, _spider, _horse)))
