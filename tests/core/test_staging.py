"""Folders that appear whole or not at all (workbench/staging.py)."""

import pytest

from workbench.errors import WorkbenchError
from workbench.staging import refuse_existing, staged_folder


def test_success_renames_the_staged_folder_into_place(tmp_path):
    target = tmp_path / "out" / "session"
    with staged_folder(target) as tmp:
        assert tmp.parent == target.parent and tmp.name.startswith(".session.")
        (tmp / "a.txt").write_text("x")
        assert not target.exists()  # nothing visible until the block succeeds
    assert (target / "a.txt").read_text() == "x"
    assert [p.name for p in target.parent.iterdir()] == ["session"]


def test_failure_leaves_nothing(tmp_path):
    target = tmp_path / "session"
    with pytest.raises(RuntimeError):
        with staged_folder(target) as tmp:
            (tmp / "half.txt").write_text("x")
            raise RuntimeError("interrupted")
    assert list(tmp_path.iterdir()) == []


def test_existing_content_is_refused_and_kept(tmp_path):
    target = tmp_path / "session"
    target.mkdir()
    (target / "keep.txt").write_text("mine")
    with pytest.raises(WorkbenchError, match=r"session: already exists; choose a new profile folder"):
        with staged_folder(target, "profile folder"):
            pass
    assert (target / "keep.txt").read_text() == "mine"
    refuse_existing(tmp_path / "empty")  # a missing target is fine
    (tmp_path / "empty").mkdir()
    refuse_existing(tmp_path / "empty")  # and so is an empty folder
    (tmp_path / "f").write_text("")
    with pytest.raises(WorkbenchError, match="already exists"):
        refuse_existing(tmp_path / "f")


def test_someone_else_creating_the_target_meanwhile_is_refused(tmp_path):
    target = tmp_path / "session"
    with pytest.raises(WorkbenchError, match="already exists"):
        with staged_folder(target):
            target.mkdir()
            (target / "theirs.txt").write_text("x")
    assert [p.name for p in target.iterdir()] == ["theirs.txt"]
    assert [p.name for p in tmp_path.iterdir()] == ["session"]  # the staged folder is gone
