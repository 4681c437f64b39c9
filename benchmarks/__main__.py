"""``python -m benchmarks ...``: the same as ``jaxpose bench ...``."""
import sys

from .report import cli

if __name__ == "__main__":
    raise SystemExit(cli(sys.argv[1:]))
