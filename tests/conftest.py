"""Shared fixtures: deterministic point sets and a float64 switch."""
from __future__ import annotations

import contextlib
import gc
import os
import pathlib
import shutil
import sys
import tempfile

# One persistent compilation cache per test run, shared by every process of the run: the test
# processes (pytest-xdist workers inherit the variables set here by the process that starts them),
# command-line subprocesses and their workers (JAXPOSE_CACHE_DIR, read by jaxpose.batch.cache) and
# notebook kernels (JAX_COMPILATION_CACHE_DIR). A program compiled once in the run, by another
# worker or before the memory-map guard below released it, is loaded instead of compiled again.
# The folder is new for each run and removed at its end: a folder that outlived the run would
# make a second run on one machine faster than CI's fresh one (docs/testing.md). A
# JAXPOSE_CACHE_DIR set by the caller is used as it is (an empty value turns the cache off).
RUN_CACHE = None
if "JAXPOSE_CACHE_DIR" not in os.environ:
    RUN_CACHE = tempfile.mkdtemp(prefix="jaxpose-tests-jax-cache-")
    os.environ["JAXPOSE_CACHE_DIR"] = RUN_CACHE
if os.environ["JAXPOSE_CACHE_DIR"]:
    os.environ.setdefault("JAX_COMPILATION_CACHE_DIR", os.environ["JAXPOSE_CACHE_DIR"])
os.environ.setdefault("JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS", "0.2")

import jax  # noqa: E402

if os.environ.get("JAX_COMPILATION_CACHE_DIR"):  # also where a plugin imported JAX before this file
    jax.config.update("jax_compilation_cache_dir", os.environ["JAX_COMPILATION_CACHE_DIR"])
    jax.config.update("jax_persistent_cache_min_compile_time_secs",
                      float(os.environ["JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS"]))

import numpy as np
import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:  # benchmarks/ is importable from a source checkout
    sys.path.insert(0, str(ROOT))
SHARED = ROOT.parent / "shared"
FAUST = SHARED / "data" / "faust-dev"


# XLA:CPU maps every compiled kernel's code and data into memory separately (about three memory
# maps a kernel, ~20 for a small jitted function) and keeps them while the program is cached, and
# a pytest-xdist worker runs hundreds of tests. Past the kernel's per-process limit
# (vm.max_map_count, 65530 by default) LLVM's section allocation fails ("LLVM compilation error:
# Cannot allocate memory") and the next compilation kills the worker with a segmentation fault or
# an abort in backend_compile_and_load (docs/testing.md). The compiled programs are released after
# the last test of a file that leaves the process above half the limit (the next file compiles
# its own), or after any test above three quarters (a file's tests share programs; one test has
# added at most ~8,000 maps).
MAP_FRACTION = 0.5
MAP_FRACTION_IN_FILE = 0.75


def memory_maps() -> int:
    """The number of memory maps of this process (0 where /proc is not there)."""
    try:
        with open("/proc/self/maps", "rb") as f:
            return sum(1 for _ in f)
    except OSError:
        return 0


def max_map_count() -> int | None:
    """The kernel's per-process limit on memory maps, None where unknown (not Linux)."""
    try:
        return int(pathlib.Path("/proc/sys/vm/max_map_count").read_text())
    except (OSError, ValueError):
        return None


def release_compiled_programs(limit=None, fraction=MAP_FRACTION) -> bool:
    """Clear JAX's caches of compiled programs (their memory maps go with them) when this process
    holds more than `fraction` of `limit` memory maps (default: vm.max_map_count). -> cleared?"""
    limit = max_map_count() if limit is None else limit
    if not limit or memory_maps() <= fraction * limit:
        return False
    jax.clear_caches()
    gc.collect()
    return True


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_teardown(item, nextitem):
    yield  # after the test's fixtures are torn down
    same_file = nextitem is not None and nextitem.path == item.path
    release_compiled_programs(fraction=MAP_FRACTION_IN_FILE if same_file else MAP_FRACTION)


# The longest tests first: a real pip install into a fresh virtual environment and the executed
# notebooks (each a minute or more). `--dist worksteal` gives each worker a contiguous share of the
# collected order and lets an idle worker take from the end of the other's queue, so what starts
# early is shared out and what sits at the end of a share is not (docs/testing.md).
FIRST = ("test_fresh_venv.py", "test_notebooks.py")


def pytest_collection_modifyitems(session, config, items):
    items.sort(key=lambda item: item.path.name not in FIRST)  # stable: the order is otherwise kept


def pytest_unconfigure(config):
    if RUN_CACHE is not None:  # this process made the run's cache folder: the run is over
        shutil.rmtree(RUN_CACHE, ignore_errors=True)


@contextlib.contextmanager
def compilations():
    """A list that collects the XLA compilations made inside the block (the persistent cache off,
    so that a new program compiles instead of loading from an earlier run's file)."""
    import jax.monitoring as monitoring

    compiles = []
    listener = lambda name, *_, **__: compiles.append(name) if name.endswith("backend_compile_duration") else None
    monitoring.register_event_duration_secs_listener(listener)
    cache = jax.config.jax_enable_compilation_cache
    jax.config.update("jax_enable_compilation_cache", False)
    try:
        yield compiles
    finally:
        jax.config.update("jax_enable_compilation_cache", cache)
        monitoring.unregister_event_duration_listener(listener)


