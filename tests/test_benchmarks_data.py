"""benchmarks/data.py: the converter lays out downloads as docs/data.md says (real files, real
subprocesses), and a benchmark without its data exits non-zero saying where the data comes from."""
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks import data  # noqa: E402


def _run(*args, env=None):
    return subprocess.run([sys.executable, "-m", *args], cwd=ROOT, capture_output=True, text=True, timeout=300,
                          env={**os.environ, **(env or {})})


def _box(k):
    return trimesh.creation.box(extents=(1.0 + 0.1 * k, 0.6, 0.3))


def test_consistency_without_data_exits_1_and_says_where_it_comes_from(tmp_path):
    r = _run("benchmarks.consistency", "--datasets", "faust-dev", env={"JAXPOSE_DATA": str(tmp_path / "none")})
    assert r.returncode == 1, r
    assert "faust-dev" in r.stderr and "docs/data.md" in r.stderr and str(tmp_path / "none") in r.stderr


def test_check_reports_missing_datasets(tmp_path):
    (tmp_path / "faust-dev").mkdir()
    r = _run("benchmarks.data", "check", "--out", str(tmp_path))
    assert r.returncode == 1 and "faust-dev: present" in r.stdout and "kids-dev: missing" in r.stdout


def test_faust_conversion_keeps_vertex_order_and_faces(tmp_path):
    src = tmp_path / "MPI-FAUST" / "training" / "registrations"
    src.mkdir(parents=True)
    for i in range(20):
        _box(i).export(src / f"tr_reg_{i:03d}.ply")
    r = _run("benchmarks.data", "faust", str(tmp_path / "MPI-FAUST"), "--out", str(tmp_path / "data"))
    assert r.returncode == 0, r.stderr
    out = sorted((tmp_path / "data" / "faust-dev").iterdir())
    assert [p.name for p in out] == [f"tr_reg_{i:03d}.ply" for i in range(20)]
    for i in (0, 19):
        got = trimesh.load(out[i], process=False)
        want = _box(i)
        np.testing.assert_array_equal(got.faces, want.faces)
        np.testing.assert_array_equal(got.vertices, want.vertices.astype(np.float32))
    again = _run("benchmarks.data", "faust", str(tmp_path / "MPI-FAUST"), "--out", str(tmp_path / "data"))
    assert again.returncode != 0 and "exists" in again.stderr  # nothing overwritten without --force


def test_tosca_vert_tri_and_kids_folders(tmp_path):
    src = tmp_path / "tosca"
    src.mkdir()
    mesh = trimesh.creation.icosphere(subdivisions=1)
    for name, numbers in data.TOSCA.items():
        for i in numbers:
            np.savetxt(src / f"{name}{i}.vert", mesh.vertices * (i + 1))
            np.savetxt(src / f"{name}{i}.tri", mesh.faces + 1, fmt="%d")  # TOSCA counts from 1
    kids = tmp_path / "kids"
    for child in ("a", "b"):
        (kids / child).mkdir(parents=True)
        for j in range(16):
            _box(j).export(kids / child / f"shape_{j:02d}.off")
    out = tmp_path / "data"
    assert data.convert_tosca(src, out) == 16 and data.convert_kids(kids, out) == 32
    horse = trimesh.load(out / "tosca-dev" / "horse" / "horse17.ply", process=False)
    np.testing.assert_array_equal(horse.faces, mesh.faces)
    np.testing.assert_allclose(horse.vertices, mesh.vertices * 18, rtol=1e-6)
    pose = trimesh.load(out / "kids-dev" / "kid_0002" / "pose_15.ply", process=False)
    np.testing.assert_allclose(pose.vertices, _box(15).vertices, rtol=1e-6)
    assert data.missing(root=out) == ["faust-dev"]


def test_faust_classes_links_two_people(tmp_path):
    faust = tmp_path / "faust-dev"
    faust.mkdir()
    for i in range(20):
        (faust / f"tr_reg_{i:03d}.ply").write_bytes(b"ply")
    out = data.faust_classes(faust, tmp_path / "people")
    assert sorted(p.name for p in (out / "person_b").iterdir()) == [f"tr_reg_{i:03d}.ply" for i in range(10, 20)]
    assert (out / "person_a" / "tr_reg_000.ply").resolve() == (faust / "tr_reg_000.ply").resolve()


def test_a_download_that_lacks_a_mesh_is_refused(tmp_path):
    with pytest.raises(SystemExit, match="tr_reg_000"):
        data.convert_faust(tmp_path, tmp_path / "out")
