"""jaxpose: consistent canonical position and size of 3D shapes, with one-class SVMs, in JAX.

Importing the package is light: the JAX modules (and trimesh, SciPy) load on first use of a name
that needs them, so the command line and the NumPy estimators start without compiling anything.
"""
from .errors import ConvergenceError, InvalidInputError, InvalidPoseWarning, JaxposeError

__version__ = "0.1.0"

__all__ = [
    "SVDD",
    "fit_svdd",
    "decision_function",
    "Moments",
    "volume_moments",
    "Pose",
    "normalize",
    "normalize_batch",
    "sample_surface",
    "normalize_mesh",
    "normalize_files",
    "read_transforms",
    "pose_sensitivity",
    "baselines",
    "SolverConfig",
    "GridConfig",
    "PoseConfig",
    "JaxposeError",
    "InvalidInputError",
    "ConvergenceError",
    "InvalidPoseWarning",
    "Status",
]

# public name -> the module that defines it (imported on first access)
_LAZY_NAMES = {
    "SVDD": "occupancy.svdd",
    "fit_svdd": "occupancy.svdd",
    "decision_function": "occupancy.svdd",
    "Moments": "moments",
    "volume_moments": "moments",
    "Pose": "pose.result",
    "normalize": "pose.pose",
    "normalize_batch": "pose.pose",
    "SolverConfig": "config",
    "GridConfig": "config",
    "PoseConfig": "config",
    "sample_surface": "mesh",
    "normalize_mesh": "mesh",
    "normalize_files": "batch.batch",
    "read_transforms": "batch.transforms",
    "pose_sensitivity": "pose.sensitivity",
    "Status": "pose.result",
}
# public module name -> where it lives (``jaxpose.sensitivity`` and ``jaxpose.transforms``: their paths before the layers)
_LAZY_MODULES = {name: name for name in ("baselines", "datasets", "evaluation", "tuning", "plot", "mesh", "batch", "io",
                                         "occupancy", "pose", "rotation")}
_LAZY_MODULES.update(sensitivity="pose.sensitivity", transforms="batch.transforms")


def __getattr__(name):
    import importlib

    if name in _LAZY_NAMES:
        value = getattr(importlib.import_module(f".{_LAZY_NAMES[name]}", __name__), name)
        globals()[name] = value  # later look-ups skip this function
        return value
    if name in _LAZY_MODULES:
        return importlib.import_module(f".{_LAZY_MODULES[name]}", __name__)
    raise AttributeError(f"module 'jaxpose' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(__all__))
