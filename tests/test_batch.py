"""Batch normalization on real files in temporary folders: trees, manifests, bad files, the
transforms table, resuming, the output folder's lock, refusals before any work (in this process,
one worker; processes and Dask in test_workers.py, signals in test_interrupts.py)."""
import json
import logging
import os
from pathlib import Path

import numpy as np
import pytest
import trimesh

import jaxpose
from jaxpose.batch import batch
from jaxpose import cli, mesh
from jaxpose.errors import InvalidInputError, UsageError
from jaxpose.batch.inputs import find_inputs
from jaxpose.batch.journal import FolderBusyError, OutputFolder
from jaxpose.batch.task import NormalizeOptions

from conftest import write_mesh_tree

FAST = NormalizeOptions(resolution=16)  # the robust default on a coarse voxel grid: milliseconds a file
TIMING = ("seconds", "worker", "worker_peak_mb")


@pytest.fixture
def tree(tmp_path):
    return write_mesh_tree(tmp_path / "scans")


def run(inputs, out, **kwargs):
    kwargs.setdefault("workers", 1)
    kwargs.setdefault("progress", False)
    return batch.run_batch(inputs, out, kwargs.pop("options", FAST), **kwargs)


def stable(rows):
    return [{k: v for k, v in row._asdict().items() if k not in TIMING} for row in rows]


def test_folder_tree_outputs_mirror_inputs_and_table_matches_single_files(tmp_path, tree, caplog):
    root = tmp_path / "scans"
    out = tmp_path / "out"
    with caplog.at_level(logging.WARNING, logger="jaxpose.batch"):
        result = run([root], out)
    assert (result.written, result.skipped, result.failed, result.stopped) == (4, 0, 3, False)
    rows = {os.path.relpath(r.input, root): r for r in result.rows}
    assert sorted(rows) == sorted(os.path.relpath(p, root) for p in tree["good"] + tree["bad"])  # no .md, no hidden
    for path in tree["good"]:
        row = rows[os.path.relpath(path, root)]
        assert row.ok and row.output == str(out / path.relative_to(root)) and row.error == ""
        _, pose = jaxpose.normalize_mesh(path, resolution=16)  # the single-file API is the oracle
        np.testing.assert_array_equal(row.center, np.asarray(pose.center))
        assert row.scale == float(pose.scale) and row.valid and row.method == "robust"
        assert row.kind == ("points" if path.name == "cloud.ply" else "mesh")
        assert row.input_size == path.stat().st_size and row.resolution == 16
    for path, fragment in zip(tree["bad"], ["NaN", "cannot read", "empty"]):
        row = rows[os.path.relpath(path, root)]
        assert row.status == "failed" and fragment in row.error and row.output == ""
        assert np.isnan(row.scale) and fragment in caplog.text
    written = sorted(str(p.relative_to(out)) for p in out.rglob("*") if p.is_file() and ".jaxpose" not in p.parts)
    assert written == sorted([str(p.relative_to(root)) for p in tree["good"]] + ["transforms.parquet"])
    assert stable(jaxpose.read_transforms(result.table)) == stable(result.rows)


@pytest.mark.parametrize("suffix", [".parquet", ".csv"])
def test_table_round_trip_is_exact(tmp_path, tree, suffix):
    root, out = tmp_path / "scans", tmp_path / "out"
    table = tmp_path / f"t{suffix}"
    options = NormalizeOptions(resolution=16, rotation=True)
    run([root / "a" / "capsule.ply", root / "cloud.ply"], out, options=options, table=table)
    rows = jaxpose.read_transforms(table)
    assert [r.rotation_method for r in rows] == ["head", "head"]
    for row in rows:
        original = mesh.load(row.input).vertices
        written = mesh.load(row.output).vertices  # trimesh writes PLY coordinates as float32
        np.testing.assert_array_equal(row.apply(original).astype(np.float32), written.astype(np.float32))
        rounding = 2 * np.finfo(np.float32).eps * np.abs(written).max() * row.scale
        np.testing.assert_allclose(row.invert(written), original, rtol=0, atol=rounding)
        np.testing.assert_allclose(row.invert(row.apply(original)), original, rtol=0, atol=1e-13)
        assert np.linalg.det(row.rotation) == pytest.approx(1.0) and 0.0 <= row.ambiguity <= 1.0
        np.testing.assert_allclose(row.matrix @ np.r_[row.center, 1.0], [0, 0, 0, 1], atol=1e-12)


def test_csv_and_parquet_hold_the_same_numbers(tmp_path, tree):
    root = tmp_path / "scans"
    a = run([root], tmp_path / "a", table=tmp_path / "a.csv").rows
    b = run([root], tmp_path / "b", table=tmp_path / "b.parquet").rows
    text = jaxpose.read_transforms(tmp_path / "a.csv")
    for x, y in zip(text, jaxpose.read_transforms(tmp_path / "b.parquet")):
        for name in ("center_x", "center_y", "center_z", "scale"):
            assert repr(getattr(x, name)) == repr(getattr(y, name))  # bit for bit, NaN for failures
    assert [r.status for r in a] == [r.status for r in b]


def test_manifests_text_and_csv(tmp_path, tree):
    root = tmp_path / "scans"
    (tmp_path / "list.txt").write_text("# the meshes\nscans/a/capsule.ply\n\nscans/sphere.off\nscans/missing.ply\n")
    (tmp_path / "list.csv").write_text("id,path\n1,scans/cloud.ply\n2,scans/a/capsule.ply\n")
    result = run([tmp_path / "list.txt", tmp_path / "list.csv"], tmp_path / "out")
    names = [os.path.relpath(r.input, root) for r in result.rows]
    assert names == ["a/capsule.ply", "sphere.off", "missing.ply", "cloud.ply"]  # repeats once, in order
    assert [r.status for r in result.rows] == ["ok", "ok", "failed", "ok"]
    assert "no such file" in result.rows[2].error
    assert (tmp_path / "out" / "a" / "capsule.ply").is_file()  # mirrored from the common folder


def test_glob_and_format(tmp_path, tree):
    root = tmp_path / "scans"
    result = run([root], tmp_path / "out", glob="a/*", file_format="ply")
    assert [os.path.relpath(r.input, root) for r in result.rows] == ["a/capsule.ply", "a/b/box.obj", "a/b/nan.obj"]
    assert isinstance(mesh.load(tmp_path / "out" / "a" / "b" / "box.ply"), trimesh.Trimesh)
    cloud = run([root / "cloud.ply"], tmp_path / "stl", file_format="stl").rows[0]
    assert cloud.status == "failed" and "point cloud cannot be written as STL" in cloud.error
    assert "output format stl (--format / file_type): a point cloud" in cloud.error  # not a made-up 'output.stl'
    assert "output.stl" not in cloud.error
    assert not (tmp_path / "stl" / "cloud.stl").exists()


def test_inputs_of_a_format_jaxpose_does_not_write_are_written_as_glb(tmp_path, tree):
    """A .gltf kept in its own format (no file_format) is written as .glb, the other inputs as
    they were (one .gltf in a folder of meshes refused the whole run, exit 2, and --glob could not
    leave one suffix out; before that, each was read and normalized, then failed 'output.gltf:
    cannot write '.gltf' files'). A model.glb beside it is a second input with that output."""
    root = tmp_path / "scans"
    shape = trimesh.load(root / "sphere.off", process=False)
    (root / "model.gltf").write_bytes(
        trimesh.exchange.gltf.export_gltf(trimesh.Scene(shape), embed_buffers=True)["model.gltf"])
    rows = run([root], tmp_path / "out").rows
    by_name = {os.path.basename(r.input): r for r in rows}
    assert by_name["model.gltf"].status == "ok" and by_name["sphere.off"].status == "ok"
    written = mesh.load(tmp_path / "out" / "model.glb")
    assert isinstance(written, trimesh.Trimesh) and len(written.faces) == len(shape.faces)
    assert not (tmp_path / "out" / "model.gltf").exists()
    (root / "model.glb").write_bytes(b"")
    with pytest.raises(UsageError, match=r"model.gl(b|tf) and .*model.gl(b|tf) would both be written to .*model.glb"):
        run([root], tmp_path / "out2")
    (root / "model.glb").unlink()
    rows = run([root / "model.gltf"], tmp_path / "glb", file_format="glb").rows
    assert [r.status for r in rows] == ["ok"] and (tmp_path / "glb" / "model.glb").is_file()
    (tmp_path / "list.txt").write_text("scans/sphere.off\nnotes\nscans/readme.md\n")  # names of no mesh format
    rows = run([tmp_path / "list.txt"], tmp_path / "listed").rows  # each fails as before, unread
    assert [r.status for r in rows] == ["ok", "failed", "failed"]
    assert "no such file" in rows[1].error and "no such file" in rows[2].error


def test_glob_ignores_case_as_the_suffix_filter_does(tmp_path, tree):
    """A folder search takes SCAN.PLY (suffixes ignore case); --glob "*.ply" left it out."""
    root = tmp_path / "scans"
    upper = root / "a" / "Pose_01.PLY"
    upper.write_bytes((root / "a" / "capsule.ply").read_bytes())
    assert upper in find_inputs([root]).files
    plys = [p for p in find_inputs([root]).files if p.suffix.lower() == ".ply"]  # the oracle: the suffix filter
    for glob in ("*.ply", "*.PLY", "*.Ply"):
        assert find_inputs([root], glob=glob).files == plys, glob
    assert find_inputs([root], glob="pose_0?.ply").files == [upper]
    assert find_inputs([root], glob="A/POSE_*").files == [upper]


def test_a_globstar_stands_for_any_folders_none_too(tmp_path):
    """'**/' is zero or more folders, as in pathlib and shells: '**/*.off' left out the searched
    folder's own files, 'sub/**/*.off' sub's own, and '**/sub/**/*.off' found nothing."""
    root = tmp_path / "scans"
    for name in ("top.off", "sub/s.off", "sub/deep/d.off", "other/o.off"):
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_text("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")
    found = lambda glob: [p.relative_to(root).as_posix() for p in find_inputs([root], glob=glob).files]
    everything = found(None)
    assert found("**/*.off") == everything == found("*.off")
    assert found("sub/**/*.off") == ["sub/s.off", "sub/deep/d.off"] == found("**/sub/**/*.off")
    assert found("**/deep/*.off") == ["sub/deep/d.off"]
    assert found("**/top.off") == ["top.off"]
    # within a name '**/' is two '*' (glob(recursive=True)): 'su**/s.off' took 'sus.off' as 'su' + no folder
    (root / "sus.off").write_text("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")
    assert found("su**/s.off") == ["sub/s.off"]
    assert found("**/su**/s.off") == ["sub/s.off"]


def test_rerun_skips_what_is_done_and_redoes_what_changed(tmp_path, tree):
    root, out = tmp_path / "scans", tmp_path / "out"
    first = run([root], out)
    again = run([root], out)
    assert (again.written, again.skipped, again.failed) == (0, 4, 3)  # failures are tried again
    assert stable(again.rows) == stable(first.rows)
    capsule = root / "a" / "capsule.ply"
    os.utime(capsule, ns=(capsule.stat().st_atime_ns, capsule.stat().st_mtime_ns + 10**9))
    assert run([root], out).written == 1  # a newer modification time: done again
    hashed = run([root], out, check="hash")
    assert hashed.written == 4  # no hash recorded yet
    os.utime(capsule, ns=(capsule.stat().st_atime_ns, capsule.stat().st_mtime_ns + 10**9))
    assert run([root], out, check="hash").written == 0  # same bytes
    assert run([root], out, options=NormalizeOptions(method="robust", resolution=16), check="hash").written == 0  # same
    assert run([root], out, options=NormalizeOptions(method="bbox"), force=True).written == 4  # other options
    records = OutputFolder(out).records()
    assert {r["method"] for r in records.values()} == {"bbox"}


