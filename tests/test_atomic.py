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
