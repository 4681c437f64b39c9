"""The dataset command's hostile inputs, each with real files, processes and signals: files that
are not regular met in a folder, a folder link loop, two inputs for one output, names that are
not UTF-8, a manifest of missing files, a worker killed from outside, an output folder that is a
file, a file that changes between the listing and the read, a FIFO that never delivers (with
``--timeout``). Each ends as a recorded, explained failure or a correct result; the rest of the
run completes; nothing is overwritten; nothing hangs."""
import os
import re
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
import trimesh

import jaxpose
from jaxpose.batch import batch
from jaxpose import mesh
from jaxpose.errors import InvalidInputError
from jaxpose.batch.task import NormalizeOptions

pytestmark = pytest.mark.skipif(sys.platform != "linux", reason="FIFOs, sockets, /proc and bytes names: Linux")

ROOT = Path(__file__).resolve().parents[1]
FAST = NormalizeOptions(resolution=16)


def good_meshes(folder, count=3):
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for i in range(count):
        shape = trimesh.creation.box(extents=(1.0 + 0.2 * i, 0.6, 0.4))
        shape.apply_translation([i, -1.0, 2.0])
        paths.append(folder / f"good_{i}.ply")
        shape.export(paths[-1])
    return paths


def cli(*args, timeout=180, prefix=()):
    """`python -m jaxpose normalize ...` in a subprocess (after the command `prefix`): (exit code,
    stdout, stderr)."""
    extra = [] if "--method" in args else ["--resolution", "16"]
    process = subprocess.run([*prefix, sys.executable, "-m", "jaxpose", "normalize", *map(str, args), *extra],
                             cwd=ROOT, capture_output=True, text=True, timeout=timeout)
    return process.returncode, process.stdout, process.stderr


def by_name(rows):
    return {Path(r.input).name: r for r in rows}


def assert_normalized(row):
    """The output on disk is the input under the row's transform (PLY stores float32)."""
    expected = row.apply(mesh.load(row.input).vertices).astype(np.float32)
    np.testing.assert_array_equal(mesh.load(row.output).vertices.astype(np.float32), expected)


def test_files_that_are_not_regular_in_a_folder_fail_unread_and_a_link_loop_is_not_followed(tmp_path):
    scans = tmp_path / "scans"
    good = good_meshes(scans / "sub")
    os.mkfifo(scans / "pipe.ply")  # opened, it would block the run forever
    server = socket.socket(socket.AF_UNIX)
    server.bind(str(scans / "sock.ply"))
    os.symlink("/dev/null", scans / "null.ply")
    os.symlink(scans, scans / "sub" / "loop")  # a folder link back to the root
    try:
        code, out, err = cli(scans, "-o", tmp_path / "out", "--workers", "1", timeout=120)
    finally:
        server.close()
    assert code == 1 and "3 of 6 inputs failed" in err, err
    rows = by_name(jaxpose.read_transforms(tmp_path / "out" / "transforms.parquet"))
    assert sorted(rows) == sorted(["pipe.ply", "sock.ply", "null.ply"] + [p.name for p in good])  # once each
    for name, kind in [("pipe.ply", "a FIFO"), ("sock.ply", "a socket"), ("null.ply", "a character device")]:
        assert rows[name].status == "failed" and f"{kind}, not a regular file" in rows[name].error
        assert f"{kind}, not a regular file" in err
        # only a FIFO is read when named as an INPUT (a socket or device is 'not a file' there too)
        assert ("name it as an INPUT" in rows[name].error) == (name == "pipe.ply"), rows[name].error
    for path in good:
        assert rows[path.name].ok
        assert_normalized(rows[path.name])
    assert not (tmp_path / "out" / "sub" / "loop").exists()


