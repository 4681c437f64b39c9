"""Remote paths: inputs, OUTDIR and tables as fsspec URLs (fsspec's in-memory file system, in
this process) and ``file://`` URLs (local paths, every local guarantee), round-tripping outputs
and the table; without fsspec a clear error naming the extra."""
import os
import sys
import uuid

import numpy as np
import pytest
import trimesh

import jaxpose
from jaxpose.batch import batch
from jaxpose import cli, mesh
from jaxpose.errors import InvalidInputError
from jaxpose.batch.task import NormalizeOptions

from conftest import write_mesh_tree

fsspec = pytest.importorskip("fsspec")
FAST = NormalizeOptions(resolution=16)
TIMING = ("seconds", "worker", "worker_peak_mb")


def stable(rows, prefix):
    return sorted(({k: (v.replace(prefix, "") if isinstance(v, str) else v) for k, v in r._asdict().items()
                    if k not in TIMING} for r in rows), key=lambda d: d["input"])


@pytest.fixture
def memory_scans(tmp_path):
    """The mesh tree of conftest, copied into fsspec's in-memory file system under a fresh name."""
    local = tmp_path / "scans"
    write_mesh_tree(local)
    fs = fsspec.filesystem("memory")
    base = f"/jaxpose-test-{uuid.uuid4().hex}"
    for path in local.rglob("*"):
        if path.is_file():
            fs.pipe_file(f"{base}/scans/{path.relative_to(local).as_posix()}", path.read_bytes())
    yield local, f"memory://{base}"  # memory:///jaxpose-test-..., as fsspec writes it back
    fs.rm(base, recursive=True)


def test_memory_file_system_round_trips_outputs_and_table(tmp_path, memory_scans):
    local, base = memory_scans  # base: memory:///jaxpose-test-...
    fs = fsspec.filesystem("memory")
    remote = batch.run_batch([f"{base}/scans"], f"{base}/out", FAST, workers=1, progress=False)
    reference = batch.run_batch([local], tmp_path / "out", FAST, workers=1, progress=False)
    assert (remote.written, remote.failed) == (4, 3)
    assert str(remote.table) == f"{base}/out/transforms.parquet"
    rows = jaxpose.read_transforms(str(remote.table))  # the table, read back from the store
    assert stable(rows, base) == stable(remote.rows, base)
    ours = stable(remote.rows, base)
    theirs = stable(reference.rows, str(tmp_path))
    for d in ours + theirs:  # a file's time differs between the copies; the rest is the same
        d.pop("input_mtime_ns")
    assert ours == theirs  # the same numbers as the local run
    for row in rows:
        if row.ok:  # each output: the bytes the local run wrote; a PLY one, the input under its row
            relative = row.output.split("/out/", 1)[1]
            data = fs.cat_file(row.output.split("://", 1)[1])
            assert data == (tmp_path / "out" / relative).read_bytes()
            if relative.endswith(".ply"):
                written = trimesh.load(trimesh.util.wrap_as_stream(data), file_type="ply", process=False)
                original = mesh.load(local / row.input.split("/scans/", 1)[1])
                np.testing.assert_array_equal(np.asarray(written.vertices, np.float32),
                                              row.apply(original.vertices).astype(np.float32))
    assert not [p for p in fs.find(base.split("://", 1)[1] + "/out") if p.endswith(".tmp")]
    again = batch.run_batch([f"{base}/scans"], f"{base}/out", FAST, workers=1, progress=False)
    assert (again.written, again.skipped) == (0, 4)  # the remote journal: finished inputs skipped


def test_memory_manifest_shards_and_a_remote_folder_that_is_a_file(tmp_path, memory_scans):
    _, base = memory_scans
    fs = fsspec.filesystem("memory")
    path = base.split("://", 1)[1]
    fs.pipe_file(f"{path}/list.txt", b"scans/a/capsule.ply\nscans/sphere.off\nscans/gone.ply\n")
    result = batch.run_batch([f"{base}/list.txt"], f"{base}/listed", FAST, workers=1, progress=False)
    assert [r.status for r in result.rows] == ["ok", "ok", "failed"] and "no such file" in result.rows[2].error
    shards = [batch.run_batch([f"{base}/scans"], f"{base}/sharded", FAST, workers=1, progress=False, shard=(i, 2))
              for i in range(2)]
    merged = jaxpose.read_transforms(f"{base}/sharded")  # a remote folder of tables
    assert sorted(r.input for r in merged) == sorted(r.input for s in shards for r in s.rows)
    assert len(merged) == 7
    fs.pipe_file(f"{path}/afile", b"mine")
    with pytest.raises(InvalidInputError, match="is a file"):
        batch.run_batch([f"{base}/scans"], f"{base}/afile", FAST, workers=1, progress=False)
    assert fs.cat_file(f"{path}/afile") == b"mine"
    with pytest.raises(InvalidInputError, match="different file systems"):
        batch.run_batch([f"{base}/scans", str(tmp_path / "scans")], tmp_path / "o", FAST, workers=1)


