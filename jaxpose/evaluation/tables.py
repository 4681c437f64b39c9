"""Per-class terminal tables: one table per class, methods as rows, each variant's columns side by side."""
from __future__ import annotations

from typing import Callable

__all__ = ["class_tables", "check_result", "counted"]

_KINDS = {"evaluate": ("sigma_tr", "format_table / format_per_class"),
          "evaluate_rotation": ("raw_mean", "format_rotation_table / format_rotation_per_class")}


def counted(n: int, noun: str, plural: str | None = None) -> str:
    """``n`` and ``noun`` in the number ``n`` takes: ``counted(1, "class")`` is ``"1 class"``,
    ``counted(0, "class")`` ``"0 classes"`` (the plural: ``plural``, else ``noun`` + "es" after
    s, x, z, ch, sh, else + "s"); the one rule of the tables' headers."""
    if n == 1:
        return f"{n} {noun}"
    if plural is None:
        plural = noun + ("es" if noun.endswith(("s", "x", "z", "ch", "sh")) else "s")
    return f"{n} {plural}"


def check_result(result, kind: str) -> dict:
    """``result`` unless it is plainly not a result of ``kind`` (``"evaluate"`` or
    ``"evaluate_rotation"``): not a dict of ``variants`` (or evaluate's ``summary``), or the other
    function's result, told by its summary rows' keys; InvalidInputError naming the formatter it
    belongs to (either was a KeyError deep in the table)."""
    from .._validate import InvalidInputError

    blocks = result.get("variants") or ({"plain": result} if "summary" in result else None) \
        if isinstance(result, dict) else None
    if not isinstance(blocks, dict) or not blocks:
        raise InvalidInputError(f"result must be the dict {kind}() returns, got {result!r:.80}")
    first = next(iter(blocks.values()))
    row = next(iter(first.get("summary", ())), None) if isinstance(first, dict) else None
    other = next((k for k, (key, _) in _KINDS.items() if k != kind), None)
    if isinstance(row, dict) and _KINDS[other][0] in row and _KINDS[kind][0] not in row:
        raise InvalidInputError(f"result must be the dict {kind}() returns: it is {other}'s, formatted by "
                                f"{_KINDS[other][1]}")
    return result


def class_tables(per_variant: dict, objects: dict, head: str, variant_width: int,
                 rows: Callable[[dict, list], dict]) -> list:
    """The lines of one table per class (without a legend).

    Args:
      per_variant: {variant: {"summary": [{"method": ...}, ...], "per_class": {class: {method: cell}}}};
        the first variant's summary orders the methods, its per_class the classes.
      objects: {class: number of objects}, shown after the class name where given.
      head: the column heads of one variant (repeated per variant).
      variant_width: the width a variant's name is centered in.
      rows: ``rows(cells, methods)`` -> {method: the text of its columns in every variant}, where
        ``cells`` is {variant: {method: cell}} of one class.

    Returns:
      list of str: for each class a blank line, ``class NAME (N objects)``, the variants' names,
      the column heads, a rule and a line per method.
    """
    variants = list(per_variant)
    first = per_variant[variants[0]]
    methods = [row["method"] for row in first["summary"]]
    width = max([len("method")] + [len(m) for m in methods]) + 2
    lines = []
    for name in first["per_class"]:
        count = f" ({objects[name]} objects)" if name in objects else ""
        top = f"{'':<{width}}" + "".join(f"{v:^{variant_width}}" for v in variants)
        header = f"{'method':<{width}}" + head * len(variants)
        lines += ["", f"class {name}{count}", top, header, "-" * len(header)]
        texts = rows({v: per_variant[v]["per_class"][name] for v in variants}, methods)
        lines += [f"{m:<{width}}" + texts[m] for m in methods]
    return lines