def test_two_inputs_for_one_output_are_refused_before_any_work(tmp_path):
    scans = tmp_path / "scans"
    good_meshes(scans)
    trimesh.creation.icosphere(1).export(scans / "good_0.off")  # good_0.ply and good_0.off -> good_0.ply
    code, _, err = cli(scans, "-o", tmp_path / "out", "--format", "ply", "--workers", "1")
    assert code == 2 and "would both be written to" in err and "good_0.off" in err and "Traceback" not in err
    assert not (tmp_path / "out").exists()
    (scans / "good_1.ply").unlink()
    trimesh.creation.icosphere(1).export(scans / "good_1.off")
    good_meshes(scans / "good_1.ply", count=1)  # good_1.off -> out/good_1.ply, a file where a folder must be
    (scans / "good_0.off").unlink()
    code, _, err = cli(scans, "-o", tmp_path / "out", "--format", "ply", "--workers", "1")
    assert code == 2 and "a file where" in err and "good_1.ply/good_0.ply" in err and "Traceback" not in err
    assert not (tmp_path / "out").exists()


def test_an_earlier_runs_output_folder_inside_the_input_folder_is_not_searched(tmp_path):
    scans = tmp_path / "scans"
    good = good_meshes(scans, count=2)
    first = batch.run_batch([scans], scans / "out1", FAST, workers=1, progress=False)
    assert (first.written, first.failed) == (2, 0)
    # a second output folder beside the first: the first one's outputs are not inputs again
    second = batch.run_batch([scans], scans / "out2", FAST, workers=1, progress=False)
    assert sorted(r.input for r in second.rows) == sorted(str(p) for p in good)
    assert (second.written, second.failed) == (2, 0) and not (scans / "out2" / "out1").exists()
    # named as an INPUT itself, an output folder is searched (its outputs normalized again)
    third = batch.run_batch([scans / "out1"], tmp_path / "again", FAST, workers=1, progress=False)
    assert sorted(Path(r.input).name for r in third.rows) == sorted(p.name for p in good)


def test_a_file_and_a_link_to_it_are_done_once_under_the_files_own_name(tmp_path):
    scans = tmp_path / "scans"
    good = good_meshes(scans, count=2)
    os.symlink(good[1].name, scans / "a_latest.ply")  # listed before its target
    result = batch.run_batch([scans], tmp_path / "out", FAST, workers=1, progress=False)
    assert [r.input for r in result.rows] == [str(p) for p in good]
    assert sorted(p.name for p in (tmp_path / "out").glob("*.ply")) == [p.name for p in good]
    assert_normalized(by_name(result.rows)[good[1].name])


def test_names_that_are_not_utf8(tmp_path):
    scans = tmp_path / "scans"
    good_meshes(scans, count=1)
    raw = os.path.join(os.fsencode(scans), b"caf\xe9-\xff.ply")
    trimesh.creation.box(extents=(2.0, 1.0, 0.5)).export(os.fsdecode(raw))
    result = batch.run_batch([scans], tmp_path / "out", FAST, workers=1, progress=False)
    assert (result.written, result.failed) == (2, 0)
    output = os.path.join(os.fsencode(tmp_path / "out"), b"caf\xe9-\xff.ply")  # the same bytes name
    assert os.path.isfile(output)
    original = trimesh.load(os.fsdecode(raw), process=False).vertices
    row = next(r for r in jaxpose.read_transforms(result.table) if "caf" in r.input)
    assert row.ok and row.input.endswith("caf\\xe9-\\xff.ply")  # stored as valid UTF-8, bytes escaped
    np.testing.assert_array_equal(mesh.load(os.fsdecode(output)).vertices.astype(np.float32),
                                  row.apply(original).astype(np.float32))
    again = batch.run_batch([scans], tmp_path / "out", FAST, workers=1, progress=False)
    assert (again.written, again.skipped) == (0, 2)  # the journal knows the name exactly


