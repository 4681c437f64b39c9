"""The host entry points run the robust default on concrete meshes without importing JAX: the
library call in a fresh interpreter (sys.modules), and the batch command's own process and its
worker processes, forked or fresh (``python -X importtime``'s record of every import, through the
environment)."""
from __future__ import annotations

import os
import re
import subprocess
import sys

import numpy as np
import pytest
import trimesh

import jaxpose

from conftest import ROOT


def _env(**extra):
    env = {**os.environ, "PYTHONPATH": str(ROOT), **extra}
    env.pop("JAX_PLATFORMS", None)
    return env


def _meshes(folder, count):
    rng = np.random.default_rng(0)
    for i in range(count):
        mesh = trimesh.creation.icosphere(subdivisions=2)
        mesh.vertices *= rng.uniform(0.5, 2.0, 3)
        mesh.apply_translation(rng.normal(size=3))
        path = folder / f"shape_{i}.{('off', 'ply')[i % 2]}"
        data = mesh.export(file_type=path.suffix[1:])
        path.write_bytes(data.encode() if isinstance(data, str) else data)
    return folder


def test_normalize_mesh_and_normalize_file_import_no_jax(tmp_path):
    _meshes(tmp_path, 1)
    code = ("import sys, jaxpose\n"
            "from jaxpose.batch.task import normalize_file\n"
            f"mesh, pose = jaxpose.normalize_mesh({str(tmp_path / 'shape_0.off')!r})\n"
            f"result = normalize_file({str(tmp_path / 'shape_0.off')!r})\n"
            "assert result.record['status'] == 'ok', result.record\n"
            "assert abs(result.record['scale'] - float(pose.scale)) < 1e-12 * float(pose.scale)\n"
            "print(sorted(m for m in sys.modules if m == 'jax' or m.startswith('jax.')))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=_env(), timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[]"


def _imported(stderr, name):
    """How many processes imported module `name` (one ``import time`` line per process and module)."""
    return len(re.findall(rf"^import time:\s+\d+ \|\s+\d+ \|\s*{re.escape(name)}$", stderr, flags=re.M))


def test_batch_command_and_its_workers_import_no_jax(tmp_path):
    folder = tmp_path / "in"
    folder.mkdir()
    _meshes(folder, 6)
    command = [sys.executable, "-m", "jaxpose", "normalize", str(folder), "-o", str(tmp_path / "out"), "--workers", "2"]
    for forked, threads in ((True, None), (False, "2")):  # OMP_NUM_THREADS=2: fresh interpreters (not forked)
        env = _env(PYTHONPROFILEIMPORTTIME="1")
        for name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
            env.pop(name, None)
        if threads:
            env["OMP_NUM_THREADS"] = threads
        out = subprocess.run([*command[:-3], str(tmp_path / f"out{forked}"), *command[-2:]], capture_output=True,
                             text=True, env=env, timeout=300)
        assert out.returncode == 0, out.stderr[-3000:]
        rows = jaxpose.read_transforms(tmp_path / f"out{forked}")
        assert len(rows) == 6 and all(r.ok for r in rows)
        assert len({r.worker for r in rows}) >= 2  # the workers did some of it
        # plain OFF and PLY files are read, normalized and written as arrays: no process imported
        # trimesh (nor JAX)
        assert _imported(out.stderr, "trimesh") == 0
        assert _imported(out.stderr, "jax") == 0


SURFACE_FILES = {
    "off": lambda m: m.export(file_type="off").encode(),
    "ply": lambda m: m.export(file_type="ply"),
    "ply_ascii": lambda m: m.export(file_type="ply", encoding="ascii"),
    "obj": lambda m: m.export(file_type="obj", include_normals=False, include_texture=False).encode(),
}


@pytest.mark.parametrize("name", sorted(SURFACE_FILES))
@pytest.mark.parametrize("method", ["robust", "surface_centroid", "solid", "bbox", "robust+rotation"])
def test_normalize_file_as_arrays_equals_through_trimesh(tmp_path, monkeypatch, name, method):
    """A plain mesh file goes through the batch as a Surface (no trimesh object): the same output
    bytes, in every output format, and the same table columns as through load's Trimesh."""
    from jaxpose import mesh as jmesh
    from jaxpose.batch.task import NormalizeOptions, normalize_file
    from jaxpose.geometry import Surface

    shape = trimesh.creation.icosphere(subdivisions=2)
    shape.vertices = shape.vertices * [1.0, 0.6, 1.7] + [3.0, -2.0, 0.25]
    path = tmp_path / f"shape.{name.split('_')[0]}"
    path.write_bytes(SURFACE_FILES[name](shape))
    assert isinstance(jmesh.read(path), Surface)
    method, _, rotation = method.partition("+")
    # the robust solid at resolution 48 (incidental: the same code path, head search included, as
    # the default 96, whose rotation took 1.1 s of host CPU per call here, ten calls a test)
    grid = {"resolution": 48} if method == "robust" else {}
    options = NormalizeOptions(method=method, rotation=bool(rotation), **grid)
    for file_type in jmesh.MESH_FORMATS:
        fast = normalize_file(str(path), options, file_type)
        with monkeypatch.context() as patch:
            patch.setattr(jmesh, "read", jmesh.load)  # trimesh objects all along
            slow = normalize_file(str(path), options, file_type)
        assert fast.record["status"] == slow.record["status"] == "ok", (fast.record, slow.record)
        assert fast.data == slow.data, file_type
        same = ("seconds", "worker_peak_mb")
        assert {k: v for k, v in fast.record.items() if k not in same} == \
            {k: v for k, v in slow.record.items() if k not in same}


def test_read_gives_trimesh_where_the_file_holds_more(tmp_path):
    """Colors (and a binary STL's header) stay with trimesh: read gives load's Trimesh."""
    from jaxpose import mesh as jmesh

    shape = trimesh.creation.icosphere(subdivisions=1)
    shape.visual.vertex_colors = np.random.default_rng(1).integers(0, 255, (len(shape.vertices), 4))
    (tmp_path / "colors.ply").write_bytes(shape.export(file_type="ply"))
    (tmp_path / "plain.stl").write_bytes(shape.export(file_type="stl"))
    for name in ("colors.ply", "plain.stl"):
        got = jmesh.read(tmp_path / name)
        assert isinstance(got, trimesh.Trimesh)
        np.testing.assert_array_equal(got.vertices, jmesh.load(tmp_path / name).vertices)


@pytest.mark.parametrize("seed", range(4))
def test_anchor_is_the_vertex_nearest_the_box_middle(seed):
    """host.anchor (column by column) against the plain axis-0 formula it replaces: the same vertex,
    on far-off coordinates, signed zeros, and ties (the first of equally near vertices)."""
    from jaxpose.host import anchor

    rng = np.random.default_rng(seed)
    vertices = rng.normal(size=(5000, 3)) * 10.0 ** rng.integers(-3, 4) + rng.normal(size=3) * 1e6 * (seed % 2)
    if seed == 2:
        vertices = np.round(vertices)  # many vertices equally near the middle
        vertices[:10] = [[0.0, -0.0, 0.0], [-0.0, 0.0, -0.0]] * 5
    middle = 0.5 * (vertices.min(axis=0) + vertices.max(axis=0))
    expected = vertices[int(np.argmin(np.sum((vertices - middle) ** 2, axis=1)))]
    np.testing.assert_array_equal(anchor(vertices).view(np.int64), expected.view(np.int64))  # signed zeros too
    assert anchor(vertices).flags.owndata


def test_anchor_of_coordinates_whose_squares_overflow():
    """Beyond ~1e154 the squared distances overflow: no RuntimeWarning (it was one from every read of
    such a file, before the mesh was refused or rescaled), and a vertex at the middle is still it."""
    from jaxpose.host import anchor

    vertices = np.array([[0.0, 0.0, 0.0], [1e300, 0.0, 0.0], [0.0, 1e300, 0.0], [5e299, 5e299, 0.0]])
    np.testing.assert_array_equal(anchor(vertices), vertices[3])  # (the others' squares are inf)


def test_host_frames_refuse_traced_complex_and_empty_points_by_name():
    """host.host_frame, host.anchor, sizes.pad and rotation.core.frame_solid (host helpers in
    docs/api.md): traced arrays were JAX's TracerArrayConversionError, complex points lost their
    imaginary part (host_frame: a NumPy warning), no vertices NumPy's 'zero-size array to reduction
    operation minimum' (anchor). Refused while tracing: nothing compiles."""
    import jax

    from jaxpose import host
    from jaxpose.pose import sizes
    from jaxpose.rotation import core

    points = trimesh.creation.box().vertices.astype(np.float32)
    for call, name in [(lambda p: host.host_frame(p)[1], "points"), (host.anchor, "vertices"),
                       (lambda p: sizes.pad([p], 16, np.float32)[0], "sets"),
                       (lambda p: core.frame_solid(p, None, 16), "vertices and faces")]:
        with pytest.raises(jaxpose.InvalidInputError, match=f"^{name}: a traced array"):
            jax.jit(call)(points)
    with pytest.raises(jaxpose.InvalidInputError, match="^points must be real numbers, got dtype complex128"):
        host.host_frame(points.astype(complex))
    with pytest.raises(jaxpose.InvalidInputError, match=r"^vertices must have shape \(n >= 1, d\), got \(0, 3\)"):
        host.anchor(np.zeros((0, 3)))
