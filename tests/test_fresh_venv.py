"""The README's and docs/data.md's commands in a FRESH virtual environment: ``python -m venv`` (no
system site packages, no pip) and ``pip install -e`` of this checkout into it (this interpreter's pip,
``pip --python``) with its runtime dependencies only, then each command as a user types it, in a
real subprocess, its output checked against what the README says it does. Long commands run in the
small versions the README documents (``--classes human,chair --instances 3``, one variant). Marked
``venv``: one test, so one install per run whatever the pytest-xdist split (pip's cache and wheel
links make it fast), every command under a timeout; ``-m "not venv"`` leaves it out.
The README's test command (``pip install -e ".[test]" && python -m pytest -q``) is what .ci/run runs."""
from __future__ import annotations

import json
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh

pytestmark = pytest.mark.venv

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()
SMALL = ["--classes", "human,chair", "--instances", "3"]  # the README's small run of `jaxpose evaluate`


def _blocks(lang):
    return re.findall(rf"```{lang}\n(.*?)```", README, flags=re.S)


def test_readme_and_docs_commands_in_a_fresh_venv(tmp_path):
    env = _venv(tmp_path / "venv")
    for step in (_no_test_only_packages, _readme_main_job_small_version, _readme_command_line_block,
                 _readme_python_block, _data_commands_say_where_the_data_comes_from):
        work = tmp_path / step.__name__.strip("_")
        work.mkdir()
        step(env, work)


def _venv(root):
    """(bin folder, environment) of a new venv with this checkout installed (runtime dependencies)."""
    root.mkdir()
    # an empty venv (no pip, no setuptools: ensurepip's copy of pip was ~4.5 CPU s of unpacking and
    # byte-compiling that no command uses); this interpreter's pip installs the checkout into it
    # (`pip --python`: the venv's interpreter and site-packages), resolving its dependencies from
    # pyproject.toml, so the venv holds only jaxpose and what it declares it needs. Where this
    # interpreter has no pip that can (a uv-made environment; pip < 22.3), the venv's own, as before.
    pip = [sys.executable, "-m", "pip", "--python", str(root / "env" / "bin" / "python")] if _pip_python() else None
    subprocess.run([sys.executable, "-m", "venv", *(["--without-pip"] if pip else []), str(root / "env")],
                   check=True, timeout=300)
    bin_dir = root / "env" / "bin"
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV", "PYTHONHOME")}
    # pip byte-compiles every module it installs (jax, scipy, ...: 18 of its 32 CPU s here); with
    # --no-compile the commands compile what they import, once, into a cache inside the venv's folder
    # (PYTHONPYCACHEPREFIX: nothing written into the checkout), the first import ~3 CPU s slower
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    env.update(PATH=f"{bin_dir}{os.pathsep}{env.get('PATH', '')}", VIRTUAL_ENV=str(root / "env"),
               JAXPOSE_DATA=str(root / "no-data"), PYTHONPYCACHEPREFIX=str(root / "pycache"))
    install = subprocess.run([*(pip or [str(bin_dir / "pip")]), "install", "--quiet", "--no-compile", "-e", str(ROOT)],
                             env=env, capture_output=True, text=True, timeout=900)
    if install.returncode != 0:
        pytest.fail(f"pip install -e . failed in a fresh venv:\n{install.stderr[-3000:]}")
    probe = subprocess.run([str(bin_dir / "python"), "-c", "import sys, jaxpose; print(jaxpose.__file__); "
                            "print(sys.flags.no_site, sys.prefix)"], env=env, capture_output=True, text=True,
                           timeout=300)
    assert probe.returncode == 0 and probe.stdout.startswith(str(ROOT / "jaxpose")), probe
    return bin_dir, env


def _pip_python():
    """Whether this interpreter's pip can install into another interpreter (``pip --python``: 22.3)."""
    try:
        from pip import __version__
    except ImportError:
        return False
    return tuple(int(p) for p in re.findall(r"\d+", __version__)[:2]) >= (22, 3)


def _run(venv, command, cwd, timeout=600):
    bin_dir, env = venv
    args = shlex.split(command) if isinstance(command, str) else list(command)
    args[0] = str(bin_dir / args[0])
    return subprocess.run(args, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)


