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
        # forked workers import nothing (the command's process imported trimesh for them); fresh ones
        # import trimesh each; none of the processes imported JAX
        assert _imported(out.stderr, "trimesh") == (1 if forked else 3)
        assert _imported(out.stderr, "jax") == 0