def test_a_name_near_the_file_systems_limit_is_written(tmp_path):
    from jaxpose.io.atomic import temporary_path

    scans = tmp_path / "scans"
    good_meshes(scans, count=1)
    long = scans / ("x" * 246 + ".ply")  # 250 bytes: its temporary .NAME.<12 hex>.tmp would be 268
    trimesh.creation.box(extents=(2.0, 1.0, 0.5)).export(long)
    out = tmp_path / "out"
    result = batch.run_batch([scans], out, FAST, workers=1, progress=False, shard=(0, 1))  # a shard removes
    assert (result.written, result.failed) == (2, 0)                                          # its own temporaries
    assert_normalized(by_name(result.rows)[long.name])
    left = temporary_path(out / long.name)  # what a SIGKILL mid-write leaves: removed by the rerun
    left.write_bytes(b"partial")
    assert len(os.fsencode(left.name)) <= 255
    again = batch.run_batch([scans], out, FAST, workers=1, progress=False, shard=(0, 1))
    assert again.skipped == 2 and not left.exists()


def test_a_manifest_of_missing_files(tmp_path):
    good = good_meshes(tmp_path / "scans", count=2)
    (tmp_path / "list.txt").write_text("scans/good_0.ply\nscans/gone.ply\nnowhere/else.obj\nscans/good_1.ply\n")
    code, out, err = cli(tmp_path / "list.txt", "-o", tmp_path / "out", "--workers", "1")
    assert code == 1 and "2 of 4 inputs failed" in err
    rows = by_name(jaxpose.read_transforms(tmp_path / "out" / "transforms.parquet"))
    for name in ("gone.ply", "else.obj"):
        assert rows[name].status == "failed" and "no such file" in rows[name].error
    assert all(rows[p.name].ok for p in good)


def test_a_point_cloud_named_as_a_manifest_is_named_so(tmp_path):
    """A point cloud in a .txt or .csv (the manifests' suffixes): refused before any work, naming
    .xyz; every line was an input of its own, each failing 'no such file: /tmp/0 0 0'. With
    -o out.ply the refusal says the INPUT is a manifest (it read 'pts.txt give many files')."""
    points = np.random.default_rng(0).normal(size=(30, 3))
    (tmp_path / "pts.txt").write_text("".join(f"{x} {y} {z}\n" for x, y, z in points))
    (tmp_path / "pts.csv").write_text("x,y,z\n" + "".join(f"{x},{y},{z}\n" for x, y, z in points))
    for name in ("pts.txt", "pts.csv"):
        code, _, err = cli(tmp_path / name, "-o", tmp_path / "out", "--workers", "1")
        assert code == 1 and f"{name}: a manifest (.txt and .csv INPUTs list mesh paths, one a line) whose lines are " \
            "numbers" in err and "is it a point cloud? name it .xyz" in err, err
        assert ("a column named neither 'path' nor 'input': the first column is read" in err) == name.endswith(".csv")
        assert not (tmp_path / "out").exists()
    code, _, err = cli(tmp_path / "pts.txt", "-o", tmp_path / "p.ply")
    assert code == 2 and "pts.txt is a manifest (a list of mesh paths): it gives many files: -o OUTDIR" in err, err


def test_a_csv_manifest_whose_paths_column_is_named_otherwise_is_refused(tmp_path):
    """A .csv manifest's paths are its 'path' or 'input' column, else its first (docs/batch.md);
    a header naming them 'file' (or 'filename', 'mesh', ...) is refused before any work, naming the
    columns read and the fix: 'id,file' read the ids as paths (the header 'id' too, each a failed
    row 'no such file'), 'file' alone the header as a path."""
    from jaxpose.batch import inputs

    trimesh.creation.box().export(tmp_path / "a.off")
    for name, text, column in (("ids.csv", "id,file\nx1,a.off\n", "file"), ("one.csv", "File\na.off\n", "file"),
                               ("mesh.csv", "Mesh, notes\na.off,x\n", "mesh")):
        (tmp_path / name).write_text(text)
        with pytest.raises(InvalidInputError, match=rf"{name}: a .csv manifest's paths are read from its column "
                                                    rf"named 'path' or 'input', else from its first column .*names "
                                                    rf"'{column}': rename that column 'path'"):
            inputs.find_inputs(tmp_path / name)
    (tmp_path / "ok.csv").write_text("id,Path,file\n1,a.off,b.off\n")  # a 'path' column is read as before
    assert [p.name for p in inputs.find_inputs(tmp_path / "ok.csv").files] == ["a.off"]


