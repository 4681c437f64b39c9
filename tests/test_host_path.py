"""The host entry points run the robust default on concrete meshes without importing JAX: the
library call in a fresh interpreter (sys.modules), and the batch command's own process and its
worker processes (``python -X importtime``'s record of every import, through the environment)."""
from __future__ import annotations

import os
import re
import subprocess
import sys

import numpy as np
import trimesh

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
    out = subprocess.run(command, capture_output=True, text=True, env=_env(PYTHONPROFILEIMPORTTIME="1"), timeout=300)
    assert out.returncode == 0, out.stderr[-3000:]
    assert len(list((tmp_path / "out").glob("shape_*"))) == 6
    # the command's process and both workers (each imports trimesh) ran; none of them imported JAX
    assert _imported(out.stderr, "trimesh") >= 3
    assert _imported(out.stderr, "jaxpose.batch.pool") >= 3
    assert _imported(out.stderr, "jax") == 0