def test_a_rerun_redoes_a_gltf_whose_buffer_file_changed(tmp_path):
    """A .gltf's geometry is in the .bin files it names: a rerun skipped it when only a buffer
    changed (its key was the .gltf's own size and time, or bytes, and the table kept the old
    scale). The key covers the buffers: sizes summed, the latest time, every file's bytes."""
    root, out = tmp_path / "in", tmp_path / "out"
    root.mkdir()
    for name, data in trimesh.creation.box(extents=[1.0, 1.0, 1.0]).export(file_type="gltf").items():
        (root / name).write_bytes(data)
    gltf = root / "model.gltf"
    positions = root / json.loads(gltf.read_text())["buffers"][1]["uri"]
    bbox = NormalizeOptions(method="bbox")
    for check in ("mtime", "hash"):
        first = run([root], out, options=bbox, check=check, force=True)
        assert first.written == 1 and first.rows[0].scale == {"mtime": 1.0, "hash": 3.0}[check]
        assert run([root], out, options=bbox, check=check).skipped == 1
        stamp = positions.stat().st_mtime_ns
        stretched = np.frombuffer(positions.read_bytes(), "<f4") * np.float32(3.0)  # the same size
        positions.write_bytes(stretched.tobytes())
        os.utime(positions, ns=(stamp + 10**9, stamp + (10**9 if check == "mtime" else 0)))  # hash: the same time
        again = run([root], out, options=bbox, check=check)
        assert (again.written, again.skipped) == (1, 0), check
        assert again.rows[0].scale == 3.0 * first.rows[0].scale
    from jaxpose.batch.task import input_key

    key = input_key(gltf, "hash")
    assert key["input_size"] == sum(p.stat().st_size for p in root.iterdir())
    assert key["input_mtime_ns"] == max(p.stat().st_mtime_ns for p in root.iterdir())
    assert input_key(root / "plain.bin", "hash")["input_size"] is None  # not there
    positions.write_bytes(b"")
    assert input_key(gltf, "mtime")["input_size"] == gltf.stat().st_size + (root / "gltf_buffer_0.bin").stat().st_size


def test_a_rerun_redoes_a_file_replaced_with_its_size_and_times_kept(tmp_path):
    """--check mtime: a .gltf's buffer replaced by one of the same size and an older time (cp -p)
    was skipped as done (the .gltf's later time stayed the latest, the size sum the same): each
    file's size and time are in the key, in order (input_stat), and it is redone. A file replaced
    by one of the same size and the same time (cp -p from a copy with the same fixed time, as
    archives give) is the documented limit of --check mtime: skipped; --check hash redoes it. A
    record of an earlier version, without input_stat, is compared by size and time as before."""
    import shutil

    root, out, spare, kept = tmp_path / "in", tmp_path / "out", tmp_path / "spare", tmp_path / "kept"
    root.mkdir()
    spare.mkdir()
    kept.mkdir()
    for name, data in trimesh.creation.box(extents=[1.0, 1.0, 1.0]).export(file_type="gltf").items():
        (root / name).write_bytes(data)
    gltf = root / "model.gltf"
    positions = root / json.loads(gltf.read_text())["buffers"][1]["uri"]
    stamp = gltf.stat().st_mtime_ns
    os.utime(positions, ns=(stamp - 10**10, stamp - 10**10))  # the buffer older than the .gltf
    plain = root / "plain.ply"
    trimesh.creation.box(extents=[1.0, 1.0, 1.0]).export(plain)
    shutil.copy2(plain, kept / plain.name)  # the unit box, its time kept
    bbox = NormalizeOptions(method="bbox")
    first = run([root], out, options=bbox)
    assert first.written == 2 and run([root], out, options=bbox).skipped == 2
    unit = {os.path.basename(r.input): r.scale for r in first.rows}
    stretched = spare / positions.name
    stretched.write_bytes((np.frombuffer(positions.read_bytes(), "<f4") * np.float32(3.0)).tobytes())  # same size
    os.utime(stretched, ns=(stamp - 2 * 10**10, stamp - 2 * 10**10))  # older still
    shutil.copy2(stretched, positions)  # cp -p
    wide = trimesh.creation.box(extents=[2.0, 1.0, 1.0])
    wide.export(spare / plain.name)
    assert (spare / plain.name).stat().st_size == plain.stat().st_size
    times = plain.stat().st_mtime_ns
    os.utime(spare / plain.name, ns=(times, times))  # the same time
    shutil.copy2(spare / plain.name, plain)
    assert plain.stat().st_mtime_ns == times and gltf.stat().st_mtime_ns == stamp
    again = run([root], out, options=bbox)
    assert (again.written, again.skipped) == (1, 1)  # the buffer redone; the .ply: the limit of mtime
    scales = {os.path.basename(r.input): r.scale for r in again.rows}
    assert scales == {"model.gltf": 3.0 * unit["model.gltf"], "plain.ply": unit["plain.ply"]}  # (stale)
    assert run([root], out, options=bbox).skipped == 2
    hashed = run([root], out, options=bbox, check="hash")  # (no hash recorded yet: both)
    assert {os.path.basename(r.input): r.scale for r in hashed.rows}["plain.ply"] == 2.0 * unit["plain.ply"]
    assert run([root], out, options=bbox, check="hash").skipped == 2
    shutil.copy2(kept / plain.name, plain)  # the unit box back: the same size and time
    assert plain.stat().st_mtime_ns == times
    rehashed = run([root], out, options=bbox, check="hash")
    assert (rehashed.written, rehashed.skipped) == (1, 1)  # its bytes differ
    assert {os.path.basename(r.input): r.scale for r in rehashed.rows}["plain.ply"] == unit["plain.ply"]
    assert run([root], out, options=bbox).skipped == 2  # mtime after hash: the same sizes and times
    journal = out / ".jaxpose" / "journal.jsonl"
    lines = [json.loads(line) for line in journal.read_text().splitlines()]
    files = {"model.gltf": [gltf] + sorted(root.glob("*.bin")), "plain.ply": [plain]}  # the .gltf and its buffers
    stats = {name: [[p.stat().st_size, p.stat().st_mtime_ns] for p in paths] for name, paths in files.items()}
    latest = {os.path.basename(r["input"]): r["input_stat"] for r in lines if r["status"] == "ok"}
    assert latest["plain.ply"] == stats["plain.ply"]
    assert latest["model.gltf"][0] == stats["model.gltf"][0]  # the .gltf, then its buffers
    assert sorted(latest["model.gltf"]) == sorted(stats["model.gltf"])
    # an earlier version's records: no input_stat, compared by the sum and the latest time
    journal.write_text("".join(json.dumps({k: v for k, v in r.items() if k != "input_stat"}) + "\n" for r in lines))
    assert run([root], out, options=bbox).skipped == 2


def test_a_rerun_under_mtime_redoes_nothing_for_a_move_a_chmod_or_a_hard_link(tmp_path):
    """--check mtime compares sizes and modification times only: the input folder moved elsewhere
    on the same filesystem and back, each file moved away and back (its status-change time moves,
    its inode stays), a chmod and a new hard link (status-change time) redo nothing. They redid
    every input when the key held the inode number and status-change time."""
    import stat

    root, out, away = tmp_path / "in", tmp_path / "out", tmp_path / "away"
    root.mkdir()
    away.mkdir()
    for name, data in trimesh.creation.box(extents=[1.0, 1.0, 1.0]).export(file_type="gltf").items():
        (root / name).write_bytes(data)
    trimesh.creation.box(extents=[2.0, 1.0, 1.0]).export(root / "plain.ply")
    bbox = NormalizeOptions(method="bbox")
    first = run([root], out, options=bbox)
    assert first.written == 2
    files = sorted(root.iterdir())
    before = {p.name: p.stat() for p in files}
    os.rename(root, tmp_path / "moved")  # the folder elsewhere, and back
    os.rename(tmp_path / "moved", root)
    for path in files:  # each file away and back: a new status-change time, the same inode
        os.rename(path, away / path.name)
        os.rename(away / path.name, path)
    for path in files:
        path.chmod(0o600 if stat.S_IMODE(path.stat().st_mode) != 0o600 else 0o644)
    os.link(root / "plain.ply", away / "plain.ply")
    os.link(root / "model.gltf", away / "model.gltf")
    now = {p.name: p.stat() for p in files}
    assert all(now[n].st_ino == before[n].st_ino and now[n].st_ctime_ns != before[n].st_ctime_ns for n in now)
    assert all((now[n].st_size, now[n].st_mtime_ns) == (before[n].st_size, before[n].st_mtime_ns) for n in now)
    again = run([root], out, options=bbox)
    assert (again.written, again.skipped, again.failed) == (0, 2, 0)
    assert stable(again.rows) == stable(first.rows)


def _good_dataset_done(data, options):
    """write_mesh_tree's good files under data/scans (the bad ones would be done again on every
    run), run into data/out: the run's result (3 written)."""
    import shutil

    write_mesh_tree(data / "scans")
    shutil.rmtree(data / "scans" / "a" / "b")
    for name in ("corrupt.ply", "empty.stl"):
        (data / "scans" / name).unlink()
    first = run([data / "scans"], data / "out", options=options)
    assert (first.written, first.failed) == (3, 0)
    return first


def test_a_dataset_moved_with_its_output_folder_resumes_where_it_was(tmp_path):
    """Inputs and OUTDIR moved together (``mv data data2``), each file's size and modification time
    kept: a rerun skips what is done, the table names the files where they are now, the one option
    set per OUTDIR still holds, and a run over part of the inputs keeps the others' rows. The
    journal named absolute paths: the moved dataset was done again from the start, a run with
    other options was not refused, and a run over part of it wrote a table without the other
    outputs' rows. The same for a journal an earlier version wrote (no ``outdir`` field), and for
    an OUTDIR moved alone (its inputs where they were)."""
    bbox = NormalizeOptions(method="bbox")
    first = _good_dataset_done(tmp_path / "data", bbox)

    def moved(rows, old, new):
        return [{**row, "input": row["input"].replace(str(old), str(new)), "output": row["output"].replace(str(old), str(new))}
                for row in stable(rows)]

    data = tmp_path / "data2"
    os.rename(tmp_path / "data", data)
    again = run([data / "scans"], data / "out", options=bbox)
    assert (again.written, again.skipped, again.failed) == (0, 3, 0)
    assert stable(again.rows) == moved(first.rows, tmp_path / "data", data)
    assert all(Path(row.output).is_file() and Path(row.input).is_file() for row in again.rows)
    with pytest.raises(UsageError, match="--method bbox there, robust here"):
        run([data / "scans"], data / "out")
    part = run([data / "scans"], data / "out", options=bbox, glob="a/*")
    assert (part.written, part.skipped) == (0, 1) and sorted(stable(part.rows), key=str) == sorted(
        stable(again.rows), key=str)  # the other outputs' rows kept
    journal = data / "out" / ".jaxpose" / "journal.jsonl"
    lines = [json.loads(line) for line in journal.read_text().splitlines()]
    assert [line["outdir"] for line in lines] == [str(tmp_path / "data" / "out")] * 3 + [str(data / "out")] * 3
    assert sorted(line["input"] for line in lines[3:]) == sorted(str(data / "scans" / Path(line["input"]).relative_to(
        tmp_path / "data" / "scans")) for line in lines[:3])  # where they were written; then adopted here, for good
    journal.write_text("".join(json.dumps({k: v for k, v in r.items() if k != "outdir"}) + "\n" for r in lines[:3]))
    older = tmp_path / "data3"
    os.rename(data, older)  # an earlier version's journal, moved
    assert run([older / "scans"], older / "out", options=bbox).skipped == 3
    assert run([older / "scans"], older / "out", options=bbox, force=True).written == 3  # records written here
    os.rename(older / "out", tmp_path / "elsewhere")  # OUTDIR alone: its inputs stay
    alone = run([older / "scans"], tmp_path / "elsewhere", options=bbox)
    assert (alone.written, alone.skipped) == (0, 3)
    assert {row.input for row in alone.rows} == {row["input"] for row in moved(first.rows, tmp_path / "data", older)}
    # moved whole, then one file changed: that one is done again (its path says it is that input), as
    # where nothing moved; the others are skipped (was refused: "is not that file moved ... --force")
    os.rename(tmp_path / "elsewhere", older / "out")
    os.rename(older, tmp_path / "data4")
    scans4 = tmp_path / "data4" / "scans"
    inputs = sorted(scans4 / Path(row["input"]).relative_to(tmp_path / "data" / "scans") for row in stable(first.rows))
    trimesh.creation.box(extents=(1.0, 2.0, 3.0)).export(inputs[0], file_type=inputs[0].suffix[1:])
    redo = run([scans4], tmp_path / "data4" / "out", options=bbox)
    assert (redo.written, redo.skipped, redo.failed) == (1, 2, 0)
    assert sorted(Path(row.input) for row in redo.rows) == inputs