def children_holding(path):
    """Process ids of this process's children that have `path` open."""
    found = []
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat") as handle:
                ppid = int(handle.read().rpartition(")")[2].split()[1])
            if ppid != os.getpid():
                continue
            fds = os.listdir(f"/proc/{entry}/fd")
            if any(os.readlink(f"/proc/{entry}/fd/{fd}") == str(path) for fd in fds):
                found.append(int(entry))
        except OSError:
            continue
    return found


def test_a_worker_killed_from_outside_fails_its_input_and_the_run_goes_on(tmp_path):
    good = good_meshes(tmp_path / "scans", count=4)
    fifo = tmp_path / "scans" / "stuck.ply"
    os.mkfifo(fifo)  # named as an INPUT: read; it blocks its worker until killed
    killed, stop = [], threading.Event()

    def killer():
        while not stop.is_set():
            for pid in children_holding(fifo):
                os.kill(pid, signal.SIGKILL)  # the worker, not this (parent) process
                killed.append(pid)
            time.sleep(0.1)

    writer = os.open(fifo, os.O_RDWR)  # a writer that never writes: a reader's open returns, its read blocks
    thread = threading.Thread(target=killer, daemon=True)
    thread.start()
    try:
        result = batch.run_batch([fifo, *good], tmp_path / "out", FAST, workers=2, progress=False)
    finally:
        stop.set()
        thread.join()
        os.close(writer)
    rows = by_name(result.rows)
    # the first worker, then the one that tried it again; a worker lost before it reports the task
    # started is not a try, and the message counts it apart: it names every worker killed
    error = rows["stuck.ply"].error
    assert rows["stuck.ply"].status == "failed"
    assert "killed by SIGKILL" in error and "tried twice" in error
    before = re.search(r"and (\d+) workers? lost before starting it$", error)
    assert len(set(killed)) == 2 + (int(before.group(1)) if before else 0), (killed, error)
    assert (result.written, result.failed) == (4, 1)
    for path in good:
        assert_normalized(rows[path.name])


def test_an_output_folder_that_is_a_file(tmp_path):
    good = good_meshes(tmp_path / "scans" / "sub", count=2)
    (tmp_path / "outfile").write_text("mine")
    code, _, err = cli(tmp_path / "scans", "-o", tmp_path / "outfile", "--workers", "1")
    assert code == 2 and "is a file" in err and "Traceback" not in err  # usage, as a mesh file name below
    assert (tmp_path / "outfile").read_text() == "mine"
    # an existing file with a mesh suffix as OUTDIR: a usage error before any work, the file untouched
    (tmp_path / "out.ply").write_text("mine")
    code, _, err = cli(tmp_path / "scans", "-o", tmp_path / "out.ply", "--workers", "1")
    assert code == 2 and "names a mesh file" in err and "Traceback" not in err
    assert (tmp_path / "out.ply").read_text() == "mine"
    # a folder the outputs need is a file: those inputs fail, the file stays, the rest is done
    good_meshes(tmp_path / "scans" / "other", count=1)
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "sub").write_text("mine too")
    result = batch.run_batch([tmp_path / "scans"], tmp_path / "out", FAST, workers=1, force=True, progress=False)
    rows = {os.path.relpath(r.input, tmp_path / "scans"): r for r in result.rows}
    assert (tmp_path / "out" / "sub").read_text() == "mine too"
    for path in good:
        row = rows[f"sub/{path.name}"]
        assert row.status == "failed" and "cannot write" in row.error
    assert rows["other/good_0.ply"].ok