def _no_test_only_packages(venv, tmp_path):
    run = _run(venv, ["python", "-c", "import importlib.util as u; print([m for m in ('sklearn', 'pytest', "
                                      "'distributed', 'pyarrow') if u.find_spec(m)])"], tmp_path)
    assert run.returncode == 0 and run.stdout.strip() == "[]", run


def _readme_main_job_small_version(venv, tmp_path):
    first = _blocks("bash")[0].strip()
    assert first == "pip install -e . && jaxpose evaluate" and "--classes human,chair --instances 3" in README
    assert "`--variants\nplain` for one variant" in README or "`--variants plain` for one variant" in README
    run = _run(venv, ["jaxpose", "evaluate", *SMALL, "--variants", "plain"], tmp_path, timeout=900)
    assert run.returncode == 0, run.stderr[-3000:]
    out, err = run.stdout, run.stderr
    assert out.splitlines()[0].startswith("2 classes x 3 objects") and "gamma=47.0" in out.splitlines()[0]
    for method in ("robust", "ocsvm", "solid_sqrt_area", "surface_centroid", "depth_weighted_solid:4"):
        assert re.search(rf"^{re.escape(method)}\s", out, flags=re.M), method  # the README's table rows
    assert "lower is better" in out and "ms/object" in out and "compilation" in out  # the legend
    assert "jaxpose evaluate: [0/2] plain: first call of each method (compiles)" in err  # progress, piped


def _readme_command_line_block(venv, tmp_path):
    (tmp_path / "scans" / "a").mkdir(parents=True)
    trimesh.creation.capsule(height=1.0, radius=0.4, count=[8, 8]).export(tmp_path / "scans" / "a" / "capsule.ply")
    trimesh.creation.box(extents=(1.0, 0.6, 0.3)).export(tmp_path / "scans" / "box.obj")
    commands = [line.split("#")[0].strip() for line in _blocks("bash")[2].splitlines()]
    commands = [c for c in commands if c]
    assert len(commands) == 5
    for command in commands:
        if command.startswith("jaxpose evaluate"):
            run = _run(venv, shlex.split(command) + SMALL, tmp_path, timeout=900)
            assert run.returncode == 0, run.stderr[-3000:]
            assert "variant holes" in run.stdout and "robust" in run.stdout
            continue
        run = _run(venv, command, tmp_path)
        if "--dask-local" in command:  # the README: "Dask needs pip install "jaxpose[dask]"": refused before any work
            assert run.returncode == 1 and 'jaxpose[dask]' in run.stderr, run
            assert not (tmp_path / "normalized-dask").exists()
            assert 'pip install "jaxpose[dask]"' in README
            continue
        assert run.returncode == 0, (command, run.stderr[-3000:])
    # "also writes normalized.transform.json"; the robust default: center to the origin, volume 1
    record = json.loads((tmp_path / "normalized.transform.json").read_text())
    matrix, center = np.asarray(record["matrix"]), np.asarray(record["center"])
    np.testing.assert_allclose(matrix[:3, :3] @ center + matrix[:3, 3], 0.0, atol=1e-9)
    assert record["method"] == "robust" and json.loads((tmp_path / "paper.transform.json").read_text())["method"] == "ocsvm"
    # "outputs mirror the input tree"; the table (CSV without pyarrow, which a fresh install lacks)
    assert (tmp_path / "normalized" / "a" / "capsule.ply").exists() and (tmp_path / "normalized" / "box.obj").exists()
    assert (tmp_path / "normalized" / "transforms.csv").exists()
    rows = _run(venv, ["python", "-c", "import jaxpose; print(len(jaxpose.read_transforms('normalized')))"], tmp_path)
    assert rows.returncode == 0 and rows.stdout.strip() == "2", rows  # the output folder is accepted


def _readme_python_block(venv, tmp_path):
    (block,) = _blocks("python")
    run = _run(venv, ["python", "-c", block], tmp_path)
    assert run.returncode == 0, run.stderr[-3000:]


def _data_commands_say_where_the_data_comes_from(venv, tmp_path):
    data = (ROOT / "docs" / "data.md").read_text()
    assert "python -m benchmarks.consistency" in data and "python -m benchmarks.data check" in data
    for command in ("python -m benchmarks.consistency --datasets faust-dev", "python -m benchmarks.data check"):
        run = _run(venv, command, ROOT)
        assert run.returncode == 1 and "docs/data.md" in run.stderr, (command, run)
