"""The persistent JAX compilation cache of command-line runs and worker processes.

JAX can store compiled programs on disk and load them in later processes instead of compiling
again (``jax_compilation_cache_dir``; programs that took at least a second to compile are kept).
The command line and the worker processes of :mod:`jaxpose.batch.batch` point it at a user cache folder
before JAX is imported, through the ``JAX_COMPILATION_CACHE_DIR`` environment variable:

* ``$JAXPOSE_CACHE_DIR`` when set (an empty value turns the cache off), else
* ``$XDG_CACHE_HOME/jaxpose/jax`` or ``~/.cache/jaxpose/jax`` (Linux and other POSIX),
  ``~/Library/Caches/jaxpose/jax`` (macOS), ``%LOCALAPPDATA%\\jaxpose\\jax`` (Windows).

A ``JAX_COMPILATION_CACHE_DIR`` already in the environment is left as it is. A process that has
already imported JAX is not changed (its owner configures it): library calls never touch JAX's
configuration.
"""
from __future__ import annotations

import os
import sys
from pathlib import Path

__all__ = ["cache_dir", "environment"]

_JAX_VARIABLE = "JAX_COMPILATION_CACHE_DIR"


def cache_dir(environ=None) -> Path | None:
    """The folder for compiled programs (module docs), or None when turned off.

    Args:
      environ: the environment to read (default ``os.environ``).
    """
    environ = os.environ if environ is None else environ
    if "JAXPOSE_CACHE_DIR" in environ:
        value = environ["JAXPOSE_CACHE_DIR"]
        return Path(value).expanduser() if value else None
    if sys.platform == "darwin":
        base = Path.home() / "Library" / "Caches"
    elif os.name == "nt":
        base = Path(environ.get("LOCALAPPDATA") or Path.home() / "AppData" / "Local")
    else:
        base = Path(environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return base / "jaxpose" / "jax"


def environment(environ=None) -> dict:
    """The variables a new process needs for the cache: ``{}`` when set already or turned off."""
    environ = os.environ if environ is None else environ
    folder = cache_dir(environ)
    if _JAX_VARIABLE in environ or folder is None:
        return {}
    return {_JAX_VARIABLE: str(folder)}