def test_a_file_where_the_outputs_need_a_folder_fails_those_inputs_before_their_work(tmp_path):
    """OUTDIR/sub a regular file where OUTDIR/sub/x.ply (and OUTDIR/sub/deeper/y.ply) needs a folder:
    those inputs fail before they are read, named as the write would name it (they were read and
    normalized, then failed on the write: "FileExistsError: [Errno 17] File exists"); the file
    stays; the other inputs are done."""
    scans, out = tmp_path / "scans", tmp_path / "out"
    good_meshes(scans / "sub", count=1)
    good_meshes(scans / "sub" / "deeper", count=1)
    good_meshes(scans / "other", count=1)
    out.mkdir()
    (out / "sub").write_text("mine")
    code, _, err = cli(scans, "-o", out, "--force", "--workers", "1")
    assert code == 1 and "2 of 3 inputs failed" in err and "Traceback" not in err, err
    rows = {os.path.relpath(r.input, scans): r for r in jaxpose.read_transforms(out / "transforms.parquet")}
    for name in ("sub/good_0.ply", "sub/deeper/good_0.ply"):
        row = rows[name]
        assert row.status == "failed" and row.error == f"cannot write {out / name}: {out / 'sub'} is a file, not a folder"
        assert f"jaxpose: failed: {scans / name}: cannot write {out / name}" in err
        assert row.vertices is None and row.seconds is None and not row.worker  # never read: no worker's record
    assert rows["other/good_0.ply"].ok and (out / "sub").read_text() == "mine"


@pytest.mark.parametrize("target", ["missing", "file"])
def test_a_link_where_the_outputs_need_a_folder_fails_those_inputs_before_their_work(tmp_path, target):
    """OUTDIR/sub a symbolic link to a missing folder, or to a regular file outside OUTDIR, where
    OUTDIR/sub/x.ply needs a folder: those inputs fail before they are read, saying what is there;
    the link stays; the other inputs are done and the table written. A link to nothing was read and
    normalized, then failed on the write ("FileExistsError: [Errno 17] File exists"); a link to a
    file ended the whole run (NotADirectoryError from the removal of temporaries: no table, the
    other inputs not done)."""
    scans, out = tmp_path / "scans", tmp_path / "out"
    good_meshes(scans / "sub", count=1)
    good_meshes(scans / "other", count=1)
    out.mkdir()
    pointed = tmp_path / "nowhere" if target == "missing" else tmp_path / "elsewhere.txt"
    if target == "file":
        pointed.write_text("mine")
    (out / "sub").symlink_to(pointed)
    code, _, err = cli(scans, "-o", out, "--force", "--workers", "1")
    assert code == 1 and "1 of 2 inputs failed" in err and "Traceback" not in err, err
    rows = {os.path.relpath(r.input, scans): r for r in jaxpose.read_transforms(out / "transforms.parquet")}
    row, name = rows["sub/good_0.ply"], "sub/good_0.ply"
    said = f"a symbolic link to a missing folder ({pointed})" if target == "missing" else \
        "a symbolic link to a file, not a folder"
    assert row.status == "failed" and row.error == f"cannot write {out / name}: {out / 'sub'} is {said}"
    assert row.vertices is None and row.seconds is None and not row.worker  # never read: no worker's record
    assert rows["other/good_0.ply"].ok and os.readlink(out / "sub") == str(pointed)
    assert target == "missing" or pointed.read_text() == "mine"


def test_a_file_that_changes_between_the_listing_and_the_read(tmp_path):
    """The listing is done and the run has started (its worker is reading a FIFO) when the file
    is replaced: the row describes the bytes read (size, time, SHA-256) and the output is theirs."""
    import hashlib

    scans = tmp_path / "scans"
    target = good_meshes(scans, count=1)[0]
    fifo = scans / "first.ply"
    os.mkfifo(fifo)
    replacement = trimesh.creation.icosphere(subdivisions=2, radius=3.0)
    replacement.apply_translation([5.0, 0.0, 0.0])

    def writer():
        with open(fifo, "wb") as pipe:  # blocks until the run's worker opens it to read
            replacement.export(target)  # the file changes after the listing, before its read
            pipe.write(trimesh.creation.box().export(file_type="ply"))

    thread = threading.Thread(target=writer, daemon=True)
    thread.start()
    result = batch.run_batch([fifo, target], tmp_path / "out", FAST, workers=1, check="hash", progress=False)
    thread.join(timeout=60)
    rows = by_name(result.rows)
    assert rows["first.ply"].ok and rows["first.ply"].input_size is None  # a FIFO has no size
    row = rows[target.name]
    assert row.ok and row.vertices == len(replacement.vertices)
    assert row.input_size == target.stat().st_size and row.input_mtime_ns == target.stat().st_mtime_ns
    assert row.input_sha256 == hashlib.sha256(target.read_bytes()).hexdigest()
    assert_normalized(row)
    again = batch.run_batch([target], tmp_path / "out", FAST, workers=1, check="hash", progress=False)
    assert again.skipped == 1  # the record matches the file as it is


