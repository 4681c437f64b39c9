"""Atomic writes: nothing partial and no temporary left, whatever stops the write."""
import os

import pytest

from jaxpose.io.atomic import check_folder_writable, is_temporary, remove_temporaries, temporary_path, write_atomic
from jaxpose.errors import InvalidInputError


@pytest.mark.parametrize("stop", [KeyboardInterrupt, SystemExit, OSError])
def test_interrupted_write_leaves_the_old_file_and_no_temporary(tmp_path, monkeypatch, stop):
    target = tmp_path / "out.ply"
    target.write_bytes(b"old")
    real_fsync = os.fsync

    def fsync_then_stop(fd):
        real_fsync(fd)
        raise stop()

    monkeypatch.setattr(os, "fsync", fsync_then_stop)
    with pytest.raises(stop):
        write_atomic(target, b"new", force=True)
    assert target.read_bytes() == b"old" and sorted(os.listdir(tmp_path)) == ["out.ply"]


def test_write_keeps_the_mode_and_refuses_without_force(tmp_path):
    target = tmp_path / "t.json"
    target.write_text("{}")
    os.chmod(target, 0o640)
    with pytest.raises(InvalidInputError, match="exists"):
        write_atomic(target, "x")
    write_atomic(target, "new", force=True)
    assert target.read_text() == "new" and (target.stat().st_mode & 0o777) == 0o640
    with pytest.raises(InvalidInputError, match="does not exist"):
        write_atomic(tmp_path / "no" / "t.json", "x")


def test_temporaries_of_a_killed_writer_are_found_and_only_they(tmp_path):
    target = tmp_path / "a.ply"
    left = temporary_path(target)
    left.write_bytes(b"half")
    other = temporary_path(tmp_path / "b.ply")
    other.write_bytes(b"half")
    keep = [tmp_path / ".a.ply.tmp", tmp_path / "a.ply.0123456789ab.tmp", tmp_path / ".a.ply.notahexnumbr.tmp"]
    for path in keep:
        path.write_bytes(b"user's")
    assert is_temporary(left.name) and not any(is_temporary(p.name) for p in keep)
    assert remove_temporaries(target) == 1 and not left.exists() and other.exists()
    assert all(p.exists() for p in keep)
    # no folder where the target's is needed: a file, a link to one, a loop of links (a shard run's
    # cleanup raised OSError ELOOP): no temporaries there
    (tmp_path / "file").write_text("x")
    (tmp_path / "loop1").symlink_to(tmp_path / "loop2")
    (tmp_path / "loop2").symlink_to(tmp_path / "loop1")
    for folder in ("file", "loop1", "missing"):
        assert remove_temporaries(tmp_path / folder / "x.ply") == 0


def test_check_folder_writable(tmp_path):
    assert check_folder_writable(tmp_path) == tmp_path
    (tmp_path / "f").write_text("")
    with pytest.raises(InvalidInputError, match="is not a folder"):
        check_folder_writable(tmp_path / "f")
    if os.geteuid() != 0:  # root may write anywhere
        os.chmod(tmp_path, 0o500)
        try:
            with pytest.raises(InvalidInputError, match="not writable"):
                check_folder_writable(tmp_path)
        finally:
            os.chmod(tmp_path, 0o700)


