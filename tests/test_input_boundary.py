"""Inputs at the public boundary that once hung or were accepted silently: a named pipe with no
writer, the OCSVM's options given to an estimator that ignores them, numbers beyond a float's
range, truncated PLY and OBJ files. Each ends in a clear InvalidInputError naming the file or the
option (or a correct result), never a hang."""
from __future__ import annotations

import os
import re
import sys
import threading
import time

import numpy as np
import pytest
import trimesh

import jaxpose
from jaxpose.batch.task import NormalizeOptions
from jaxpose.errors import InvalidInputError
from jaxpose.io import mesh as io_mesh

linux = pytest.mark.skipif(sys.platform != "linux", reason="FIFOs as Linux reports them")


def in_thread(call, seconds):
    """call() in a daemon thread: ("returned", value) | ("raised", exc) | ("still running", None)
    after `seconds`."""
    out = []

    def target():
        try:
            out.append(("returned", call()))
        except BaseException as exc:  # noqa: BLE001 - handed back to the test
            out.append(("raised", exc))

    thread = threading.Thread(target=target, daemon=True)
    thread.start()
    thread.join(seconds)
    return out[0] if out else ("still running", None)


def release(fifo):
    """Let a reader blocked in open() of `fifo` go on (it reads an empty stream)."""
    try:
        os.close(os.open(fifo, os.O_WRONLY | os.O_NONBLOCK))
    except OSError:  # no reader left: nothing to release
        pass


@linux
def test_a_named_pipe_with_no_writer_fails_instead_of_hanging(tmp_path, monkeypatch):
    monkeypatch.setattr(io_mesh, "PIPE_WAIT_S", 0.5, raising=False)
    fifo = tmp_path / "silent.ply"
    os.mkfifo(fifo)
    try:
        outcome, value = in_thread(lambda: jaxpose.normalize_mesh(fifo, method="bbox"), 30)
    finally:
        release(fifo)
    assert outcome == "raised", f"{outcome}: a FIFO with no writer must not block the read"
    assert isinstance(value, InvalidInputError)
    assert str(fifo) in str(value) and "named pipe" in str(value) and "0.5 s" in str(value)


@linux
def test_a_named_pipe_whose_writer_comes_late_is_read_whole(tmp_path, monkeypatch):
    monkeypatch.setattr(io_mesh, "PIPE_WAIT_S", 30.0, raising=False)
    fifo = tmp_path / "late.ply"
    os.mkfifo(fifo)
    box = trimesh.creation.box(extents=(2.0, 1.0, 0.5))
    data = box.export(file_type="ply")

    def writer():
        time.sleep(0.3)  # the reader is already waiting
        with open(fifo, "wb") as pipe:
            for i in range(0, len(data), 97):  # in pieces: the reader goes on to the end of the stream
                pipe.write(data[i:i + 97])
                pipe.flush()

    thread = threading.Thread(target=writer, daemon=True)
    thread.start()
    try:
        outcome, value = in_thread(lambda: jaxpose.mesh.load(fifo), 60)
    finally:
        release(fifo)
        thread.join(5)
    assert outcome == "returned", value
    np.testing.assert_array_equal(np.asarray(value.vertices), np.asarray(box.vertices))
    np.testing.assert_array_equal(np.asarray(value.faces), np.asarray(box.faces))


# --------------------------------------------------------------------------- the OCSVM's options
# gamma, nu, count, seed, sampling are read by the OCSVM alone (jaxpose.pose.estimators and the
# ocsvm frame); the command line refuses them with any other estimator (tests/test_cli_habits.py)
@pytest.mark.parametrize("kwargs,named", [
    (dict(method="robust", gamma=5.0), "gamma"),
    (dict(gamma=5.0, nu=0.3), "gamma, nu"),  # the default method, robust
    (dict(method="bbox", count=100), "count"),
    (dict(center="surface_centroid", scale="sqrt_area", seed=3, sampling="random"), "seed, sampling"),
])
def test_options_of_the_ocsvm_are_refused_by_the_estimators_that_ignore_them(kwargs, named):
    box = trimesh.creation.box(extents=(2.0, 1.0, 0.5))
    with pytest.raises(InvalidInputError, match=f"^{named} (is an option|are options) of the ocsvm estimator"):
        jaxpose.normalize_mesh(box, **kwargs)
    with pytest.raises(InvalidInputError, match=f"^{named} (is an option|are options) of the ocsvm estimator"):
        NormalizeOptions(**kwargs)  # the dataset command's options: the same refusal


