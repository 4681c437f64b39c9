"""Command line: ``jaxpose normalize | evaluate | tune | bench`` (also ``python -m jaxpose``).

Thin: parse arguments, call the library, print and write results. No math here.
Exit codes: 0 success, 1 failure (one line on stderr, no traceback), 2 usage error (a bad option or
value, an output path that cannot be used, options that conflict: found before any work), 130 Ctrl-C,
143 SIGTERM (:mod:`jaxpose.batch.interrupts`; nothing partial or temporary is left).
"""
from __future__ import annotations

import argparse
import os
import sys

from .. import __version__
from ..errors import JaxposeError, UsageError
from . import bench, evaluate, normalize, tune
from .common import fail

__all__ = ["main", "console", "build_parser"]

_DELEGATED = ("tune", "bench")  # commands that receive every argument after their name


# --------------------------------------------------------------------------- parser
def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="jaxpose",
        description="A canonical position and size (and orientation) for 3D shapes that bend, stretch, have holes "
                    "or stray parts: meshes and point clouds, one file or a dataset. The default method, robust, is "
                    "the depth-weighted centroid and volume of a robust solid; --method ocsvm is the paper's "
                    "one-class SVM; classical baselines by name.",
        epilog="Exit codes: 0 success, 1 failure (one line on stderr), 2 usage (a bad option or value, an "
               "output path that cannot be used, before any work), "
               "130 Ctrl-C, 143 SIGTERM. 'jaxpose COMMAND --help' describes each command.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}",
                        help="print jaxpose's version and exit")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for command in (normalize, evaluate, tune, bench):
        command.add_parser(sub)
    return parser


# --------------------------------------------------------------------------- main
def main(argv=None) -> int:
    """Run the command line; returns the exit code (argparse usage errors exit with 2)."""
    parser = build_parser()
    args, extra = parser.parse_known_args(argv)
    if extra and args.command not in _DELEGATED:
        glob = getattr(args, "glob", None)
        expanded = normalize.expanded_glob_names(glob, extra)  # (not for any unknown option)
        hint = "" if not expanded else \
            f"; did the shell expand --glob's pattern into file names ({glob} {expanded[0]} ...)? quote it: --glob " \
            f"'*{os.path.splitext(glob)[1].lower()}'"
        parser.error(f"unrecognized arguments: {' '.join(extra)}{hint}")
    args.extra = extra
    try:
        return int(args.handler(args) or 0)
    except BrokenPipeError:  # `jaxpose ... | head`: the reader left; the work and its files were done first
        _silence_stdout()
        return 0
    except UsageError as exc:  # the arguments refused before any work (an output path, a conflict)
        return fail(str(exc), code=2)
    except JaxposeError as exc:
        return fail(str(exc))
    except (OSError, ValueError) as exc:  # file system and number trouble outside the library
        return fail(f"{type(exc).__name__}: {exc}")
    except KeyboardInterrupt as exc:
        return _interrupted(exc)


def _silence_stdout():
    """Point stdout at /dev/null, so that nothing more is written to the closed pipe (no second
    BrokenPipeError when Python flushes it)."""
    import os

    try:
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    except (OSError, ValueError):
        pass


def _interrupted(exc):
    from ..batch.interrupts import Terminated

    if isinstance(exc, Terminated):
        return fail("terminated (SIGTERM); nothing partial was left", code=143)
    return fail("interrupted; nothing partial was left", code=130)


def console():
    """The ``jaxpose`` command (and ``python -m jaxpose``): :func:`main` under a signal guard.

    Ends the process with ``os._exit`` (:func:`jaxpose.batch.interrupts.leave`): the exit code of
    :func:`main`, or 128 + the signal when Ctrl-C or SIGTERM came at any moment of the run.
    """
    from ..batch import interrupts, workers

    code = 1
    with interrupts.SignalGuard() as guard:
        try:
            # before anything imports NumPy or JAX: the compilation cache; for normalize also one
            # BLAS thread, as in its worker processes (the same bits whichever process computes)
            workers.configure_process(one_thread=sys.argv[1:2] == ["normalize"])
            code = main()
        except SystemExit as exc:  # argparse: --help (0), usage errors (2)
            code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else fail(exc.code))
        except KeyboardInterrupt as exc:  # landed outside main's own handling
            code = _interrupted(exc)
        if guard.received is not None and code != guard.exit_code:
            code = fail("interrupted after the work was done", code=guard.exit_code)
        interrupts.leave(code)
