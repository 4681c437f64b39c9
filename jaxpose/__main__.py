"""``python -m jaxpose``: the command line (see :mod:`jaxpose.cli`)."""
import sys

from .cli import main

if __name__ == "__main__":
    sys.exit(main())
