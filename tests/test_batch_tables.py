"""The transforms table across runs: shards whose tables together are the unsharded table, runs
one after the other into one folder that keep every row an output depends on, what each row
records (the input's size, time, SHA-256; the version and options that made it)."""
import dataclasses
import filecmp
import hashlib
import json
import os
from pathlib import Path

import numpy as np
import pytest
import trimesh

import jaxpose
from jaxpose.batch import batch
from jaxpose import cli, mesh
from jaxpose.errors import InvalidInputError
from jaxpose.batch.inputs import shard_index
from jaxpose.batch.journal import FolderBusyError, OutputFolder
from jaxpose.batch.task import NormalizeOptions
from jaxpose.batch.transforms import merge_transforms

from conftest import write_mesh_tree

FAST = NormalizeOptions(resolution=16)
TIMING = ("seconds", "worker", "worker_peak_mb")


def run(inputs, out, **kwargs):
    kwargs.setdefault("workers", 1)
    kwargs.setdefault("progress", False)
    return batch.run_batch(inputs, out, kwargs.pop("options", FAST), **kwargs)


def stable(row, out):
    return {k: (v.replace(str(out), "OUT") if isinstance(v, str) else v) for k, v in row._asdict().items()
            if k not in TIMING}


@pytest.fixture
def scans(tmp_path):
    write_mesh_tree(tmp_path / "scans")
    for i in range(5):  # a few more, so that each of 3 shards has some
        trimesh.creation.box(extents=(1.0 + 0.1 * i, 0.5, 0.3)).export(tmp_path / "scans" / f"box{i}.stl")
    return tmp_path / "scans"


def test_shard_index_is_the_documented_stable_hash():
    for name in ["kid_01/pose_03.ply", "a/b/c.off", "caf\udce9.ply"]:
        digest = hashlib.sha256(os.fsencode(name)).digest()
        assert shard_index(name, 7) == int.from_bytes(digest[:8], "big") % 7
    assert shard_index("kid_01/pose_03.ply", 1) == 0


def test_three_shards_make_the_unsharded_table_and_files(tmp_path, scans):
    whole = run([scans], tmp_path / "whole")
    shards = [run([scans], tmp_path / "sharded", shard=(i, 3)) for i in range(3)]
    assert [s.table.name for s in shards] == [f"transforms.shard-{i}-of-3.parquet" for i in range(3)]
    taken = [sorted(r.input for r in s.rows) for s in shards]
    assert all(taken) and sorted(sum(taken, [])) == sorted(r.input for r in whole.rows)  # each input once
    for i, inputs in enumerate(taken):
        assert all(shard_index(os.path.relpath(p, scans), 3) == i for p in inputs)
    merged = jaxpose.read_transforms(tmp_path / "sharded")  # the folder: its tables
    listed = jaxpose.read_transforms([s.table for s in shards])
    assert [stable(r, tmp_path / "sharded") for r in merged] == [stable(r, tmp_path / "sharded") for r in listed]
    key = lambda r: r.input  # noqa: E731
    assert sorted((stable(r, tmp_path / "sharded") for r in merged), key=lambda d: d["input"]) == \
        sorted((stable(r, tmp_path / "whole") for r in whole.rows), key=lambda d: d["input"])
    for row in sorted(whole.rows, key=key):
        if row.ok:
            relative = os.path.relpath(row.output, tmp_path / "whole")
            assert filecmp.cmp(row.output, tmp_path / "sharded" / relative, shallow=False)
    again = run([scans], tmp_path / "sharded", shard=(1, 3))
    assert again.written == 0 and again.skipped == sum(r.ok for r in shards[1].rows)


def test_shards_run_side_by_side_but_not_twice_nor_beside_a_whole_run(tmp_path, scans):
    out = tmp_path / "out"
    with OutputFolder(out, shard=(0, 2)):
        assert run([scans], out, shard=(1, 2)).rows  # another shard: fine
        with pytest.raises(FolderBusyError, match=f"pid {os.getpid()}"):
            run([scans], out, shard=(0, 2))
        with pytest.raises(FolderBusyError):
            run([scans], out)
    # ints by the one rule (jaxpose.config._integer): (0.0, 2.0) was taken as (0, 2)
    for bad, fragment in [((2, 2), "0 <= index < count"), ((0, 0), "0 <= index < count"), ("0/2", "(index, count)"),
                          ((0.5, 2), "(index, count)"), ((0.0, 2.0), "(index, count)"), ((0, 2.0), "(index, count)"),
                          ((True, 2), "(index, count)")]:
        with pytest.raises(InvalidInputError, match=fragment):
            run([scans], tmp_path / "o", shard=bad)


