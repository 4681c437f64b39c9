"""Evaluation of normalizations: within-class consistency of centers and scales (paper, section 4), on
seeded input variants (plain, stray parts, point clouds, holes)."""
from .alignment import align_core, kabsch
from .consistency import METHODS, SWEEP_FIXED, SWEEP_VALUES, evaluate, format_table, reference_method, sweep
from .variants import VARIANTS, make_class, make_variant
from .measures import scale_spread, spread

__all__ = ["METHODS", "spread", "scale_spread", "evaluate", "sweep", "align_core", "kabsch", "format_table",
           "SWEEP_VALUES", "SWEEP_FIXED", "VARIANTS", "make_class", "make_variant", "reference_method"]
