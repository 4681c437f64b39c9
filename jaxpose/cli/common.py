"""What the commands share: the OCSVM options' arguments and the one-line failure message."""
from __future__ import annotations

import sys

__all__ = ["add_svm_options", "fail"]


def add_svm_options(p, count=2000):
    p.add_argument("--gamma", type=float, default=47.0, help="ocsvm: Gaussian kernel width (dimensionless, default 47)")
    p.add_argument("--nu", type=float, default=0.5, help="ocsvm: slack in [0, 1] (default 0.5)")
    p.add_argument("--count", type=int, default=count, help=f"ocsvm: surface samples per object (default {count})")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")


def fail(message, code=1):
    text = " ".join(str(message).split()) or "failed"
    print(f"jaxpose: error: {text}", file=sys.stderr)
    return code