def test_what_is_not_a_regular_file_is_never_replaced(tmp_path):
    """A FIFO, a device and a link to an open file descriptor (/dev/stdout -> /proc/self/fd/1,
    whatever that is: a pipe, a terminal, a redirected file) are refused, force or not, and left as
    they are; the rename replaced them with a file (as root, --transform /dev/stdout --force
    replaced the system's /dev/stdout link). A regular file and a link to one are written as before."""
    from jaxpose import cli
    from jaxpose.io.atomic import check_output_file

    fifo = tmp_path / "fifo.json"
    os.mkfifo(fifo)
    device = tmp_path / "null.json"
    os.symlink(os.devnull, device)
    with open(tmp_path / "stream", "wb") as stream:  # a redirected stdout: a regular file behind the link
        fd_link = tmp_path / "stdout.json"
        os.symlink(f"/proc/self/fd/{stream.fileno()}", fd_link)
        for path, kind in ((fifo, "a FIFO"), (device, "a character device"),
                           (fd_link, r"a link to an open file descriptor \(a standard stream\)")):
            with pytest.raises(InvalidInputError, match=rf"{path} is {kind}, not a file: .* name a regular file"):
                write_atomic(path, b"{}", force=True)
            with pytest.raises(InvalidInputError, match=rf"--json {path} is {kind}"):
                check_output_file(path, force=True)
            source = tmp_path / "tetra.off"
            source.write_text("OFF\n4 4 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n")
            assert cli.main(["normalize", str(source), "--method", "vertex_mean", "-o", str(tmp_path / "o.ply"),
                             "--transform", str(path), "--force"]) == 2  # before any work
            assert not (tmp_path / "o.ply").exists()
    assert (tmp_path / "stream").read_bytes() == b""
    assert os.path.islink(fd_link) and os.path.islink(device) and os.stat(fifo).st_mode & 0o170000 == 0o010000
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fifo.json", "null.json", "stdout.json", "stream",
                                                           "tetra.off"]  # no temporary left
    target = tmp_path / "target.json"
    target.write_text("old")
    link = tmp_path / "link.json"
    os.symlink(target, link)
    write_atomic(link, b"new", force=True)  # a link to a regular file: written through, the link kept
    assert link.read_bytes() == b"new"
    assert os.path.islink(link) and target.read_bytes() == b"new"  # (the link was replaced by a file, its target left)


def test_a_link_whose_target_folder_is_missing_is_refused_before_the_work(tmp_path, monkeypatch):
    """An output that is a dangling symbolic link into a folder that does not exist (the write goes
    to its target, whose folder is never made) is a usage error before any work, as other unusable
    output paths are: -o was refused only when written, after the normalization."""
    from jaxpose import cli, mesh
    from jaxpose.io.atomic import check_output_file

    link = tmp_path / "link.ply"
    os.symlink(tmp_path / "nowhere" / "x.ply", link)
    message = rf"{link} \(a link to {tmp_path / 'nowhere' / 'x.ply'}\): the folder {tmp_path / 'nowhere'} does not exist"
    with pytest.raises(InvalidInputError, match="--json " + message):
        check_output_file(link)
    with pytest.raises(InvalidInputError, match=message):
        write_atomic(link, b"x")
    source = tmp_path / "tetra.off"
    source.write_text("OFF\n4 4 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n")
    monkeypatch.setattr(mesh, "normalize_mesh", lambda *a, **k: pytest.fail("the work started"))
    assert cli.main(["normalize", str(source), "-o", str(link)]) == 2
    assert cli.main(["normalize", str(source), "-o", str(tmp_path / "o.ply"), "--transform", str(link)]) == 2
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link.ply", "tetra.off"] and os.path.islink(link)


def test_a_loop_of_links_or_a_folder_is_refused_not_replaced(tmp_path):
    """A loop of links (loop1 -> loop2 -> loop1) was replaced by a regular file (the link is to be
    kept); a folder, or a link to one, raised a raw IsADirectoryError: all refused by name, as
    check_output_file (--json, -o) does before any work."""
    from jaxpose.errors import UsageError
    from jaxpose.io.atomic import check_output_file

    loop1, loop2, folder, to_folder = (tmp_path / n for n in ("loop1", "loop2", "folder", "to_folder"))
    os.symlink(loop2, loop1)
    os.symlink(loop1, loop2)
    folder.mkdir()
    os.symlink(folder, to_folder)
    for path, fragment in ((loop1, "is a symbolic link that cannot be resolved"), (folder, "is a folder"),
                           (to_folder, "is a folder")):
        for force in (False, True):
            with pytest.raises(UsageError, match=f"{path.name} {fragment}"):
                write_atomic(path, b"x", force=force)
        with pytest.raises(UsageError, match=fragment):
            check_output_file(path, force=True)
    assert os.readlink(loop1) == str(loop2) and os.readlink(loop2) == str(loop1)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["folder", "loop1", "loop2", "to_folder"]
    assert list(folder.iterdir()) == []