def test_options_of_the_ocsvm_are_taken_where_the_ocsvm_reads_them():
    """Where an OCSVM is asked for (here only as the frame), its options pass; without them the
    defaults hold and the estimator named runs (a box's bbox center: its translation)."""
    from jaxpose.config import OCSVM
    from jaxpose.mesh import check_arguments

    box = trimesh.creation.box(extents=(2.0, 1.0, 0.5))
    box.apply_translation([1.0, -2.0, 3.0])
    check_arguments(method="bbox", rotation="ocsvm", gamma=5.0, count=100)  # no refusal
    _, pose = jaxpose.normalize_mesh(box, method="bbox")
    np.testing.assert_allclose(np.asarray(pose.center), [1.0, -2.0, 3.0], atol=1e-12)
    assert NormalizeOptions(method="bbox").gamma == OCSVM.gamma


# --------------------------------------------------------------------------- real numbers, one check
HUGE = 10**400  # an int no float holds


def test_an_int_beyond_a_floats_range_is_refused_by_name(tmp_path):
    """_validate.check_real behind power (normalize_mesh) and timeout (the dataset run): an int
    beyond float64's range is no finite number (it was a raw OverflowError from float())."""
    assert HUGE > sys.float_info.max
    box = trimesh.creation.box(extents=(2.0, 1.0, 0.5))
    with pytest.raises(InvalidInputError, match="^power must be a finite number >= 0, got an int of 1329 bits$"):
        jaxpose.normalize_mesh(box, power=HUGE)
    from jaxpose.batch import batch

    box.export(tmp_path / "box.ply")
    with pytest.raises(InvalidInputError, match=r"^timeout \(seconds\) must be a finite number > 0"):
        batch.run_batch([tmp_path / "box.ply"], tmp_path / "out", timeout=HUGE, progress=False)
    assert not (tmp_path / "out").exists()  # refused before any work


@pytest.mark.parametrize("bad", ["2", True, HUGE, float("nan")], ids=["str", "bool", "huge_int", "nan"])
def test_the_depth_weighted_solid_checks_its_power_as_every_power(bad):
    """voxels.depth_weighted_solid had its own check: a string was a raw TypeError from
    np.isfinite, True passed as the power 1."""
    from jaxpose.occupancy import voxels

    with pytest.raises(InvalidInputError, match="^power must be a finite number >= 0"):
        voxels.depth_weighted_solid(trimesh.creation.box(), power=bad)


# --------------------------------------------------------------------------- truncated files
def cloud_ply(encoding):
    points = np.random.default_rng(0).normal(size=(30, 3))
    return trimesh.PointCloud(points).export(file_type="ply", encoding=encoding)


def trimesh_reads(path):
    """What trimesh makes of a file without a word (the partial read the fix refuses)."""
    return trimesh.load(path, process=False)


@pytest.mark.parametrize("case", ["ascii_lines", "binary_faces"])
def test_a_truncated_ply_file_is_refused_naming_it(tmp_path, case):
    """An ASCII point cloud short of lines (its header says 30 vertices), a binary mesh cut where
    its faces begin: trimesh reads a point cloud of what is there, jaxpose refuses the file."""
    if case == "ascii_lines":
        data = cloud_ply("ascii")
        cut = data[:data.index(b"end_header\n") + 11]
        cut += b"".join(data[len(cut):].splitlines(keepends=True)[:12])  # 12 whole vertex lines of 30
    else:
        box = trimesh.creation.box()
        data = box.export(file_type="ply", encoding="binary")
        body = data.index(b"end_header\n") + 11
        cut = data[:body + len(box.vertices) * 3 * 4]  # the vertices (3 float32 each), no face
    path = tmp_path / "cut.ply"
    path.write_bytes(cut)
    partial = trimesh_reads(path)
    assert isinstance(partial, trimesh.PointCloud) and len(partial.vertices) in (12, 8)  # read in part
    with pytest.raises(InvalidInputError, match=f"^{re.escape(str(path))}: cannot read PLY file: truncated"):
        jaxpose.mesh.load(path)


@pytest.mark.parametrize("tail,what", [("f 1 3", "face 3 .* fewer than 3 corners"), ("f", "a line 'f' without values"),
                                      ("v 1 1", "vertex 5 has fewer than 3 coordinates")])
def test_an_obj_file_cut_within_its_last_line_is_refused_naming_it(tmp_path, tail, what):
    """trimesh drops a face of fewer than 3 corners, or a vertex of fewer than 3 values, without a
    word; such a line is not OBJ (a face has 3 corners or more, a vertex x y z [w]): most often a
    truncated file's last line."""
    path = tmp_path / "cut.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\n" + tail)
    assert len(trimesh_reads(path).faces) == 2  # the whole faces only
    with pytest.raises(InvalidInputError, match=f"^{re.escape(str(path))}: cannot read OBJ file: {what}"):
        jaxpose.mesh.load(path)