def test_a_fifo_that_never_delivers_times_out_and_the_rest_completes(tmp_path):
    good = good_meshes(tmp_path / "scans", count=3)
    fifo = tmp_path / "scans" / "never.ply"
    os.mkfifo(fifo)
    start = time.monotonic()
    # bbox: NumPy only, milliseconds a file (a worker's start-up is outside the limit: warm_up)
    code, out, err = cli(fifo, *good, "-o", tmp_path / "out", "--timeout", "5", "--workers", "2", "--method", "bbox",
                         timeout=300)
    wall = time.monotonic() - start
    assert code == 1 and "1 of 4 inputs failed" in err, err
    rows = by_name(jaxpose.read_transforms(tmp_path / "out" / "transforms.parquet"))
    assert rows["never.ply"].status == "failed" and "time limit of 5 s" in rows["never.ply"].error
    assert all(rows[p.name].ok for p in good)
    print(f"FIFO with --timeout 5: the run took {wall:.1f} s")


def as_a_user(tmp_path):
    """A command prefix under which file permissions hold: none for a user; for root, who reads
    anything, ``setpriv`` dropping the capabilities that override them. Skips where neither works."""
    if os.geteuid() != 0:
        return []
    prefix = ["setpriv", "--bounding-set", "-dac_override,-dac_read_search"]
    probe = tmp_path / "probe"
    probe.write_text("x")
    probe.chmod(0)
    try:
        denied = subprocess.run([*prefix, "cat", str(probe)], capture_output=True).returncode != 0
    except OSError:
        denied = False
    probe.unlink()
    if not denied:
        pytest.skip("running as root without setpriv: permissions cannot be denied")
    return prefix


def test_a_folder_that_cannot_be_searched_fails_naming_it_and_a_rerun_takes_its_files(tmp_path):
    """A sub-folder of a searched folder that cannot be listed (chmod 000) is a failed row naming
    it, and an unreadable file one of its own; the rest of the run completes. The folder's files
    were left out without a word (exit 0, no row), and a folder INPUT that cannot be listed gave
    'no mesh files found'."""
    prefix = as_a_user(tmp_path)
    scans = tmp_path / "scans"
    good = good_meshes(scans, count=2)
    hidden = good_meshes(scans / "locked", count=1)
    good[1].chmod(0)
    (scans / "locked").chmod(0)
    try:
        code, out, err = cli(scans, "-o", tmp_path / "out", "--workers", "1", prefix=prefix)
        refused = cli(scans / "locked", "-o", tmp_path / "out2", prefix=prefix)
    finally:
        (scans / "locked").chmod(0o755)
        good[1].chmod(0o644)
    assert code == 1 and "2 of 3 inputs failed" in err, err
    rows = by_name(jaxpose.read_transforms(tmp_path / "out"))
    assert sorted(rows) == ["good_0.ply", "good_1.ply", "locked"]
    assert rows["locked"].status == "failed" and "cannot search this folder: Permission denied" in rows["locked"].error
    assert rows["good_1.ply"].status == "failed" and "cannot read: Permission denied" in rows["good_1.ply"].error
    assert f"jaxpose: failed: {scans / 'locked'}: cannot search this folder" in err
    assert_normalized(rows["good_0.ply"])
    assert refused[0] == 1 and "cannot search the folder" in refused[2] and "Permission denied" in refused[2]
    assert not (tmp_path / "out2").exists()
    again = jaxpose.normalize_files(scans, tmp_path / "out", FAST, workers=1)  # readable now: its files are done
    assert [r.input for r in again] == [str(p) for p in good + hidden] and all(r.ok for r in again)
    assert_normalized(again[-1])