def _float64():
    old = jax.config.jax_enable_x64
    jax.config.update("jax_enable_x64", True)
    yield
    jax.config.update("jax_enable_x64", old)


@pytest.fixture
def x64():
    """Run a test in float64 and restore the previous setting."""
    yield from _float64()


@pytest.fixture(scope="module")
def x64_module():
    """float64 for a whole module (use with pytestmark = pytest.mark.usefixtures("x64_module"))."""
    yield from _float64()


def sphere_with_arm(m, seed=0):
    """Points on a sphere of radius 0.4 with an outlying arm along +x. (m, 3)."""
    rng = np.random.default_rng(seed)
    v = rng.normal(size=(m, 3))
    v *= 0.4 / np.linalg.norm(v, axis=1, keepdims=True)
    k = m // 6
    t = rng.uniform(0, 1, k)
    v[:k] = np.c_[0.4 + 0.5 * t, 0.04 * rng.normal(size=k), 0.04 * rng.normal(size=k)]
    return v


def clusters(m, seed=0):
    """Four Gaussian clusters of different sizes. (m, 3)."""
    rng = np.random.default_rng(seed)
    centers = rng.uniform(-0.5, 0.5, size=(4, 3))
    which = rng.choice(4, size=m, p=[0.4, 0.3, 0.2, 0.1])
    return centers[which] + rng.normal(size=(m, 3)) * np.array([0.08, 0.05, 0.12, 0.03])[which, None]


def box_surface(m, seed=0, extents=(1.0, 0.6, 0.3)):
    """Uniform samples of a box surface (area-weighted faces). (m, 3)."""
    rng = np.random.default_rng(seed)
    e = np.asarray(extents)
    areas = np.array([e[1] * e[2], e[0] * e[2], e[0] * e[1]] * 2)
    face = rng.choice(6, size=m, p=areas / areas.sum())
    p = rng.uniform(-0.5, 0.5, size=(m, 3)) * e
    axis = face % 3
    sign = np.where(face < 3, 0.5, -0.5)
    p[np.arange(m), axis] = sign * e[axis]
    return p


def faust_points(m, index=0, seed=0):
    """Area-weighted samples of a FAUST mesh scaled to the unit cube; skips without ../shared."""
    path = FAUST / f"tr_reg_{index:03d}.ply"
    if not path.exists():
        pytest.skip("../shared/data/faust-dev is not available")
    import trimesh

    mesh = trimesh.load(path, process=False)
    pts = np.asarray(trimesh.sample.sample_surface(mesh, m, seed=seed)[0])
    lo, hi = pts.min(0), pts.max(0)
    return (pts - (lo + hi) / 2) / (hi - lo).max()


def write_mesh_tree(root):
    """A small dataset on disk: nested folders, a point cloud, a corrupt, an empty and a NaN file,
    files that are not meshes, a hidden folder. Returns {"good": [...], "bad": [...]} (paths)."""
    import trimesh

    root = pathlib.Path(root)
    (root / "a" / "b").mkdir(parents=True)
    (root / ".hidden").mkdir()
    capsule = trimesh.creation.capsule(height=1.0, radius=0.4, count=[8, 8])
    capsule.apply_translation([3.0, -1.0, 2.0])
    capsule.export(root / "a" / "capsule.ply")
    box = trimesh.creation.box(extents=(1.0, 0.6, 0.3))
    box.apply_translation([-2.0, 0.5, 0.0])
    box.export(root / "a" / "b" / "box.obj")
    trimesh.creation.icosphere(subdivisions=1, radius=2.0).export(root / "sphere.off")
    rng = np.random.default_rng(0)
    cloud = rng.normal(size=(200, 3)) * [1.0, 0.7, 0.5]
    cloud = cloud / np.linalg.norm(cloud, axis=1, keepdims=True) * [1.0, 0.7, 0.5] + [0.5, 0.0, -1.0]
    trimesh.PointCloud(cloud).export(root / "cloud.ply")
    (root / "a" / "b" / "nan.obj").write_text("v 0 0 0\nv 1 0 0\nv nan 1 0\nv 0 0 1\nf 1 2 3\nf 1 3 4\nf 1 2 4\nf 2 3 4\n")
    (root / "corrupt.ply").write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 99\n\x00\x01")
    (root / "empty.stl").write_bytes(b"")
    (root / "notes.md").write_text("not a mesh")
    box.export(root / ".hidden" / "skip.ply")
    good = [root / "a" / "capsule.ply", root / "a" / "b" / "box.obj", root / "sphere.off", root / "cloud.ply"]
    bad = [root / "a" / "b" / "nan.obj", root / "corrupt.ply", root / "empty.stl"]
    return {"good": good, "bad": bad}
