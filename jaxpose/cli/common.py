"""What the commands share: the OCSVM options' arguments and the one-line failure message."""
from __future__ import annotations

import sys

from ..config import OCSVM

__all__ = ["add_svm_options", "fail", "check_output_file", "check_creatable"]


def add_svm_options(p, count=OCSVM.count):
    p.add_argument("--gamma", type=float, default=OCSVM.gamma,
                   help=f"ocsvm: Gaussian kernel width (dimensionless, default {OCSVM.gamma:g})")
    p.add_argument("--nu", type=float, default=OCSVM.nu, help=f"ocsvm: slack in [0, 1] (default {OCSVM.nu:g})")
    p.add_argument("--count", type=int, default=count, help=f"ocsvm: surface samples per object (default {count})")
    p.add_argument("--seed", type=int, default=OCSVM.seed, help=f"random seed (default {OCSVM.seed})")


def fail(message, code=1):
    text = " ".join(str(message).split()) or "failed"
    print(f"jaxpose: error: {text}", file=sys.stderr)
    return code


def check_output_file(path, force=False, what="--json"):
    """Refuse, before any work, an output file that cannot be written: a folder, an existing file
    without ``force``, or a folder that cannot be made or written (raises InvalidInputError).
    A missing folder is made when the file is written."""
    from pathlib import Path

    from ..errors import InvalidInputError

    path = Path(path)
    if path.is_dir():
        raise InvalidInputError(f"{what} {path} is a folder; name a file")
    if path.exists() and not force:
        raise InvalidInputError(f"{path} exists (use --force to overwrite)")
    check_creatable(path.parent, f"{what} {path}")


def check_creatable(folder, what):
    """`folder` exists and is writable, or its nearest existing parent is a writable folder."""
    import os
    from pathlib import Path

    from ..errors import InvalidInputError

    folder = Path(folder) if str(folder) else Path(".")
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent
    if not folder.is_dir():
        raise InvalidInputError(f"{what}: {folder} is a file, not a folder")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise InvalidInputError(f"{what}: the folder {folder} is not writable")