def test_a_dataset_copied_with_its_output_folder_resumes_and_redoes_what_changed(tmp_path):
    """``cp -a data data2`` (sizes and times kept): the copy's inputs are skipped as done; in a copy
    with one input edited before its first run, that one is done again, the others skipped, as in a
    dataset moved whole. It was refused
    ("holds the output of data/scans/x.ply ..., not of data2/scans/x.ply"): the recorded input is
    still there (the original), and only --force, which redoes the whole dataset, went on."""
    import shutil

    bbox = NormalizeOptions(method="bbox")
    first = _good_dataset_done(tmp_path / "data", bbox)
    shutil.copytree(tmp_path / "data", tmp_path / "data2", symlinks=True)  # copy2: sizes and times kept
    shutil.copytree(tmp_path / "data", tmp_path / "data3", symlinks=True)
    scans = tmp_path / "data2" / "scans"
    again = run([scans], tmp_path / "data2" / "out", options=bbox)
    assert (again.written, again.skipped, again.failed) == (0, 3, 0)
    scans = tmp_path / "data3" / "scans"  # a copy edited before its first run
    inputs = sorted(scans / Path(row["input"]).relative_to(tmp_path / "data" / "scans") for row in stable(first.rows))
    trimesh.creation.box(extents=(1.0, 2.0, 3.0)).export(inputs[0], file_type=inputs[0].suffix[1:])
    redo = run([scans], tmp_path / "data3" / "out", options=bbox)
    assert (redo.written, redo.skipped, redo.failed) == (1, 2, 0)
    assert sorted(Path(row.input) for row in redo.rows) == inputs
    assert run([tmp_path / "data" / "scans"], tmp_path / "data" / "out", options=bbox).skipped == 3  # the original


def test_an_input_folder_renamed_is_recognized_by_its_files_size_and_time(tmp_path):
    """The input folder renamed (``mv scans scans2``), OUTDIR where it was: each output's recorded
    input is gone, and this run's input for it (the same path relative to the inputs' root) has
    the record's size and modification time: it is that input, skipped, and the table names it
    where it is. The run was refused ("holds the output of scans/x.ply ..., not of
    scans2/x.ply"). A file changed since is refused, saying why and what to do."""
    bbox = NormalizeOptions(method="bbox")
    scans, out = tmp_path / "scans", tmp_path / "out"
    write_mesh_tree(scans)
    first = run([scans], out, options=bbox)
    assert (first.written, first.failed) == (4, 3)
    os.rename(scans, tmp_path / "scans2")
    scans = tmp_path / "scans2"
    again = run([scans], out, options=bbox)
    assert (again.written, again.skipped, again.failed) == (0, 4, 3)
    assert sorted((r.input, r.output) for r in again.rows if r.ok) == sorted(
        (r.input.replace(str(tmp_path / "scans"), str(scans)), r.output) for r in first.rows if r.ok)
    hashed = run([scans], out, options=bbox, check="hash")  # records without a SHA-256: done again, not refused
    assert (hashed.written, hashed.skipped) == (4, 0)
    assert run([scans], out, options=bbox, check="hash").skipped == 4
    os.rename(scans, tmp_path / "scans3")
    scans = tmp_path / "scans3"
    trimesh.creation.box(extents=(1.0, 2.0, 3.0)).export(scans / "sphere.off")  # changed since
    with pytest.raises(UsageError, match=r"sphere.off holds the output of .*scans2/sphere.off \(an earlier run into this "
                                         r"folder\), which is no longer there; .*scans3/sphere.off, this run's input for "
                                         r"that output, is not that file moved \(it differs from the record.*use --force"):
        run([scans], out, options=bbox)
    forced = run([scans], out, options=bbox, force=True)
    assert forced.written == 4 and {os.path.relpath(r.input, scans) for r in forced.rows if r.ok} == {
        "a/capsule.ply", "a/b/box.obj", "sphere.off", "cloud.ply"}


def test_an_output_folder_moved_alone_keeps_its_inputs_beside_a_folder_of_the_same_layout(tmp_path):
    """OUTDIR moved alone (``data/out`` -> ``archive/out``) beside a folder of the same layout
    (``archive/scans/a.ply``, another file): its records' inputs are still where they were, so a
    rerun of them skips them, and a run of another input keeps their rows naming them. The journal
    took any file at the same path relative to OUTDIR for the input: the rerun was refused ('holds
    the output of archive/scans/a.ply ..., not of data/scans/a.ply'), and the other run's table
    named archive/scans/a.ply for data/scans/a.ply's output."""
    bbox = NormalizeOptions(method="bbox")
    scans = tmp_path / "data" / "scans"
    scans.mkdir(parents=True)
    for i, name in enumerate(["a.ply", "b.ply"]):
        trimesh.creation.box(extents=(1.0 + i, 2.0, 3.0)).export(scans / name)
    first = run([scans], tmp_path / "data" / "out", options=bbox)
    assert first.written == 2
    (tmp_path / "archive" / "scans").mkdir(parents=True)
    trimesh.creation.box(extents=(7.0, 7.0, 7.0)).export(tmp_path / "archive" / "scans" / "a.ply")
    out = tmp_path / "archive" / "out"
    os.rename(tmp_path / "data" / "out", out)
    again = run([scans], out, options=bbox)
    assert (again.written, again.skipped, again.failed) == (0, 2, 0)
    assert sorted((r.input, r.output) for r in again.rows) == [(str(scans / n), str(out / n)) for n in ("a.ply", "b.ply")]
    other = tmp_path / "new"
    other.mkdir()
    trimesh.creation.box(extents=(5.0, 2.0, 3.0)).export(other / "c.ply")
    more = run([other], out, options=bbox)
    assert more.written == 1
    assert sorted((r.input, r.output) for r in more.rows) == [
        (str(scans / "a.ply"), str(out / "a.ply")), (str(scans / "b.ply"), str(out / "b.ply")),
        (str(other / "c.ply"), str(out / "c.ply"))]
    with pytest.raises(UsageError, match=r"out/a.ply holds the output of .*data/scans/a.ply \(an earlier run into this "
                                         r"folder\), not of .*archive/scans/a.ply"):
        run([tmp_path / "archive" / "scans"], out, options=bbox)  # another file there: not taken for it


def test_a_journal_is_read_one_record_per_pair_before_it_is_rebased(tmp_path, monkeypatch):
    """Reading a journal keeps one record per (input, output) pair as it reads (the latest), and
    rebases those, not every line: a folder rerun 10 times held all its lines at once (200k lines
    of 20k pairs: peak 903 MiB, now 120 MiB). The result is the same: the latest of each pair,
    in the order written, rebased."""
    from jaxpose.batch import journal

    state = tmp_path / "out" / ".jaxpose"
    state.mkdir(parents=True)
    lines = [{"input": f"/x/{i}.ply", "output": f"/old/out/{i}.ply", "outdir": "/old/out", "status": "ok", "n": n}
             for n in range(10) for i in range(3)]
    (state / "journal.jsonl").write_text("".join(json.dumps(line) + "\n" for line in lines) + '{"torn')
    seen = []
    rebase = journal.rebase
    monkeypatch.setattr(journal, "rebase", lambda records, outdir: seen.append(len(records)) or rebase(records, outdir))
    read = journal._read_journal(state / "journal.jsonl", str(tmp_path / "out"))
    assert seen == [3]
    assert [(r["input"], r["output"], r["n"]) for r in read] == [
        (f"/x/{i}.ply", str(tmp_path / "out" / f"{i}.ply"), 9) for i in range(3)]


def test_an_earlier_versions_records_naming_outdir_through_a_link_are_not_taken_for_moved(tmp_path):
    """An earlier version's records (no ``outdir``) whose outputs name OUTDIR through a link to it
    (``d/e/link`` -> ``out``, as versions before its real path recorded them) were written in OUTDIR,
    not in a folder it moved from (journal.former_folder: their folder's real path is inside it): a
    copy of the inputs (``scans``, the same sizes and times) at the same path relative to OUTDIR as
    the recorded ones (``d/e/scans``) to the link is not taken for them, and the outputs stay
    theirs. Taken for a moved folder (the link), the copy was adopted and the outputs named it."""
    import shutil

    from jaxpose.batch import journal

    bbox = NormalizeOptions(method="bbox")
    scans, out, link = tmp_path / "d" / "e" / "scans", tmp_path / "out", tmp_path / "d" / "e" / "link"
    for i, name in enumerate(["a.ply", "b.ply"]):
        (scans / name).parent.mkdir(parents=True, exist_ok=True)
        trimesh.creation.box(extents=(1.0 + i, 2.0, 3.0)).export(scans / name)
    assert run([scans], out, options=bbox).written == 2
    link.symlink_to(out)
    path = out / ".jaxpose" / "journal.jsonl"
    lines = [json.loads(line) for line in path.read_text().splitlines()]
    path.write_text("".join(json.dumps({**{k: v for k, v in r.items() if k != "outdir"},
                                        "output": r["output"].replace(str(out), str(link))}) + "\n" for r in lines))
    assert journal.former_folder([str(link / "a.ply"), str(link / "b.ply")], str(out)) is None
    copy = tmp_path / "scans"
    shutil.copytree(scans, copy)  # (copy2: sizes and times kept)
    with pytest.raises(UsageError, match=r"out/a.ply holds the output of .*d/e/scans/a.ply \(an earlier run into this "
                                         r"folder\), not of .*/scans/a.ply"):
        run([copy], out, options=bbox)
    again = run([scans], out, options=bbox)
    assert (again.written, again.skipped) == (0, 2)
    assert sorted((r.input, r.output) for r in again.rows) == [(str(scans / n), str(out / n)) for n in ("a.ply", "b.ply")]


