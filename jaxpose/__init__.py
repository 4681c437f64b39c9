"""jaxpose: consistent canonical position and size of 3D shapes, with one-class SVMs, in JAX."""
from ._validate import ConvergenceError, InvalidInputError, InvalidPoseWarning, JaxposeError
from .config import GridConfig, PoseConfig, SolverConfig
from .moments import Moments, volume_moments
from .pose import Pose, normalize, normalize_batch
from .svdd import SVDD, decision_function, fit_svdd
from .validity import Status

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

_LAZY_MODULES = ("baselines", "sensitivity", "datasets", "evaluation", "tuning", "plot", "mesh")


def __getattr__(name):
    # trimesh-dependent and optional pieces load on first use, keeping `import jaxpose` light
    if name in ("sample_surface", "normalize_mesh"):
        from . import mesh

        return getattr(mesh, name)
    if name == "pose_sensitivity":
        from .sensitivity import pose_sensitivity

        return pose_sensitivity
    if name in _LAZY_MODULES:
        import importlib

        return importlib.import_module(f".{name}", __name__)
    raise AttributeError(f"module 'jaxpose' has no attribute {name!r}")
