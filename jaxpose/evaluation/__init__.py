"""Evaluation of normalizations: within-class consistency of centers and scales (paper, section 4)."""
from .alignment import align_core, kabsch
from .consistency import METHODS, SWEEP_FIXED, SWEEP_VALUES, evaluate, format_table, sweep
from .measures import scale_spread, spread

__all__ = ["METHODS", "spread", "scale_spread", "evaluate", "sweep", "align_core", "kabsch", "format_table",
           "SWEEP_VALUES", "SWEEP_FIXED"]
