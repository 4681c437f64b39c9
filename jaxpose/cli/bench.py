"""``jaxpose bench``: the timings of ``benchmarks/`` (a source checkout), every argument passed on."""
from __future__ import annotations

import importlib
import sys
from pathlib import Path

from .common import fail

__all__ = ["add_parser", "run"]


def add_parser(sub):
    """Register ``bench`` on the sub-command parsers `sub`: every argument after it goes to ``benchmarks.cli``."""
    p = sub.add_parser("bench", add_help=False, help="timings against scikit-learn, from a source checkout (arguments go to benchmarks/)")
    p.set_defaults(handler=run)


def run(args):
    """The benchmarks live beside the package in a source checkout (``benchmarks/``)."""
    root = Path(__file__).resolve().parents[2]
    if not (root / "benchmarks" / "__init__.py").is_file():
        return fail(f"the benchmarks are not installed with the package; run them from a source checkout "
                     f"(no {root / 'benchmarks'})")
    if str(root) not in sys.path:
        sys.path.insert(0, str(root))
    return importlib.import_module("benchmarks").cli(list(args.extra))
