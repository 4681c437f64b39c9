"""Consistency of every estimator on the dev meshes, in all five input variants.

``python -m benchmarks.consistency [--json OUT] [--datasets faust-dev,kids-dev] [--variants ...]``
from a source checkout, on the data folder of :mod:`benchmarks.data` (``$JAXPOSE_DATA``, else
../shared/data; docs/data.md says how to get it): without it the run exits 1 and says so. FAUST's flat folder is split into its two
people (tr_reg_000-009, 010-019) by symbolic links in a temporary folder; KIDS has one sub-folder
per child. Each class is rigid-core aligned (``--align-core``), then every variant is made from the
aligned meshes and every method run (``jaxpose.evaluation.evaluate``). Prints the tables of
``jaxpose evaluate``, whether the default (``robust``) is the most consistent in sigma_tr and in
cv_scale in each variant, and the wall time. No timing is asserted anywhere.
"""
from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

from benchmarks.data import data_root, faust_classes, require

SHARED = data_root()
DATASETS = ("faust-dev", "kids-dev")


def class_folder(name, tmp):
    """A folder with one sub-folder per class for a dev dataset (symbolic links, nothing copied)."""
    root = SHARED / name
    if name != "faust-dev":
        return root
    return faust_classes(root, Path(tmp) / name)


def best_of(summary, default="robust"):
    """Whether ``default`` has the lowest sigma_tr and the lowest cv_scale of every method that applies."""
    rows = [r for r in summary if r["sigma_tr"] is not None]
    mine = next(r for r in rows if r["method"] == default)
    return {k: all(mine[k] <= r[k] for r in rows) for k in ("sigma_tr", "cv_scale")}


def main(argv=None):
    from jaxpose import datasets, evaluation

    p = argparse.ArgumentParser(prog="python -m benchmarks.consistency")
    p.add_argument("--datasets", default=",".join(DATASETS))
    p.add_argument("--variants", default=",".join(evaluation.VARIANTS))
    p.add_argument("--methods", default=None)
    p.add_argument("--json", default=None)
    args = p.parse_args(argv)
    require(args.datasets.split(","), SHARED)  # nothing to measure: exit 1, saying where the data comes from
    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.datasets.split(","):
            start = time.perf_counter()
            classes = datasets.load_folder(class_folder(name, tmp))
            result = evaluation.evaluate(classes, align_core=True, variants=args.variants.split(","),
                                         methods=args.methods.split(",") if args.methods else None)
            seconds = time.perf_counter() - start
            print(f"\n## {name} ({seconds:.0f} s, loading included)\n")
            print(evaluation.format_table(result))
            verdict = {v: best_of(block["summary"]) for v, block in result["variants"].items()}
            print("robust is the most consistent:", json.dumps(verdict))
            result["seconds"] = seconds
            out[name] = result
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
