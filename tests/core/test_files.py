"""File helpers (workbench/files.py): atomic writes with the user's permissions, digests."""

import hashlib
import os

import pytest

from workbench.files import atomic_write_text, file_sha256, umask


def test_umask_is_read_without_changing_it():
    before = os.umask(0o027)
    os.umask(before)
    try:
        os.umask(0o027)
        assert umask() == 0o027
        assert umask() == 0o027  # reading it twice does not change it
    finally:
        os.umask(before)


def test_atomic_write_replaces_whole_with_the_user_permissions(tmp_path):
    path = tmp_path / "sub" / "a.json"
    atomic_write_text(path, "one")
    atomic_write_text(path, "two")
    assert path.read_text() == "two"
    assert (path.stat().st_mode & 0o777) == 0o666 & ~umask()
    assert [p.name for p in path.parent.iterdir()] == ["a.json"]  # no temp file left


def test_failed_write_keeps_the_old_file_and_leaves_no_temp(tmp_path):
    path = tmp_path / "a.txt"
    atomic_write_text(path, "old")
    with pytest.raises(TypeError):
        atomic_write_text(path, b"not text")  # type: ignore[arg-type]
    assert path.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["a.txt"]


def test_sha256_of_a_file_larger_than_one_chunk(tmp_path):
    data = os.urandom((1 << 20) + 12345)
    path = tmp_path / "blob"
    path.write_bytes(data)
    assert file_sha256(path) == hashlib.sha256(data).hexdigest()


def test_a_path_that_cannot_be_written_is_one_workbench_error(tmp_path):
    """--out naming a folder, or a file under a file, was an IsADirectoryError / NotADirectoryError traceback."""
    from workbench.errors import WorkbenchError

    (tmp_path / "f").write_text("x")
    with pytest.raises(WorkbenchError, match=r"d: cannot write \(is a folder\)"):
        (tmp_path / "d").mkdir()
        atomic_write_text(tmp_path / "d", "text")
    with pytest.raises(WorkbenchError, match=r"f/x.json: cannot write \(.*f is a file, not a folder\)"):
        atomic_write_text(tmp_path / "f" / "x.json", "text")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d", "f"]