def test_a_renamed_input_folder_is_adopted_for_good(tmp_path):
    """After ``mv scans scans2`` a run adopts the renamed inputs (their records re-appended under
    their new paths): a later run over part of them (``glob``) writes the others' rows naming them
    where they are. The adoption lasted one run: that table named scans/b/z.ply, gone."""
    bbox = NormalizeOptions(method="bbox")
    scans, out = tmp_path / "scans", tmp_path / "out"
    for i, name in enumerate(["a/x.ply", "a/y.ply", "b/z.ply"]):
        (scans / name).parent.mkdir(parents=True, exist_ok=True)
        trimesh.creation.box(extents=(1.0 + i, 2.0, 3.0)).export(scans / name)
    assert run([scans], out, options=bbox).written == 3
    scans2 = tmp_path / "scans2"
    os.rename(scans, scans2)
    assert run([scans2], out, options=bbox).skipped == 3
    part = run([scans2], out, options=bbox, glob="a/*")
    assert (part.written, part.skipped) == (0, 2)
    assert sorted(r.input for r in part.rows) == [str(scans2 / n) for n in ("a/x.ply", "a/y.ply", "b/z.ply")]
    assert run([scans2], out, options=bbox).skipped == 3


def test_an_input_rewritten_with_its_size_and_time_while_read_is_changed(tmp_path):
    """An input rewritten in place while it is read, its size the same and its modification time
    set back (cp -p over it): 'its status changed while it was read' (size, time and inode were the
    same: the bytes read passed as the file's). Its status-change time moved, and only that: the
    message says so, as for a chmod or a new hard link during the read (it read 'size 10 -> 10
    bytes', no difference named)."""
    import time

    from jaxpose.batch.task import _check_unchanged, _input_stat
    from jaxpose.errors import InvalidInputError

    path = tmp_path / "a.off"
    path.write_bytes(b"OFF\n0 0 0\n")
    before = _input_stat(path, "mtime")
    time.sleep(0.05)  # (file times move by the kernel's tick)
    info = path.stat()
    path.write_bytes(b"OFF\n1 1 1\n")
    os.utime(path, ns=(info.st_atime_ns, info.st_mtime_ns))
    status = (r"a.off: its status changed while it was read: rewritten keeping its size and time, or its permissions "
              r"or links changed; run again to read it whole$")
    with pytest.raises(InvalidInputError, match=status):
        _check_unchanged(path, before)
    for change in (lambda: path.chmod(0o600), lambda: os.link(path, tmp_path / "b.off")):  # the bytes as they were
        before = _input_stat(path, "mtime")
        time.sleep(0.05)
        change()
        with pytest.raises(InvalidInputError, match=status):
            _check_unchanged(path, before)
    before = _input_stat(path, "mtime")  # the same size, a later time: named
    time.sleep(0.05)
    path.write_bytes(b"OFF\n2 2 2\n")
    with pytest.raises(InvalidInputError, match=r"changed while it was read \(size 10 bytes, its modification time moved\)"):
        _check_unchanged(path, before)
    before = _input_stat(path, "mtime")  # another size: named
    path.write_bytes(b"OFF\n1 1 1\n\n")
    with pytest.raises(InvalidInputError, match=r"changed while it was read \(size 10 -> 11 bytes\)"):
        _check_unchanged(path, before)


def test_a_gltf_whose_buffers_are_not_a_list_of_objects_fails_alone(tmp_path, tree):
    """A .gltf whose "buffers" is not a list of objects (5; [5]) fails by itself, named by its read:
    the plan's key raised TypeError ('int' object is not iterable) and the whole run died."""
    from jaxpose.batch.task import gltf_buffers, input_key

    gltf = tmp_path / "broken.gltf"
    for bad in (5, [5], {"uri": "a.bin"}):
        gltf.write_text(json.dumps({"asset": {"version": "2.0"}, "buffers": bad}))
        assert gltf_buffers(gltf) == [] and input_key(gltf, "hash")["input_size"] == gltf.stat().st_size
    result = run([*tree["good"], gltf], tmp_path / "out")
    assert (result.written, result.failed) == (len(tree["good"]), 1)
    assert [r.input for r in result.rows if r.status == "failed"] == [str(gltf)]


def test_a_gltf_buffer_is_the_file_trimesh_reads(tmp_path):
    """The rerun key watches the buffer file the reader opens: the name taken literally
    (``pos%41.bin``, not ``posA.bin``), then without a leading '/', then its last part; never one
    out of the folder (pinned here name by name; jaxpose's resolver reads by that rule on every
    trimesh, and trimesh 5's own FilePathResolver.get agrees; 4's opened ``../outside.bin``)."""
    from trimesh.resolvers import FilePathResolver

    from jaxpose.batch.task import _buffer_file, gltf_buffers
    from jaxpose.io.mesh import _gltf_resolver

    root = tmp_path / "in"
    (root / "sub").mkdir(parents=True)
    for name in ("pos%41.bin", "posA.bin", "b.bin", "sub/c.bin"):
        (root / name).write_bytes(name.encode())
    (tmp_path / "outside.bin").write_bytes(b"outside")
    expected = {"pos%41.bin": "pos%41.bin", "posA.bin": "posA.bin", "/b.bin": "b.bin", " b.bin ": "b.bin",
                "x/b.bin": "b.bin", "sub/c.bin": "sub/c.bin", "c.bin": None, "sub/../b.bin": "b.bin",
                "../outside.bin": None, "../in/b.bin": "b.bin", "missing.bin": None, "x/missing.bin": None}
    readers = [_gltf_resolver(root / "model.gltf")]
    if int(trimesh.__version__.split(".")[0]) >= 5:
        readers.append(FilePathResolver(str(root / "model.gltf")))
    for name, file in expected.items():
        found = _buffer_file(root, name)
        assert (found and found.read_bytes()) == (file and file.encode()), name
        for resolver in readers:
            try:
                read = resolver.get(name)
            except (FileNotFoundError, ValueError):
                read = None
            assert read == (file and file.encode()), (name, resolver)
    gltf = root / "model.gltf"
    gltf.write_text(json.dumps({"asset": {"version": "2.0"}, "buffers": [{"uri": "pos%41.bin"}, {"uri": "data:,"}]}))
    assert gltf_buffers(gltf) == [root / "pos%41.bin"]


def _unblocked(call, fifos, seconds):
    """call() in a daemon thread -> (whether it was still running after `seconds`, its value). One
    still running (waiting in open() on one of `fifos`) is let go: writers that close at once, until
    it returns, so that the test ends either way."""
    import threading

    done = []
    thread = threading.Thread(target=lambda: done.append(call()), daemon=True)
    thread.start()
    thread.join(seconds)
    blocked = thread.is_alive()
    while thread.is_alive():
        for fifo in fifos:
            try:
                os.close(os.open(fifo, os.O_WRONLY | os.O_NONBLOCK))
            except OSError:  # no reader left
                pass
        thread.join(1)
    return blocked, done[0] if done else None


def test_a_gltf_buffer_that_is_a_fifo_is_never_opened(tmp_path):
    """input_key(..., "hash") of a .gltf naming a FIFO as its buffer leaves it out (it hashed it:
    blocked until a writer came), as it does an input that is a FIFO."""
    from jaxpose.batch.task import input_key

    gltf, fifo = tmp_path / "model.gltf", tmp_path / "fifo.bin"
    gltf.write_text(json.dumps({"asset": {"version": "2.0"}, "buffers": [{"uri": "fifo.bin", "byteLength": 4}]}))
    os.mkfifo(fifo)
    blocked, key = _unblocked(lambda: input_key(gltf, "hash"), [fifo], 10)
    assert not blocked and key["input_size"] == gltf.stat().st_size


def test_a_gltf_whose_buffer_file_is_a_fifo_fails_unread(tmp_path):
    """A .gltf beside a FIFO as its buffer file (a link to one too), in a batch (one worker, no
    time limit) and read alone: the buffer is refused by name before it is opened (trimesh's
    resolver opened it and waited for a writer, for ever); the other inputs are done."""
    root, out = tmp_path / "in", tmp_path / "out"
    (root / "sub").mkdir(parents=True)
    for name, data in trimesh.creation.box().export(file_type="gltf").items():
        (root / "sub" / name).write_bytes(data)
    good = root / "box.ply"
    trimesh.creation.box().export(good)
    gltf = root / "sub" / "model.gltf"
    positions = root / "sub" / json.loads(gltf.read_text())["buffers"][1]["uri"]
    positions.unlink()
    (root / "sub" / "pipes").mkdir()
    pipe = root / "sub" / "pipes" / "fifo.bin"
    os.mkfifo(pipe)
    os.symlink(os.path.join("pipes", "fifo.bin"), positions)  # a link to a FIFO
    linked = root / "sub" / "linked.gltf"
    tree = json.loads(gltf.read_text())
    tree["buffers"][0]["uri"] = "fifo0.bin"
    linked.write_text(json.dumps(tree))
    os.mkfifo(root / "sub" / "fifo0.bin")  # the buffer itself a FIFO
    blocked, result = _unblocked(lambda: run([root], out, options=NormalizeOptions(method="bbox")),
                                 [pipe, root / "sub" / "fifo0.bin"], 60)
    assert not blocked, "the run waited on a FIFO buffer"
    rows = {os.path.relpath(r.input, root): r for r in result.rows}
    assert rows["box.ply"].ok and (result.written, result.failed) == (1, 2)
    assert rows["sub/model.gltf"].error == (
        f"{gltf}: the file '{positions.name}' it refers to ({pipe}) is a FIFO, not a regular file: "
        "a .gltf's buffer files are read as regular files only (it was not opened)")
    assert f"the file 'fifo0.bin' it refers to ({root / 'sub' / 'fifo0.bin'}) is a FIFO" in rows["sub/linked.gltf"].error
    with pytest.raises(InvalidInputError, match="fifo0.bin.* is a FIFO, not a regular file"):
        mesh.load(linked)  # read alone: the same refusal


def _textured_gltf(folder, image="tex.png"):
    """A box .gltf in `folder` with its geometry in model.bin and a texture image file `image`
    (PNG) named by URI: -> the .gltf's path."""
    import io

    from PIL import Image

    folder.mkdir(parents=True, exist_ok=True)
    box = trimesh.creation.box(extents=(1.0, 2.0, 3.0))
    v, f = box.vertices.astype(np.float32), box.faces.astype(np.uint32)
    uv = (np.abs(box.vertices[:, :2]) % 1).astype(np.float32)
    blob = v.tobytes() + f.tobytes() + uv.tobytes()
    (folder / "model.bin").write_bytes(blob)
    png = io.BytesIO()
    Image.new("RGB", (4, 4), (200, 30, 30)).save(png, "PNG")
    (folder / image).write_bytes(png.getvalue())
    views = [(0, v.nbytes), (v.nbytes, f.nbytes), (v.nbytes + f.nbytes, uv.nbytes)]
    tree = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 2}, "indices": 1, "material": 0}]}],
            "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}],
            "textures": [{"source": 0}], "images": [{"uri": image}],
            "buffers": [{"uri": "model.bin", "byteLength": len(blob)}],
            "bufferViews": [{"buffer": 0, "byteOffset": o, "byteLength": n} for o, n in views],
            "accessors": [{"bufferView": 0, "componentType": 5126, "count": len(v), "type": "VEC3",
                           "min": v.min(0).tolist(), "max": v.max(0).tolist()},
                          {"bufferView": 1, "componentType": 5125, "count": f.size, "type": "SCALAR"},
                          {"bufferView": 2, "componentType": 5126, "count": len(v), "type": "VEC2"}]}
    (folder / "model.gltf").write_text(json.dumps(tree))
    return folder / "model.gltf"