def test_a_file_in_a_folder_that_cannot_be_searched_fails_as_unreadable(tmp_path):
    """A file INPUT in a folder this user may not search (chmod 000) fails as an unreadable file:
    a failed row beside the others, or the one file's error. It raised PermissionError out of
    pathlib (``jaxpose: error: PermissionError: [Errno 13] ...``), the whole run with it."""
    prefix = as_a_user(tmp_path)
    good = good_meshes(tmp_path / "scans", count=1)
    locked = good_meshes(tmp_path / "locked", count=1)[0]
    locked.parent.chmod(0)
    try:
        code, out, err = cli(locked, *good, "-o", tmp_path / "out", "--workers", "1", prefix=prefix)
        one = cli(locked, "-o", tmp_path / "one.ply", prefix=prefix)
    finally:
        locked.parent.chmod(0o755)
    assert code == 1 and "1 of 2 inputs failed" in err and "PermissionError" not in err, err
    rows = jaxpose.read_transforms(tmp_path / "out")
    failed = [r for r in rows if not r.ok]
    assert [r.input for r in failed] == [str(locked)] and "cannot read: Permission denied" in failed[0].error
    assert_normalized(next(r for r in rows if r.ok))
    assert one[0] == 1 and one[2].strip() == f"jaxpose: error: {locked}: cannot read: Permission denied", one[2]
    assert not (tmp_path / "one.ply").exists()


def test_a_table_that_cannot_be_written_is_named_and_a_rerun_writes_it(tmp_path):
    """The table, written last, failing (a full disk; here a file size limit, ``ulimit -f``: the
    outputs fit, the table does not) ended the run with "jaxpose: error: OSError: [Errno 27] File
    too large", naming nothing: now the table and why, the outputs kept with their records, and a
    rerun writes it."""
    scans = tmp_path / "scans"
    scans.mkdir()
    tetra = "OFF\n4 4 0\n0 0 0\n1 0 0\n0 1 0\n0 0 {}\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n"
    for i in (1, 2):
        (scans / f"t{i}.off").write_text(tetra.format(i))
    args = [sys.executable, "-m", "jaxpose", "normalize", str(scans), "-o", str(tmp_path / "out"), "--workers", "1",
            "--method", "bbox"]
    # the limit set in the child, then exec (a preexec_fn would fork this JAX-threaded process; Python
    # ignores SIGXFSZ: a write past the limit fails with EFBIG)
    limited = [sys.executable, "-c", "import os, resource, sys; resource.setrlimit(resource.RLIMIT_FSIZE, "
               "(4096, 4096)); os.execv(sys.argv[1], sys.argv[1:])", *args]
    first = subprocess.run(limited, cwd=ROOT, capture_output=True, text=True, timeout=120)
    last = first.stderr.strip().splitlines()[-1]
    assert first.returncode == 1 and last.startswith(f"jaxpose: error: cannot write the table {tmp_path / 'out'}/"
                                                     "transforms."), first.stderr
    assert "File too large" in last and "OSError" not in last
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == [".jaxpose", "t1.off", "t2.off"]  # no temporary
    again = subprocess.run(args, cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert again.returncode == 0 and "0 files" in again.stdout and "2 already done" in again.stdout, again.stderr
    rows = jaxpose.read_transforms(tmp_path / "out")
    assert len(rows) == 2
    for row in rows:  # bbox: the bounding box's center; the outputs are the inputs under the rows (OFF: 10 decimals)
        vertices = mesh.load(row.input).vertices
        np.testing.assert_allclose(row.center, (vertices.min(0) + vertices.max(0)) / 2)
        np.testing.assert_allclose(mesh.load(row.output).vertices, row.apply(vertices), atol=1e-9)
