"""Evaluation of normalizations: within-class consistency of centers and scales (paper, section 4), on
seeded input variants (plain, stray parts, point clouds, holes); and of canonical frames (``evaluate_rotation``)."""
from .alignment import align_classes, align_core, kabsch
from .consistency import METHODS, SWEEP_FIXED, SWEEP_VALUES, evaluate, format_per_class, format_table, reference_method, sweep
from .variants import VARIANTS, make_class, make_variant
from .measures import scale_spread, spread
from .rotation import chordal_mean, class_angles, evaluate_rotation, format_rotation_per_class, format_rotation_table, sign_free_angles

__all__ = ["METHODS", "spread", "scale_spread", "evaluate", "sweep", "align_core", "align_classes", "kabsch", "format_table", "format_per_class",
           "SWEEP_VALUES", "SWEEP_FIXED", "VARIANTS", "make_class", "make_variant", "reference_method",
           "evaluate_rotation", "format_rotation_table", "format_rotation_per_class", "chordal_mean", "class_angles", "sign_free_angles"]