def test_a_gltf_whose_texture_image_is_a_fifo_fails_unread(tmp_path):
    """A .gltf whose texture image file is a FIFO (or a link to one) is refused by name, as one
    whose buffer is, never opened: trimesh's reader skips an image it cannot read, so the .gltf
    was read without its texture and its .glb written without it, without a word. A regular image
    is read (the texture is in the output)."""
    root, out = tmp_path / "in", tmp_path / "out"
    _textured_gltf(root / "ok")
    gltf = _textured_gltf(root / "pipe")
    image = root / "pipe" / "tex.png"
    image.unlink()
    os.mkfifo(image)
    linked = _textured_gltf(root / "linked")
    (root / "linked" / "tex.png").unlink()
    (root / "linked" / "pipes").mkdir()
    os.mkfifo(root / "linked" / "pipes" / "fifo.png")
    os.symlink(os.path.join("pipes", "fifo.png"), root / "linked" / "tex.png")  # a link to a FIFO
    blocked, result = _unblocked(lambda: run([root], out, options=NormalizeOptions(method="bbox")),
                                 [image, root / "linked" / "pipes" / "fifo.png"], 60)
    assert not blocked, "the run waited on a FIFO image"
    rows = {os.path.relpath(r.input, root): r for r in result.rows}
    assert rows["ok/model.gltf"].ok and (result.written, result.failed) == (1, 2)
    written = trimesh.load(rows["ok/model.gltf"].output)
    assert [part.visual.material.baseColorTexture.size for part in written.geometry.values()] == [(4, 4)]
    assert rows["pipe/model.gltf"].error == (
        f"{gltf}: the file 'tex.png' it refers to ({image}) is a FIFO, not a regular file: "
        "a .gltf's image files are read as regular files only (it was not opened)")
    assert f"the file 'tex.png' it refers to ({root / 'linked' / 'pipes' / 'fifo.png'}) is a FIFO" in rows["linked/model.gltf"].error
    with pytest.raises(InvalidInputError, match="'tex.png' .* is a FIFO, not a regular file"):
        mesh.load(linked)  # read alone: the same refusal


def test_an_input_replaced_by_a_fifo_while_read_is_changed(tmp_path):
    """An input replaced by a file that is not regular while it was read: 'changed while it was
    read', named (it raised KeyError 'input_inode')."""
    from jaxpose.batch.task import _check_unchanged, _input_stat
    from jaxpose.errors import InvalidInputError

    path = tmp_path / "a.off"
    path.write_bytes(b"OFF\n0 0 0\n")
    before = _input_stat(path, "mtime")
    _check_unchanged(path, before)  # unchanged
    path.unlink()
    os.mkfifo(path)
    with pytest.raises(InvalidInputError, match=r"changed while it was read \(size 10 bytes -> not a regular file\)"):
        _check_unchanged(path, before)


def test_an_output_that_is_a_symbolic_link_is_written_through(tmp_path, tree):
    """An output path that is a link (OUTDIR/a/capsule.ply -> a file elsewhere; a dangling one) is
    written through, atomically: the file it points to gets the output, the link stays (the rename
    replaced the link with a file and left its target as it was, silently). The plan already took
    an output by its real path (a link to an input is refused as 'would overwrite its input')."""
    root, out, store = tmp_path / "scans", tmp_path / "out", tmp_path / "store"
    inputs = [root / "a" / "capsule.ply", root / "sphere.off"]
    (out / "a").mkdir(parents=True)
    store.mkdir()
    (store / "capsule.ply").write_bytes(b"old")
    os.symlink(store / "capsule.ply", out / "a" / "capsule.ply")
    os.symlink(os.path.join("..", "store", "sphere.off"), out / "sphere.off")  # dangling, relative
    first = run(inputs, out, force=True)
    assert first.written == 2
    for source in inputs:
        link = out / source.relative_to(root)
        assert os.path.islink(link) and (store / source.name).is_file(), link
        row = next(r for r in first.rows if r.output == str(link))
        written = mesh.load(store / source.name).vertices
        np.testing.assert_allclose(written, row.apply(mesh.load(source).vertices), rtol=0, atol=1e-6)
    assert sorted(os.listdir(store)) == ["capsule.ply", "sphere.off"]  # no temporary left
    # what a SIGKILL mid-write leaves beside a link's target, outside OUTDIR: an unsharded rerun
    # removes it as a shard's does (it walked OUTDIR only); another file's temporary is not its own
    for name in (".capsule.ply.0123456789ab.tmp", ".sphere.off.ba9876543210.tmp", ".other.ply.0123456789ab.tmp"):
        (store / name).write_bytes(b"a killed run's")
    assert run(inputs, out).skipped == 2  # done: the outputs are there through their links
    assert sorted(os.listdir(store)) == [".other.ply.0123456789ab.tmp", "capsule.ply", "sphere.off"]
    os.unlink(out / "sphere.off")
    os.symlink(root / "a" / "capsule.ply", out / "sphere.off")
    with pytest.raises(UsageError, match=r"sphere.off would overwrite its input"):
        run(inputs, out, force=True)


def test_an_output_link_into_a_missing_folder_fails_before_its_work(tmp_path, tree, monkeypatch):
    """An output path that is a dangling link into a folder that does not exist (its target's folder
    is never made) fails its input before the input is read or normalized, named as the write
    names it (it failed only when written, after the work); a link into a folder that is there is
    written through, and the other inputs are done."""
    root, out = tmp_path / "scans", tmp_path / "out"
    inputs = [root / "a" / "capsule.ply", root / "sphere.off", root / "cloud.ply"]
    (out / "a").mkdir(parents=True)
    (tmp_path / "store").mkdir()
    nowhere = tmp_path / "store" / "gone" / "capsule.ply"
    os.symlink(nowhere, out / "a" / "capsule.ply")  # dangling, into a missing folder
    os.symlink(os.path.join("..", "store", "sphere.off"), out / "sphere.off")  # dangling, its folder there
    worked, original = [], batch.normalize_file

    def normalize_file(source, *args, **kwargs):
        worked.append(os.path.basename(source))
        return original(source, *args, **kwargs)

    monkeypatch.setattr(batch, "normalize_file", normalize_file)
    result = run(inputs, out, force=True)
    assert sorted(worked) == ["cloud.ply", "sphere.off"]  # never read: capsule.ply
    assert (result.written, result.failed) == (2, 1)
    row = next(r for r in result.rows if r.status == "failed")
    link = out / "a" / "capsule.ply"
    assert row.input == str(inputs[0]) and row.error == (
        f"cannot write {link}: {link} (a link to {nowhere}): the folder {nowhere.parent} does not exist")
    assert os.path.islink(link) and not nowhere.parent.exists() and (tmp_path / "store" / "sphere.off").is_file()


def test_a_rerun_with_other_options_is_refused_unless_forced_and_a_stopped_forced_run_resumes(tmp_path, tree):
    """A folder's outputs are of one option set: other options are refused before any work (they
    replaced outputs silently, and a run stopped early left a table of two methods)."""
    root, out = tmp_path / "scans", tmp_path / "out"
    run([root], out)
    journal = (out / ".jaxpose" / "journal.jsonl").read_bytes()
    before = {p: p.stat().st_mtime_ns for p in out.rglob("*.*") if ".jaxpose" not in p.parts}
    for options in (NormalizeOptions(method="bbox"), NormalizeOptions(resolution=24)):
        with pytest.raises(UsageError, match="4 outputs .*made with other options .*--force"):
            run([root], out, options=options)
    with pytest.raises(UsageError, match="--method robust there, bbox here"):
        run([root], out, options=NormalizeOptions(method="bbox"))
    assert (out / ".jaxpose" / "journal.jsonl").read_bytes() == journal  # nothing done
    assert {p: p.stat().st_mtime_ns for p in out.rglob("*.*") if ".jaxpose" not in p.parts} == before
    # a forced run stopped early (fail fast, as an interrupt would) resumes with its options, unforced
    bbox = NormalizeOptions(method="bbox")
    stopped = run([root], out, options=bbox, force=True, fail_fast=True)
    assert stopped.stopped and stopped.written < 4
    resumed = run([root], out, options=bbox)
    assert resumed.written + stopped.written == 4 and resumed.skipped == stopped.written
    assert {r.method for r in resumed.rows} == {"bbox"}  # the table: one method
    with pytest.raises(UsageError, match="--method bbox there, robust here"):
        run([root], out)
    # outputs of other inputs this run would not redo: refused even with force
    with pytest.raises(UsageError, match="would not redo.*another output folder"):
        run([root / "sphere.off"], out, force=True)
    obj = run([root], out, options=bbox, file_format="obj")  # another format: not another option set
    assert (obj.written, obj.skipped) == (3, 1)  # box.obj is done in OBJ already (the format compared resolved)


def test_cli_rerun_with_other_options_is_a_usage_error_before_any_work(tmp_path, tree, capsys, monkeypatch):
    out = tmp_path / "out"
    args = ["normalize", str(tmp_path / "scans"), "-o", str(out), "--workers", "1"]
    assert cli.main([*args, "--resolution", "16"]) == 1  # the tree's bad files
    capsys.readouterr()
    monkeypatch.setattr(batch._Run, "execute", lambda *a, **k: pytest.fail("work started"))
    assert cli.main([*args, "--method", "bbox"]) == 2
    err = capsys.readouterr().err
    assert "--method robust there, bbox here" in err and "--force" in err and "Traceback" not in err, err


def test_a_spelled_out_default_resolution_is_the_same_options(tmp_path, tree, capsys, monkeypatch):
    """Options are compared resolved: --resolution at the estimator's default (jaxpose.config) is
    no --resolution (a rerun spelling out the default was refused, exit 2, as other options)."""
    from jaxpose.config import GridConfig, RobustConfig

    robust, ocsvm = RobustConfig().resolution, GridConfig().resolution
    sphere, out = tmp_path / "scans" / "sphere.off", tmp_path / "out"
    assert run([sphere], out, options=NormalizeOptions()).written == 1  # a folder written with no resolution
    again = run([sphere], out, options=NormalizeOptions(resolution=robust))
    assert (again.written, again.skipped) == (0, 1)
    other = tmp_path / "other"  # the reverse: the default spelled out first, then left out
    assert run([sphere], other, options=NormalizeOptions(resolution=robust)).written == 1
    assert run([sphere], other, options=NormalizeOptions()).skipped == 1
    monkeypatch.setattr(batch._Run, "execute", lambda *a, **k: pytest.fail("work started"))
    code = cli.main(["normalize", str(sphere), "-o", str(out), "--workers", "1", "--resolution", str(robust)])
    captured = capsys.readouterr()
    assert code == 0 and "1 already done" in captured.out, captured.err  # was exit 2
    with pytest.raises(UsageError, match=f"--resolution {robust} there, 24 here"):  # numbers, not 'default'
        run([sphere], out, options=NormalizeOptions(resolution=24))
    # the OCSVM reads its grid's resolution (where it is the center or the scale), not the solid's
    for fields in (dict(method="ocsvm"), dict(center="robust_depth", scale="ocsvm")):
        assert NormalizeOptions(**fields).settings() == NormalizeOptions(**fields, resolution=ocsvm).settings()
        assert NormalizeOptions(**fields).settings() != NormalizeOptions(**fields, resolution=robust).settings()
    assert NormalizeOptions(method="bbox").settings()["resolution"] is None  # no estimator reads one
    # and a refusal says so, as it says a frame's absence: it read "--resolution 96 there, default here"
    # (96 is the default) and "--rotation default there, head here"
    with pytest.raises(UsageError, match=f"--method robust there, bbox here; --resolution {robust} there, none here"):
        run([sphere], out, options=NormalizeOptions(method="bbox"))
    with pytest.raises(UsageError, match="--rotation off there, head here"):
        run([sphere], out, options=NormalizeOptions(rotation=True))