def test_an_earlier_runs_remote_output_folder_inside_the_input_folder_is_not_searched(memory_scans):
    _, base = memory_scans
    scans = f"{base}/scans"
    first = batch.run_batch([scans], f"{scans}/out1", FAST, workers=1, progress=False)
    second = batch.run_batch([scans], f"{scans}/out2", FAST, workers=1, progress=False)
    assert (first.written, second.written) == (4, 4)  # not out1's 4 outputs again
    assert sorted(r.input for r in second.rows) == sorted(r.input for r in first.rows)
    assert not any("/out1/" in r.input for r in second.rows)


def test_file_urls_are_local_paths(tmp_path):
    write_mesh_tree(tmp_path / "scans")
    code = cli.main(["normalize", f"file://{tmp_path}/scans", "-o", f"file://{tmp_path}/out", "--workers", "1",
                     "--resolution", "16"])
    assert code == 1  # the tree's 3 bad files
    rows = jaxpose.read_transforms(f"file://{tmp_path}/out/transforms.parquet")
    assert len(rows) == 7 and all(r.input.startswith(str(tmp_path / "scans")) for r in rows)
    for row in rows:
        if row.ok and row.output.endswith(".ply"):  # PLY holds float32 exactly (OBJ text rounds)
            np.testing.assert_array_equal(mesh.load(row.output).vertices.astype(np.float32),
                                          row.apply(mesh.load(row.input).vertices).astype(np.float32))
    assert (tmp_path / "out" / ".jaxpose" / "lock").exists()  # the local guarantees: lock, journal


def test_without_fsspec_the_error_names_the_extra(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "fsspec", None)  # import fsspec -> ImportError
    with pytest.raises(InvalidInputError, match=r"pip install 'jaxpose\[remote\]'"):
        batch.run_batch(["s3://bucket/scans"], tmp_path / "out", FAST, workers=1)
    with pytest.raises(InvalidInputError, match=r"pip install 'jaxpose\[remote\]'"):
        jaxpose.read_transforms("gs://bucket/out/transforms.parquet")


def test_a_remote_gltf_with_buffer_files_is_named_as_read_alone(tmp_path):
    """A remote .gltf is fetched alone (the buffer files beside it are not): its failed row says so
    and what to do; it named the run's temporary folder as where the buffers were missing."""
    fs = fsspec.filesystem("memory")
    base = f"/jaxpose-test-{uuid.uuid4().hex}"
    files = trimesh.Scene(trimesh.creation.icosphere(subdivisions=1)).export(file_type="gltf")
    try:
        for name, data in files.items():
            fs.pipe_file(f"{base}/g/{name}", data)
        rows = batch.run_batch([f"memory://{base}/g/"], f"memory://{base}/out/", FAST, file_format="glb",
                               workers=1, progress=False).rows
        assert [r.status for r in rows] == ["failed"]
        assert rows[0].error == (f"memory://{base}/g/model.gltf: a remote .gltf is read alone, without the buffer "
                                 "files beside it that it refers to; convert it to .glb (one file), or copy its "
                                 "folder to a local one")
    finally:
        fs.rm(base, recursive=True)


def test_a_remote_output_folder_holding_only_what_file_browsers_leave_is_taken_as_empty(memory_scans):
    """A remote OUTDIR kept the old rule: a .DS_Store alone was "files that jaxpose did not write",
    naming none; now the local folder's rule (batch.journal.check_no_foreign): browser files do not
    count, a file of the user's is named and left as it was."""
    from jaxpose.errors import UsageError

    _, base = memory_scans
    fs = fsspec.filesystem("memory")
    path = base.split("://", 1)[1]
    fs.pipe_file(f"{path}/mine/notes.txt", b"mine")
    fs.pipe_file(f"{path}/mine/.DS_Store", b"x")
    with pytest.raises(UsageError, match=r"did not write \(notes\.txt\)"):
        batch.run_batch([f"{base}/scans/sphere.off"], f"{base}/mine", FAST, workers=1, progress=False)
    assert sorted(p.rpartition("/")[2] for p in fs.ls(f"{path}/mine", detail=False)) == [".DS_Store", "notes.txt"]
    fs.pipe_file(f"{path}/new/.DS_Store", b"x")
    result = batch.run_batch([f"{base}/scans/sphere.off"], f"{base}/new", FAST, workers=1, progress=False)
    assert (result.written, result.failed) == (1, 0)