def test_cli_shard_and_merge(tmp_path, scans, capsys):
    for i in range(2):
        code = cli.main(["normalize", str(scans), "-o", str(tmp_path / f"m{i}"), "--workers", "1", "--resolution",
                         "16", "--shard", f"{i}/2"])
        assert code == 1  # the tree's bad files fail, in the shards that take them
    merged = jaxpose.read_transforms([tmp_path / "m0", tmp_path / "m1"])
    assert sorted(os.path.relpath(r.input, scans) for r in merged) == sorted(
        os.path.relpath(r.input, scans) for r in run([scans], tmp_path / "whole").rows)
    capsys.readouterr()
    with pytest.raises(SystemExit) as info:  # a usage error
        cli.main(["normalize", str(scans), "-o", str(tmp_path / "x"), "--shard", "2"])
    assert info.value.code == 2
    assert "expected I/N" in capsys.readouterr().err


def test_runs_one_after_the_other_keep_every_row_an_output_needs(tmp_path, scans):
    """Two dataset commands into one folder (each folder INPUT its own root): the table holds
    both runs' rows, and each output in the folder has the row that inverts it."""
    out = tmp_path / "out"
    first = run([scans / "a"], out)
    second = run([scans], out, glob="*.off")
    rows = jaxpose.read_transforms(second.table)
    assert rows[0].input == str(scans / "sphere.off")  # this run's inputs first, then the earlier rows
    assert {r.input for r in rows} == {r.input for r in first.rows if r.ok} | {str(scans / "sphere.off")}
    outputs = [p for p in out.rglob("*") if p.is_file() and ".jaxpose" not in p.parts and p.suffix != ".parquet"]
    assert sorted(map(str, outputs)) == sorted(r.output for r in rows if r.ok)
    for row in rows:
        if row.ok:
            written = mesh.load(row.output).vertices
            np.testing.assert_allclose(row.invert(written), mesh.load(row.input).vertices, rtol=0,
                                       atol=4 * np.finfo(np.float32).eps * np.abs(written).max() * row.scale)
    assert all(r.input != str(scans / "a" / "b" / "nan.obj") for r in rows)  # an earlier failure: no output


def test_a_run_with_pyarrow_after_one_without_leaves_one_table(tmp_path, scans, monkeypatch):
    """transforms.csv (no pyarrow), then transforms.parquet: the CSV, left, would give
    read_transforms(OUTDIR) the row of an output deleted in between."""
    from jaxpose.batch import transforms

    out = tmp_path / "out"
    with monkeypatch.context() as patch:
        patch.setattr(transforms, "has_parquet", lambda: False)
        first = run([scans / "a"], out)
    assert first.table == out / "transforms.csv"
    gone = next(r for r in first.rows if r.ok)
    os.remove(gone.output)
    second = run([scans / "a"], out, glob="*.obj")  # not the input of the deleted output
    assert second.table == out / "transforms.parquet" and not (out / "transforms.csv").exists()
    rows = jaxpose.read_transforms(out)
    assert [stable(r, out) for r in rows] == [stable(r, out) for r in jaxpose.read_transforms(second.table)]
    assert all(os.path.exists(r.output) for r in rows if r.ok) and gone.output not in {r.output for r in rows}
    assert {r.output for r in rows if r.ok} == {r.output for r in first.rows if r.ok} - {gone.output}


def test_an_output_of_another_input_is_not_replaced_without_force(tmp_path, scans):
    out = tmp_path / "out"
    run([scans / "a" / "capsule.ply"], out)  # -> out/capsule.ply
    other = tmp_path / "elsewhere"
    other.mkdir()
    (other / "capsule.ply").write_bytes(trimesh.creation.box().export(file_type="ply"))
    before = (out / "capsule.ply").read_bytes()
    with pytest.raises(InvalidInputError, match="holds the output of .*capsule.ply.*force"):
        run([other / "capsule.ply"], out)
    assert (out / "capsule.ply").read_bytes() == before
    rows = run([other / "capsule.ply"], out, force=True).rows
    assert [r.input for r in rows] == [str(other / "capsule.ply")]  # the old row went with its output


def test_each_row_records_the_input_and_what_made_it(tmp_path, scans):
    options = NormalizeOptions(resolution=16, method="robust")
    plain = run([scans], tmp_path / "plain", options=options)
    hashed = run([scans], tmp_path / "hashed", options=options, check="hash", file_format="ply")
    for row in plain.rows + hashed.rows:
        path = row.input
        info = os.stat(path)
        assert (row.input_size, row.input_mtime_ns) == (info.st_size, info.st_mtime_ns)
        assert row.version == jaxpose.__version__
        recorded = json.loads(row.options)
        assert {k: recorded[k] for k in ("method", "resolution", "gamma", "seed")} == \
            {k: dataclasses.asdict(options)[k] for k in ("method", "resolution", "gamma", "seed")}
    assert all(r.input_sha256 == "" for r in plain.rows)
    for row in hashed.rows:
        assert row.input_sha256 == hashlib.sha256(Path(row.input).read_bytes()).hexdigest()
        assert json.loads(row.options)["format"] == "ply"