def test_a_folder_an_earlier_version_made_with_an_unread_strict_is_resumed(tmp_path, tree):
    """strict=True with estimators that do not read it (the robust default, bbox), taken by an
    earlier version and refused by this one: its folder's outputs are done, not refused as 'options
    this version cannot read' (NormalizeOptions(**recorded) raised); where a closed-surface
    estimator reads it, strict stays an option of its own."""
    from jaxpose.batch.task import recorded_settings

    sphere = tmp_path / "scans" / "sphere.off"
    for options in (NormalizeOptions(resolution=16), NormalizeOptions(method="bbox")):  # robust (default), bbox
        out = tmp_path / f"out-{options.method}"
        assert run([sphere], out, options=options).written == 1
        journal = out / ".jaxpose" / "journal.jsonl"
        records = [json.loads(line) for line in journal.read_text().splitlines()]
        for record in records:  # as the earlier version wrote them: its options, strict=True
            if "options" in record:
                record["options"] = json.dumps({**json.loads(record["options"]), "strict": True}, sort_keys=True)
        assert any('"strict": true' in r.get("options", "") for r in records)
        journal.write_text("".join(json.dumps(r) + "\n" for r in records))
        again = run([sphere, tmp_path / "scans" / "a" / "b" / "box.obj"], out, options=options)
        assert (again.written, again.skipped, again.failed) == (1, 1, 0), options
    closed = NormalizeOptions(method="solid", strict=True)
    assert closed.settings()["strict"] is True and NormalizeOptions(method="solid").settings()["strict"] is False
    assert recorded_settings(closed.fingerprint()) == closed.settings()


def test_a_spelled_out_format_of_the_inputs_own_is_the_same_options(tmp_path, tree):
    """The output format is compared resolved: --format ply for .ply inputs is no --format (a rerun
    spelling it out redid every file, as did the reverse); another format is other outputs. An
    input's own format keeps its name, whatever the suffix's case: Upper.PLY is written Upper.PLY
    either way (--format ply wrote Upper.ply, beside the Upper.PLY of a run without it)."""
    scans = tmp_path / "scans"
    (scans / "a" / "Upper.PLY").write_bytes((scans / "a" / "capsule.ply").read_bytes())
    for first, second, out in ((None, "ply", tmp_path / "out"), ("ply", None, tmp_path / "other")):
        assert run([scans], out, glob="*.ply", file_format=first).written == 3  # capsule.ply, cloud.ply, Upper.PLY
        again = run([scans], out, glob="*.ply", file_format=second)
        assert (again.written, again.skipped, again.failed) == (0, 3, 1), (first, second)  # corrupt.ply redone
        assert sorted(os.listdir(out / "a")) == ["Upper.PLY", "capsule.ply"]
    assert run([scans], tmp_path / "out", glob="*.ply", file_format="obj").written == 3
    assert sorted(os.listdir(tmp_path / "out" / "a")) == ["Upper.PLY", "Upper.obj", "capsule.obj", "capsule.ply"]
    # a folder of an earlier version, which wrote --format ply's Upper.PLY as Upper.ply: done there
    _earlier_version_folder(scans, tmp_path / "old")
    again = run([scans], tmp_path / "old", glob="*.ply", file_format="ply")
    assert (again.written, again.skipped) == (0, 3) and sorted(os.listdir(tmp_path / "old" / "a")) == ["Upper.ply", "capsule.ply"]


def _earlier_version_folder(scans, out):
    """`out` as an earlier version's run with --format ply left it: Upper.PLY written as Upper.ply,
    and its journal line naming that output (this version's lines, the output renamed)."""
    assert run([scans], out, glob="*.ply", file_format="ply").written == 3
    (out / "a" / "Upper.PLY").rename(out / "a" / "Upper.ply")
    journal = out / ".jaxpose" / "journal.jsonl"
    records = [json.loads(line) for line in journal.read_text().splitlines()]
    for record in records:
        if record.get("output", "").endswith("Upper.PLY"):
            record["output"] = record["output"][:-len("PLY")] + "ply"
    assert sum(r.get("output", "").endswith("Upper.ply") for r in records) == 1
    journal.write_text("".join(json.dumps(r) + "\n" for r in records))


def test_a_shard_rerun_keeps_the_names_an_earlier_versions_run_recorded(tmp_path, tree):
    """Recorded names come from every journal of the folder: shards rerun over a folder an earlier
    version's whole run wrote Upper.ply into (for Upper.PLY, --format ply) wrote Upper.PLY beside it,
    two outputs of one input (one file where case does not count), as the whole run's rerun did not."""
    scans = tmp_path / "scans"
    (scans / "a" / "Upper.PLY").write_bytes((scans / "a" / "capsule.ply").read_bytes())
    out = tmp_path / "old"
    _earlier_version_folder(scans, out)
    runs = [run([scans], out, glob="*.ply", file_format="ply", shard=(i, 2)) for i in range(2)]
    assert sum(r.written for r in runs) == 3  # (a shard skips what its own journal records: nothing yet)
    assert sorted(os.listdir(out / "a")) == ["Upper.ply", "capsule.ply"]
    outputs = [r.output for result in runs for r in result.rows if r.ok]
    assert sorted(os.path.relpath(o, out) for o in outputs) == sorted(["a/Upper.ply", "a/capsule.ply", "cloud.ply"])


def test_an_output_folder_named_through_a_link_is_the_same_folder(tmp_path, tree):
    """Outputs compare by resolved path: -o LINK to OUTDIR redid every input (and doubled rows)."""
    root, out, link = tmp_path / "scans", tmp_path / "out", tmp_path / "link"
    first = run([root], out)
    link.symlink_to(out)
    for name in (link, tmp_path / "scans" / ".." / "link", str(link) + "/"):
        again = run([root], name)
        assert (again.written, again.skipped) == (0, 4), name
        assert stable(again.rows) == stable(first.rows)  # one row per file, named by its folder's real path
    journal = out / ".jaxpose" / "journal.jsonl"  # records naming outputs through the link (written so before)
    journal.write_bytes(journal.read_bytes().replace(str(out).encode(), str(link).encode()))
    again = run([root], out)
    assert (again.written, again.skipped) == (0, 4) and stable(again.rows) == stable(first.rows)


def test_an_input_folder_named_through_a_link_or_relatively_is_the_same_input(tmp_path, tree, monkeypatch):
    """Inputs compare by their folder's real path: a rerun naming the input folder through a link
    was refused ('holds the output of scans/x, not of link/x'); the table names each input under
    its folder's real path, as it names outputs (a link to a file keeps its own name)."""
    root, out, link = tmp_path / "scans", tmp_path / "out", tmp_path / "link"
    first = run([root], out)
    link.symlink_to(root)
    monkeypatch.chdir(tmp_path)
    for name in (link, str(link) + "/", "link", "scans", link / "a" / ".."):
        again = run([name], out)
        assert (again.written, again.skipped) == (0, 4), name
        assert stable(again.rows) == stable(first.rows), name  # one row per input, its folder's real path
    capsule = link / "a" / "capsule.ply"  # a changed input, read through the link: recorded by its real path
    os.utime(capsule, ns=(capsule.stat().st_atime_ns, capsule.stat().st_mtime_ns + 10**9))
    again = run([link], out)
    assert (again.written, again.skipped) == (1, 3) and {r.input for r in again.rows} == {r.input for r in first.rows}
    assert all(r.input.startswith(str(root) + os.sep) for r in again.rows)
    journal = out / ".jaxpose" / "journal.jsonl"  # records naming inputs through the link (written so before)
    journal.write_bytes(journal.read_bytes().replace(str(root).encode(), str(link).encode()))
    again = run([root], out)
    assert (again.written, again.skipped) == (0, 4) and {r.input for r in again.rows} == {r.input for r in first.rows}


def test_second_run_on_one_folder_is_refused(tmp_path, tree):
    out = tmp_path / "out"
    with OutputFolder(out):
        with pytest.raises(FolderBusyError, match=f"pid {os.getpid()}.*another output folder"):
            run([tmp_path / "scans"], out)
    assert run([tmp_path / "scans" / "sphere.off"], out).written == 1  # released


def test_output_folder_remove_temporaries_without_targets_removes_every_one(tmp_path):
    """OutputFolder.remove_temporaries() (public): every temporary under the folder, as before c29da10
    (it removed none; None raised TypeError); with targets, only theirs."""
    from jaxpose.io.atomic import temporary_path

    out = tmp_path / "out"
    with OutputFolder(out) as folder:
        (out / "sub").mkdir()
        left = [temporary_path(out / "a.ply"), temporary_path(out / "sub" / "b.ply")]
        for path in left:
            path.write_bytes(b"x")
        assert folder.remove_temporaries([out / "c.ply"]) == 0 and all(p.exists() for p in left)
        assert folder.remove_temporaries() == 2 and not any(p.exists() for p in left)
        left[0].write_bytes(b"x")
        assert folder.remove_temporaries(None) == 1 and not left[0].exists()


def test_a_lock_file_that_cannot_be_written_keeps_its_pid_line_and_no_lock_stays_held(tmp_path, monkeypatch):
    """A failing write of a lock file (a full disk): the earlier pid line stays (it was cut before the
    write), and every lock is released, also where writing a pid line back fails on leaving (it was
    raised before the release: the lock stayed held by this process)."""
    out = tmp_path / "out"
    with OutputFolder(out):
        pass
    lock = out / ".jaxpose" / "lock"
    lock.write_text("4242\n")  # its last holder another process

    def full(*args):
        raise OSError(28, "No space left on device")

    with monkeypatch.context() as patch:  # this run's pid line cannot be written
        patch.setattr(os, "pwrite", full)
        with pytest.raises(OSError, match="No space left"):
            OutputFolder(out).__enter__()
    assert lock.read_bytes() == b"4242\n"
    folder = OutputFolder(out).__enter__()  # (the lock was released)
    folder.discard()
    with monkeypatch.context() as patch:  # leaving a run that did not start: the pid line's write-back fails
        patch.setattr(os, "pwrite", full)
        folder.__exit__(None, None, None)
    with OutputFolder(out):  # released all the same
        pass


def test_a_run_refused_or_unable_to_reach_its_scheduler_leaves_nothing_it_made(tmp_path, tree, capsys, monkeypatch):
    """An unreachable --scheduler exits 1 and leaves no output folder it made (it left .jaxpose/
    with an empty journal and lock, and an empty table), and one that was there as it was: an
    empty one, and an earlier run's (its failed input redone: work to start). The scheduler here
    refuses at once, as Dask's Client does after its connect timeout (distributed.comm.timeouts.connect,
    30 s by default; a real unreachable address in test_workers.py). A refusal after the
    folder is opened (the table's folder missing) leaves none either (it left .jaxpose/), and an
    existing folder byte for byte: the lock's pid line (it was rewritten with the refused run's
    pid) and the temporaries a killed run left (removed)."""
    from types import SimpleNamespace

    from jaxpose.batch import workers

    def unreachable(address):
        raise OSError(f"Timed out trying to connect to {address} after 30 s")

    def snapshot(folder):  # the lock file's bytes too (its time changes: written back)
        return {str(p.relative_to(folder)): (p.is_dir() or p.read_bytes(), p.name == "lock" or p.stat().st_mtime_ns)
                for p in sorted(folder.rglob("*"))}

    monkeypatch.setattr(workers, "_distributed", lambda: SimpleNamespace(Client=unreachable))
    scans = tmp_path / "scans"
    empty, earlier = tmp_path / "empty", tmp_path / "earlier"
    empty.mkdir()
    assert run([scans / "corrupt.ply"], earlier).failed == 1
    (earlier / ".jaxpose" / "lock").write_text("4242\n")  # its last holder another process
    (earlier / ".sphere.off.0123456789ab.tmp").write_bytes(b"a killed run's")
    before = {folder: snapshot(folder) for folder in (empty, earlier)}
    for inputs, out in (([scans], tmp_path / "new" / "out"), ([scans], empty), ([scans / "corrupt.ply"], earlier)):
        code = cli.main(["normalize", *map(str, inputs), "-o", str(out), "--scheduler", "tcp://127.0.0.1:1"])
        err = capsys.readouterr().err
        assert code == 1 and "cannot reach the Dask scheduler tcp://127.0.0.1:1" in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["earlier", "empty", "scans"]  # no new/, no new/out
    assert {folder: snapshot(folder) for folder in (empty, earlier)} == before
    with pytest.raises(InvalidInputError, match="cannot reach the Dask scheduler"):  # the API alike
        run([scans], tmp_path / "api", workers=None, scheduler="tcp://127.0.0.1:1")
    for out in (tmp_path / "refused", earlier):
        with pytest.raises(UsageError, match="table folder .* does not exist"):
            run([scans], out, table=tmp_path / "missing" / "t.parquet")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["earlier", "empty", "scans"]
    assert snapshot(earlier) == before[earlier]


