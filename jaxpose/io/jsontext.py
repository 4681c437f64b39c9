"""Strict JSON text (RFC 8259) for the records jaxpose writes: the commands' ``--json`` files and
transforms, and the benchmarks' results. Standard library only (the command line imports it before
NumPy)."""
from __future__ import annotations

import json
import math

__all__ = ["json_text"]


def json_text(record) -> str:
    """A record (evaluate's result, normalize's transform, tune's result, a benchmark's) as strict JSON
    text (RFC 8259), indented, with a final newline.

    A float that is not finite is written as ``null`` (a NaN measure: ``json.dumps`` would write
    the bare token ``NaN``, which is not JSON; strict readers refuse the file). Nothing else changes.

    >>> json_text({"ambiguity": [float("nan"), 0.5]})
    '{\\n  "ambiguity": [\\n    null,\\n    0.5\\n  ]\\n}\\n'
    """
    def finite(value):
        if isinstance(value, float):
            return value if math.isfinite(value) else None
        if isinstance(value, dict):
            return {key: finite(item) for key, item in value.items()}
        if isinstance(value, (list, tuple)):
            return [finite(item) for item in value]
        return value

    return json.dumps(finite(record), indent=2, allow_nan=False) + "\n"
