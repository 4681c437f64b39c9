"""The library's exceptions and warnings (no dependencies: importing them costs nothing).

Re-exported by :mod:`jaxpose` and :mod:`jaxpose._validate`.
"""

__all__ = ["JaxposeError", "InvalidInputError", "UsageError", "ConvergenceError", "OpenMeshWarning", "InvalidPoseWarning"]


class JaxposeError(Exception):
    """Root of the library's exceptions."""


class InvalidInputError(JaxposeError, ValueError):
    """An argument has the wrong shape, dtype or value."""


class UsageError(InvalidInputError):
    """Arguments refused before any work for how they fit together or with the file system, not for
    a value out of range: an output path that cannot be used (a file where a folder is needed, a
    folder that cannot be written, an existing file without force, outputs that collide), options
    that conflict. The command line exits 2 (usage) for it, as for a bad option or value."""


class ConvergenceError(JaxposeError, RuntimeError):
    """A solver stopped at its iteration cap (raised only when asked)."""


class OpenMeshWarning(UserWarning):
    """A closed-surface quantity (solid volume, centroid) was computed on a mesh that is not closed."""


class InvalidPoseWarning(UserWarning):
    """A concrete pose came out not valid (``Pose.valid`` False); the message says why."""