def test_workers_and_dask_local_follow_the_one_int_rule(tmp_path, tree):
    """workers and dask_local are ints as every count is (jaxpose._validate.check_int): a () NumPy
    or JAX integer array is taken (it was refused), a float, a bool or a string refused as not an
    int, and a small int by its number."""
    import jax.numpy as jnp

    for workers in (np.array(1), jnp.int32(1)):
        assert run([tmp_path / "scans" / "sphere.off"], tmp_path / "o", workers=workers, force=True).written == 1
    for name in ("workers", "dask_local"):
        for bad, message in ((1.0, "an int, got 1.0"), (True, "an int, got True"), ("2", "an int, got '2'"),
                             (0, ">= 1, got 0"), (np.int64(0), ">= 1, got 0")):
            with pytest.raises(InvalidInputError, match=f"^{name} must be {message}$"):
                run([tmp_path / "scans"], tmp_path / "refused", **{"workers": None, name: bad})
    assert not (tmp_path / "refused").exists()


def test_refusals_before_any_work(tmp_path, tree, monkeypatch):
    root = tmp_path / "scans"
    monkeypatch.setattr(batch, "normalize_file", lambda *a: pytest.fail("work started"))
    (root / "a" / "capsule.obj").write_text((root / "a" / "b" / "box.obj").read_text())
    (tmp_path / "list.csv").write_text("path\nscans/sphere.off\n")
    (tmp_path / "case").mkdir()  # --format ply: A.PLY keeps its name, A.obj is written A.ply (one file on macOS)
    for name in ("A.PLY", "A.obj"):
        (tmp_path / "case" / name).write_text((root / "a" / "b" / "box.obj").read_text())
    cases = [
        (dict(inputs=[root], out=tmp_path / "o", file_format="ply"), "would both be written"),
        (dict(inputs=[tmp_path / "case"], out=tmp_path / "o", file_format="ply"),
         r"would be written to .*A\.(PLY|ply) and .*A\.(ply|PLY), one file where file names ignore case"),
        (dict(inputs=[root], out=root), "would overwrite its input"),
        (dict(inputs=[tmp_path / "list.csv"], out=tmp_path / "o", table=tmp_path / "list.csv"),
         "would overwrite an input"),
        (dict(inputs=[tmp_path / "nothing"], out=tmp_path / "o"), "no such file or folder"),
        # (TypeErrors: "'NoneType' object is not iterable", "expected str, bytes or os.PathLike object, not int")
        (dict(inputs=None, out=tmp_path / "o"), r"^inputs must be a path \(str, Path or URL\) or paths, got None"),
        (dict(inputs=[root, 5], out=tmp_path / "o"), r"^inputs must be paths \(str, Path or URL\), got 5 among them"),
        (dict(inputs=[root], out=tmp_path / "o", glob="*.zzz"), "no mesh files found"),
        (dict(inputs=[root], out=tmp_path / "o", workers=0), "workers must be >= 1, got 0"),
        (dict(inputs=[root], out=tmp_path / "o", dask_local=2, scheduler="tcp://x:1"), "not both"),
        (dict(inputs=[root], out=tmp_path / "o", table=tmp_path / "t.xlsx"), ".parquet or .csv"),
        (dict(inputs=[root], out=tmp_path / "o", check="size"), "mtime, hash"),
        (dict(inputs=[root], out=tmp_path / "o", file_format="vtk"), "format must be one of"),
        (dict(inputs=[root], out=tmp_path / "o", force="no"), "force must be True or False"),  # was truthy: redo all
        (dict(inputs=[root], out=tmp_path / "o", fail_fast="no"), "fail_fast must be True or False"),
    ]
    for kwargs, fragment in cases:
        with pytest.raises(InvalidInputError, match=fragment):
            run(kwargs.pop("inputs"), kwargs.pop("out"), **kwargs)
    assert not (tmp_path / "o").exists() and not (root / ".jaxpose").exists()
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "keep.txt").write_text("mine")
    with pytest.raises(InvalidInputError, match="did not write"):
        run([root], tmp_path / "mine")


def test_a_new_output_folder_holding_only_what_file_browsers_leave_is_taken_as_empty(tmp_path, tree):
    """An OUTDIR made, then shown in a file browser (macOS Finder's .DS_Store, Windows' Thumbs.db),
    was refused as holding "files that jaxpose did not write"; a file of the user's is still
    refused, now named, and left as it was."""
    out = tmp_path / "o"
    out.mkdir()
    (out / ".DS_Store").write_bytes(b"\0\0\0\1Bud1")
    (out / "Thumbs.db").write_bytes(b"x")
    result = run([tmp_path / "scans"], out)
    assert (result.written, result.failed) == (len(tree["good"]), len(tree["bad"]))
    assert (out / ".DS_Store").read_bytes() == b"\0\0\0\1Bud1"
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("mine")
    (mine / ".DS_Store").write_bytes(b"x")
    with pytest.raises(UsageError, match=r"did not write \(notes\.txt\)"):
        run([tmp_path / "scans"], mine)
    assert sorted(p.name for p in mine.iterdir()) == [".DS_Store", "notes.txt"]


def test_a_table_path_that_is_a_folder_or_another_file_is_refused_before_any_work(tmp_path, tree, monkeypatch):
    sphere = tmp_path / "scans" / "sphere.off"
    notes, config = tmp_path / "notes.csv", tmp_path / "config.parquet"
    notes.write_text("name,score\nalice,3\n")
    config.write_text('{"not": "parquet"}')
    (tmp_path / "folder.csv").mkdir()
    with monkeypatch.context() as patch:
        patch.setattr(batch, "normalize_file", lambda *a: pytest.fail("work started"))
        for table, fragment in [(notes, "not a transforms table"), (config, "not a transforms table"),
                                (tmp_path / "folder.csv", "is a folder")]:
            with pytest.raises(InvalidInputError, match=fragment):
                run([sphere], tmp_path / "o", table=table, options=FAST)
    assert notes.read_text() == "name,score\nalice,3\n" and not (tmp_path / "o").exists()
    first = run([sphere], tmp_path / "o", table=tmp_path / "t.csv")  # a table of its own: replaced by reruns
    assert run([sphere], tmp_path / "o", table=tmp_path / "t.csv").skipped == 1
    assert stable(jaxpose.read_transforms(tmp_path / "t.csv")) == stable(first.rows)
    run([sphere], tmp_path / "o", table=notes, force=True)  # force: replaced
    assert stable(jaxpose.read_transforms(notes)) == stable(first.rows)


@pytest.mark.parametrize("kwargs, fragment", [
    (dict(count=3), "count must be >= 4"), (dict(gamma=-1.0), "gamma must be a finite number > 0"),
    (dict(nu=2.0), r"nu must be a number in \[0, 1\]"), (dict(resolution=7), "resolution must be >= 8"),
    (dict(method="bbox", resolution=32), "applies to the robust solid .* the core and head frames, and the ocsvm"),
    (dict(method="nope"), "valid: robust, ocsvm"), (dict(sampling="grid"), "even, random"),
    (dict(rotation="up"), "core"), (dict(seed=-1), "seed must be >= 0"),
])
def test_options_validated_with_their_range(kwargs, fragment):
    with pytest.raises(InvalidInputError, match=fragment):
        NormalizeOptions(**kwargs)


def test_fail_fast_stops_at_the_first_failure(tmp_path, tree):
    root = tmp_path / "scans"
    inputs = [root / "corrupt.ply"] + tree["good"]
    result = run(inputs, tmp_path / "out", fail_fast=True)
    assert result.stopped and result.failed == 1 and len(result.rows) < len(inputs)
    assert result.rows[0].status == "failed"


def test_normalize_files_api(tmp_path, tree):
    rows = jaxpose.normalize_files(tmp_path / "scans" / "a", tmp_path / "out", resolution=16, workers=1,
                                   progress=False)
    assert [r.ok for r in rows] == [True, True, False] and rows[0].resolution == 16
    with pytest.raises(InvalidInputError, match="unknown argument colour"):
        jaxpose.normalize_files(tmp_path / "scans", tmp_path / "o2", colour="red")
    with pytest.raises(InvalidInputError, match="not both"):
        jaxpose.normalize_files(tmp_path / "scans", tmp_path / "o2", FAST, method="bbox")


# --------------------------------------------------------------------------- command line
def test_cli_many_files(tmp_path, tree, capsys, monkeypatch):
    out = tmp_path / "out"
    monkeypatch.setattr(batch, "PROGRESS_EVERY_S", 0.0, raising=False)  # a line after every file (10 s apart in use)
    code = cli.main(["normalize", str(tmp_path / "scans"), "-o", str(out), "--workers", "1", "--resolution", "16",
                     "--table", str(tmp_path / "t.csv")])
    captured = capsys.readouterr()
    assert code == 1
    failed = [line for line in captured.err.splitlines() if line.startswith("jaxpose: failed:")]
    assert len(failed) == 3 and "Traceback" not in captured.err
    last = captured.err.splitlines()[-1]
    assert last.startswith("jaxpose: error: 3 of 7 inputs failed") and "t.csv" in last
    # stderr is not a terminal here: progress as plain lines (no bar), stdout only the summary
    progress = [line for line in captured.err.splitlines() if line.startswith("jaxpose normalize: ")]
    assert progress[0] == "jaxpose normalize: [0/7] started" and len(progress) == 7, captured.err
    assert all(f"[{i}/7]" in line and "files/s, about" in line for i, line in enumerate(progress[1:], 1))
    assert "failed" in progress[-1] and "\r" not in captured.err
    [summary] = captured.out.splitlines()
    assert summary.startswith("normalized 4 files")
    assert len(jaxpose.read_transforms(tmp_path / "t.csv")) == 7
    assert cli.main(["normalize", str(tmp_path / "scans" / "a" / "capsule.ply"), str(tmp_path / "scans" / "sphere.off"),
                     "-o", str(out), "--workers", "1", "--resolution", "16", "--table", str(tmp_path / "t.csv")]) == 0
    assert "0 files" in capsys.readouterr().out  # both done already
    (tmp_path / "one").mkdir()
    (tmp_path / "one" / "sphere.off").write_bytes((tmp_path / "scans" / "sphere.off").read_bytes())
    assert cli.main(["normalize", str(tmp_path / "one"), "-o", str(tmp_path / "one-out"), "--workers", "1",
                     "--resolution", "16"]) == 0
    assert capsys.readouterr().out.startswith("normalized 1 file in ")  # (was "1 files")


