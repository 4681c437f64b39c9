"""Command-line habits a new user meets (issue 37.4, 36.2, 36.3): options a method ignores are
refused naming the method they belong to, outputs are checked before any work, folders are made
for single outputs as for datasets, exit codes follow the README (2 usage), a closed pipe ends
quietly, the help describes every option."""
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh

from jaxpose import cli

ROOT = Path(__file__).resolve().parents[1]


def _err(capsys):
    err = capsys.readouterr().err
    assert "Traceback" not in err, err
    return err


@pytest.fixture
def box(tmp_path):
    path = tmp_path / "box.ply"
    trimesh.creation.box(extents=(1.0, 0.6, 0.3)).export(path)
    return path


@pytest.mark.parametrize("extra,named", [(["--count", "5"], "--count"), (["--gamma", "3", "--nu", "0.2"], "--gamma, --nu"),
                                         (["--sampling", "random"], "--sampling"), (["--strict"], "--strict")])
def test_options_the_method_ignores_are_refused(tmp_path, box, capsys, extra, named):
    out = tmp_path / "out.ply"
    assert cli.main(["normalize", str(box), "-o", str(out), *extra]) == 2
    err = _err(capsys)
    assert named in err and "robust" in err and ("ocsvm" in err or "closed-surface" in err), err
    assert not out.exists()


def test_ocsvm_options_with_the_ocsvm_method_and_ocsvm_frame_are_taken(tmp_path, box, capsys):
    out = tmp_path / "out.ply"
    code = cli.main(["normalize", str(box), "-o", str(out), "--method", "ocsvm", "--count", "300", "--gamma", "20"])
    assert code == 0, _err(capsys)
    assert cli.main(["normalize", str(box), "-o", str(tmp_path / "s.ply"), "--method", "surface_centroid",
                     "--count", "300"]) == 2
    assert "surface_centroid" in _err(capsys)


def test_a_mesh_file_name_for_many_inputs_is_refused(tmp_path, box, capsys):
    folder = tmp_path / "scans"
    folder.mkdir()
    box.rename(folder / "box.ply")
    assert cli.main(["normalize", str(folder), "-o", str(tmp_path / "x.ply")]) == 2
    assert "OUTDIR" in _err(capsys)
    assert not (tmp_path / "x.ply").exists()


def test_single_output_folders_are_made_as_for_datasets(tmp_path, box, capsys):
    out = tmp_path / "new" / "deeper" / "out.ply"
    assert cli.main(["normalize", str(box), "-o", str(out), "--method", "surface_centroid"]) == 0, _err(capsys)
    assert out.exists() and (out.parent / "out.transform.json").exists()
    blocker = tmp_path / "file"
    blocker.write_text("x")
    assert cli.main(["normalize", str(box), "-o", str(blocker / "out.ply"), "--method", "surface_centroid"]) == 1
    assert "is a file" in _err(capsys)


def test_dask_without_dask_is_refused_before_any_work(tmp_path, box, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)  # import distributed fails
    folder = tmp_path / "scans"
    folder.mkdir()
    box.rename(folder / "box.ply")
    out = tmp_path / "normalized"
    assert cli.main(["normalize", str(folder), "-o", str(out), "--dask-local", "2"]) == 1
    assert "jaxpose[dask]" in _err(capsys)
    assert not out.exists()  # no table, no .jaxpose/


def test_flat_mesh_error_names_the_command_line_flag(tmp_path, capsys):
    flat = tmp_path / "flat.ply"
    trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], [[0, 1, 2], [0, 2, 3]]).export(flat)
    assert cli.main(["normalize", str(flat), "-o", str(tmp_path / "out.ply")]) == 1
    assert "--method surface_centroid" in _err(capsys)
