"""Command line: ``jaxpose normalize | evaluate | tune | bench`` (also ``python -m jaxpose``), one module per command."""
from .main import build_parser, console, main

__all__ = ["main", "console", "build_parser"]