def test_cli_progress_counts_the_inputs_the_summary_counts(tmp_path, capsys):
    """An input that fails before any work (a FIFO a folder search meets) is counted in the progress
    bar as the summary counts it: "[1/5] started, 1 failed" then "2 of 5 inputs failed" (the bar said
    "[0/4] started" where the summary said "of 5 inputs"); a rerun's bar counts what it handles and
    says how many more were done already. A truncated binary PLY's row says so, naming the file."""
    import re

    scans = tmp_path / "scans"
    scans.mkdir()
    ico = trimesh.creation.icosphere(subdivisions=0)
    for i in range(3):
        ico.export(scans / f"ico{i}.ply")
    cut = scans / "cut.ply"
    cut.write_bytes(ico.export(file_type="ply")[:-10])
    os.mkfifo(scans / "pipe.ply")

    def normalize():
        code = cli.main(["normalize", str(scans), "-o", str(tmp_path / "out"), "--workers", "1", "--resolution", "16"])
        err = capsys.readouterr().err
        started = [line for line in err.splitlines() if line.startswith("jaxpose normalize: [")][0]
        done, total, more = re.fullmatch(r"jaxpose normalize: \[(\d+)/(\d+)\] started(?: \((\d+) more already done\))?"
                                         r"(?:, (\d+) failed)?", started).group(1, 2, 3)
        failed, inputs = re.search(r"jaxpose: error: (\d+) of (\d+) inputs failed", err).group(1, 2)
        return code, err, started, int(total) + int(more or 0), int(inputs)

    code, err, started, counted, inputs = normalize()
    assert code == 1 and started == "jaxpose normalize: [1/5] started, 1 failed", err
    assert counted == inputs == 5 and "2 of 5 inputs failed" in err
    rows = {Path(r.input).name: r for r in jaxpose.read_transforms(tmp_path / "out" / "transforms.parquet")}
    assert rows["cut.ply"].status == "failed" and rows["cut.ply"].error.startswith(
        f"{cut}: cannot read PLY file: ") and "a truncated or malformed file" in rows["cut.ply"].error
    assert "unexpected length" not in err
    ico.export(scans / "ico3.ply")
    code, err, started, counted, inputs = normalize()  # the three done are skipped; the failed two tried again
    assert code == 1 and started == "jaxpose normalize: [1/3] started (3 more already done), 1 failed", err
    assert counted == inputs == 6


def test_cli_progress_lines_count_the_failure_just_recorded(tmp_path, capsys, monkeypatch):
    """Off a terminal (plain progress lines), each line counts every input that failed up to it, the
    one just done included: the failure count was set after the line was printed, so a line printed
    as a failure arrived showed the count before it ("[2/6] ..." without "1 failed" after
    "jaxpose: failed: ...cut.ply")."""
    import re

    monkeypatch.setattr(batch, "PROGRESS_EVERY_S", 0.0, raising=False)  # a line after every file
    scans = tmp_path / "scans"
    scans.mkdir()
    ico = trimesh.creation.icosphere(subdivisions=0)
    for name in ("a.ply", "c.ply", "e.ply"):
        ico.export(scans / name)
    for name in ("b_cut.ply", "d_cut.ply"):  # failures between good files
        (scans / name).write_bytes(ico.export(file_type="ply")[:-10])
    os.mkfifo(scans / "pipe.ply")  # failed before any work
    code = cli.main(["normalize", str(scans), "-o", str(tmp_path / "out"), "--workers", "1", "--resolution", "16"])
    err = capsys.readouterr().err
    assert code == 1 and "3 of 6 inputs failed" in err, err
    failures, checked = 0, 0
    for line in err.splitlines():  # in the order printed: each failure logged, then its progress line
        if line.startswith("jaxpose: failed:"):
            failures += 1
        elif line.startswith("jaxpose normalize: [") and failures:
            shown = re.search(r", (\d+) failed$", line)
            assert shown is not None and int(shown.group(1)) == failures, err
            checked += 1
    assert failures == 3 and checked >= 3, err


def test_progress_bar_shows_the_failed_in_its_first_frame(tmp_path, capsys):
    """The bar's first frame, drawn before the first file is done, counts an input that failed
    before any work ("1/3 ... 1 failed"); the note was set after the bar had drawn it, so a large
    first mesh left "1/3" without it on screen (review)."""
    scans = tmp_path / "scans"
    scans.mkdir()
    trimesh.creation.icosphere(subdivisions=0).export(scans / "ico.ply")
    (scans / "cut.ply").write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 3\n")
    os.mkfifo(scans / "pipe.ply")
    jaxpose.normalize_files(scans, tmp_path / "out", resolution=16, workers=1, progress=True)
    first = capsys.readouterr().err.split("\r")[1]  # (tqdm: "\r" before each frame)
    assert first.startswith("normalize:") and "1/3" in first and "1 failed" in first, first


@pytest.mark.parametrize("args, fragment", [
    (["--transform", "t.json"], "--transform is for one INPUT"),
    (["--example"], "'example' is one input"),
])
def test_cli_many_files_usage(tmp_path, tree, capsys, args, fragment):
    code = cli.main(["normalize", str(tmp_path / "scans"), "-o", str(tmp_path / "out"), *args])
    assert code == 2 and fragment in capsys.readouterr().err


def test_cli_the_summary_of_failures_names_the_first_failed_input(tmp_path, capsys):
    """The last line names the input of the error it quotes: an error worded without the file (a point
    cloud written as STL, a time limit) read "1 of 2 inputs failed: output format stl ...", no file."""
    scans = tmp_path / "scans"
    scans.mkdir()
    trimesh.PointCloud(np.random.default_rng(0).normal(size=(50, 3))).export(scans / "cloud.xyz")
    trimesh.creation.box().export(scans / "box.obj")
    code = cli.main(["normalize", str(scans), "-o", str(tmp_path / "out"), "--format", "stl", "--workers", "1",
                     "--method", "bbox"])
    last = capsys.readouterr().err.strip().splitlines()[-1]
    assert code == 1 and last.startswith(f"jaxpose: error: 1 of 2 inputs failed: {scans / 'cloud.xyz'}: output "
                                         "format stl"), last


@pytest.mark.parametrize("args", [["example"], ["--example"]])
def test_cli_the_example_into_a_folder_names_the_fix(tmp_path, capsys, args):
    """`jaxpose normalize example -o normalized/` was refused "'example' is one input: normalize it
    alone", as it was alone: the fix is a mesh file name for -o. Nothing is made."""
    code = cli.main(["normalize", *args, "-o", str(tmp_path / "normalized") + os.sep])
    err = capsys.readouterr().err
    assert code == 2 and "'example' is one mesh: -o names its output file (-o example.ply)" in err, err
    assert not (tmp_path / "normalized").exists()


def test_cli_many_files_output_paths_and_conflicts_are_usage_errors(tmp_path, tree, capsys, monkeypatch):
    """Refused before any work, exit 2 as other usage errors (they exited 1)."""
    monkeypatch.setattr(batch._Run, "execute", lambda *a, **k: pytest.fail("work started"))
    blocker = tmp_path / "file"
    blocker.write_text("x")
    folder_table = tmp_path / "t.csv"
    folder_table.mkdir()
    cases = [
        (["-o", str(blocker)], "is a file"),
        (["-o", str(blocker / "out")], "is not a folder"),
        (["-o", str(tmp_path / "out"), "--table", str(tmp_path / "scans")], "must end in .parquet or .csv"),
        (["-o", str(tmp_path / "out"), "--table", str(folder_table)], "is a folder"),
        (["-o", str(tmp_path / "out"), "--timeout", "5", "--dask-local", "2"], "for local runs"),
    ]
    for args, fragment in cases:
        code = cli.main(["normalize", str(tmp_path / "scans"), *args])
        err = capsys.readouterr().err
        assert code == 2 and fragment in err and "Traceback" not in err, (args, err)
    assert blocker.read_text() == "x"


def test_cli_one_file_refusals_before_work(tmp_path, tree, capsys, monkeypatch):
    cloud = tmp_path / "scans" / "cloud.ply"
    monkeypatch.setattr(mesh, "normalize_mesh", lambda *a, **k: pytest.fail("work started"))
    cases = [
        (["-o", str(tmp_path / "c.stl")], "point cloud cannot be written as STL"),
        (["-o", str(tmp_path / "c.ply"), "--transform", str(tmp_path / "c.ply")], "name the same file"),
        (["-o", str(cloud)], "is the input file"),
        (["-o", str(cloud / "c.ply")], "is a file"),  # a missing folder is made; a file in the way is refused
        (["-o", str(tmp_path / "c.ply"), "--transform", str(cloud / "t.json")], "is a file"),
        (["-o", str(tmp_path / "c.vtk")], "cannot write '.vtk'"),
        (["-o", str(tmp_path / "c.ply"), "--workers", "2"], "--workers applies to many files"),  # was 'apply'
        (["-o", str(tmp_path / "c.ply"), "--workers", "2", "--fail-fast"], "--workers, --fail-fast apply to many files"),
        (["--count", "2", "--method", "ocsvm"], "count must be >= 4"),
    ]
    for args, fragment in cases:
        code = cli.main(["normalize", str(cloud), *args])
        err = capsys.readouterr().err
        # usage errors (exit 2), but for the point cloud's STL, found once the input is read (exit 1)
        assert code == (1 if "STL" in fragment else 2) and fragment in err and "Traceback" not in err, (args, err)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scans"]
    code = cli.main(["normalize", str(tmp_path / "nothing.ply"), "-o", str(tmp_path / "x.ply"), "--resolution", "3"])
    assert code == 2 and "resolution must be >= 8" in capsys.readouterr().err  # usage, before reading the input


def test_cli_writes_a_point_cloud_in_a_points_format(tmp_path, tree):
    code = cli.main(["normalize", str(tmp_path / "scans" / "cloud.ply"), "-o", str(tmp_path / "c.xyz"),
                     "--resolution", "16"])
    assert code == 0 and isinstance(mesh.load(tmp_path / "c.xyz"), trimesh.PointCloud)
    record = json.loads((tmp_path / "c.transform.json").read_text())
    assert record["method"] == "robust" and len(record["center"]) == 3


def test_normalize_files_refuses_ocsvm_options_given_where_no_ocsvm_runs(tmp_path):
    """normalize_files(..., gamma=47) with the robust default was taken (47 is the default value, so
    NormalizeOptions could not tell it was given) and never read; normalize_mesh refuses it. Now
    refused before any work in normalize_mesh's words; with the ocsvm method it is taken."""
    import trimesh

    path = tmp_path / "box.ply"
    trimesh.creation.box().export(path)
    for named in (dict(gamma=47), dict(method="bbox", nu=0.5, seed=0)):
        with pytest.raises(InvalidInputError) as caught:
            jaxpose.normalize_files([path], tmp_path / "out", workers=1, **named)
        with pytest.raises(InvalidInputError) as mesh_says:
            jaxpose.normalize_mesh(path, **named)
        assert str(caught.value) == str(mesh_says.value) and "of the ocsvm estimator" in str(caught.value)
    assert not (tmp_path / "out").exists()
    assert NormalizeOptions(method="ocsvm", gamma=47).gamma == 47.0  # read: taken
    # 400 samples (incidental): test_pinned.py's float32 default-grid program (448 rows)
    rows = jaxpose.normalize_files([path], tmp_path / "out", workers=1, method="ocsvm", gamma=47, count=400)
    assert [row.status for row in rows] == ["ok"] and (tmp_path / "out" / "box.ply").is_file()
    assert rows[0].gamma == 47.0