def test_merge_keeps_the_latest_row_of_an_output_and_of_a_failed_input(tmp_path, scans):
    out = tmp_path / "out"
    a = run([scans / "a"], out, table=tmp_path / "a.csv").rows
    b = run([scans / "a"], out, table=tmp_path / "b.csv", options=NormalizeOptions(method="bbox"), force=True).rows
    assert [r.method for r in b] == ["bbox"] * 3  # the same outputs, redone with other options
    merged = jaxpose.read_transforms([tmp_path / "a.csv", tmp_path / "b.csv"])
    assert [(r.input, r.method, r.status) for r in merged] == [(r.input, r.method, r.status) for r in b]
    elsewhere = run([scans / "a"], tmp_path / "other", options=NormalizeOptions(method="bbox")).rows
    both = merge_transforms([a, elsewhere])  # other outputs: a's ok rows stay, its failure was retried
    assert [r.output for r in both] == [r.output for r in a if r.ok] + [r.output for r in elsewhere]
    assert merge_transforms([a]) == a


def test_one_input_written_to_two_outputs_keeps_both_rows(tmp_path, scans):
    out = tmp_path / "out"
    run([scans / "a"], out)  # root scans/a: out/capsule.ply
    rows = run([scans], out, glob="capsule.ply").rows  # root scans: out/a/capsule.ply, the same input
    capsule = str(scans / "a" / "capsule.ply")
    assert sorted(r.output for r in rows if r.input == capsule) == [str(out / "a" / "capsule.ply"),
                                                                   str(out / "capsule.ply")]
    assert rows[0].output == str(out / "a" / "capsule.ply")  # this run's first


@pytest.mark.parametrize("damage, fragment", [
    ("cut", "row 2 is not a transforms row"),    # the last row cut short: its missing cells were None
    ("edit", "row 1 is not a transforms row"),   # a center that is not a number
    ("bytes", "not a readable CSV table"),       # not UTF-8
])
def test_a_damaged_csv_table_is_an_error_naming_it(tmp_path, damage, fragment):
    """A CSV table cut short or edited by hand is an InvalidInputError naming the table and the row
    (read_transforms raised float()'s TypeError or ValueError)."""
    src = tmp_path / "scans"
    src.mkdir()
    for i in range(2):
        trimesh.creation.box(extents=(1.0 + 0.1 * i, 0.5, 0.3)).export(src / f"box{i}.ply")
    table = tmp_path / "out" / "t.csv"
    run([src], tmp_path / "out", options=NormalizeOptions(method="bbox"), table=str(table))
    assert len(jaxpose.read_transforms(table)) == 2
    lines = table.read_text().splitlines()
    center = lines[1].split(",")[4]
    damaged = {"cut": "\n".join(lines[:2] + [lines[2][:60]]) + "\n",
               "edit": "\n".join([lines[0], lines[1].replace("," + center + ",", ",abc,", 1)] + lines[2:]) + "\n",
               "bytes": None}[damage]
    if damaged is None:
        table.write_bytes(b"\xff\xfe" + table.read_bytes())
    else:
        table.write_text(damaged)
    with pytest.raises(InvalidInputError, match=f"t.csv: {fragment}"):
        jaxpose.read_transforms(table)


def test_read_transforms_names_an_argument_that_is_not_a_path(tmp_path):
    """None, a number or bytes: an InvalidInputError saying what read_transforms takes (it raised
    Python's "'NoneType' object is not iterable")."""
    for bad in (None, 5, [None], b"t.csv"):
        with pytest.raises(InvalidInputError, match="a transforms table, a folder of them or a list of those"):
            jaxpose.read_transforms(bad)


def test_read_transforms_names_a_missing_table_or_folder(tmp_path):
    """A path that does not exist is named missing, whatever its suffix (a missing folder was
    refused for its suffix: "a table must end in .parquet or .csv")."""
    for name in ("missing", "missing/", "missing.csv", "missing.parquet"):
        with pytest.raises(InvalidInputError, match="no such table or folder: .*missing"):
            jaxpose.read_transforms(str(tmp_path / name))
    os.mkfifo(tmp_path / "fifo.csv")
    with pytest.raises(InvalidInputError, match="fifo.csv: not a regular file"):
        jaxpose.read_transforms(str(tmp_path / "fifo.csv"))


def test_a_script_that_reads_a_parquet_table_exits_cleanly(tmp_path, scans):
    """A Python process that reads a Parquet table with read_transforms exits with code 0: pyarrow
    26's threaded read could leave a thread that aborted the interpreter at exit ("terminate called
    without an active exception", 134) in about a third of the runs (4 of 12 here); the table is
    read on one thread. 16 processes (~0.2 s each): with the old read, all 16 passing had a
    chance of about (2/3)^16, 0.15 %."""
    pytest.importorskip("pyarrow")
    import subprocess
    import sys

    result = run([scans / "a"], tmp_path / "out")
    assert str(result.table).endswith(".parquet")
    code = (f"import jaxpose; rows = jaxpose.read_transforms({str(result.table)!r}); "
            f"assert len(rows) == {len(result.rows)}, len(rows)")
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env["PYTHONPATH"] = str(Path(__file__).resolve().parents[1])
    exits = [subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120)
             for _ in range(16)]
    assert [e.returncode for e in exits] == [0] * 16, [e.stderr[-300:] for e in exits if e.returncode]
