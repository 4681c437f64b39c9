"""``python -m jaxpose``: the command line (see :mod:`jaxpose.cli`)."""
from .cli import console

if __name__ == "__main__":
    console()
