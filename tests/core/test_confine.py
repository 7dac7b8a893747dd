"""Names from user input: safe path components, confined files, plain format templates."""

import os
import stat

import pytest

from workbench.calset import atomic_write_text
from workbench.cli import main
from workbench.confine import confined_path, plain_line, plain_template, safe_component
from workbench.errors import WorkbenchError


@pytest.mark.parametrize("serial", ["U1", "imu-0007", "SN_12.3+a", "a" * 64])
def test_safe_serials_pass(serial):
    assert safe_component(serial) == serial


@pytest.mark.parametrize("serial", ["../../x", "a/b", "..", ".hidden", "", "a" * 65, "x\x00", "SN[/]x", "a b",
                                    "a..b", "C:x", "-rf"])
def test_unsafe_serials_refused(serial):
    with pytest.raises(WorkbenchError, match="use 1-64 letters"):
        safe_component(serial, "--serial")


@pytest.mark.parametrize("text", ["m\u202eevil", "a\u2066b\u2069", "zero\u200bwidth", "\ufeffbom", "a\nb", "\x1b[2J"])
def test_plain_lines_refuse_invisible_reordering_characters(text):
    # a model 'm<RLO>evil' reads backwards in a certificate, an export comment, the dashboard
    with pytest.raises(WorkbenchError, match="expected one line of at most 200 printable characters"):
        plain_line(text, "unit.model")


@pytest.mark.parametrize("text", ["IMU-700 CA-200", "Størmer °/h ±2 µg", "日本語モデル", ""])
def test_plain_lines_pass(text):
    assert plain_line(text) == text


def test_confined_path(tmp_path):
    assert confined_path(tmp_path, "a/b.json") == (tmp_path / "a" / "b.json").resolve()
    for bad in ("/etc/passwd", "../x", "a/../../x", "C:\\x", "\\\\server\\share"):
        with pytest.raises(WorkbenchError):
            confined_path(tmp_path, bad)


def test_plain_template():
    assert plain_template("{stem}_list.json", {"stem"}) == "{stem}_list.json"
    for bad in ("{stem.__init__}", "{0}", "{stem[0]}", "{", "{x}"):
        with pytest.raises(WorkbenchError):
            plain_template(bad, {"stem"})


def test_serial_option_cannot_escape_runs(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("WORKBENCH_DB", f"sqlite:///{tmp_path}/w.db")
    assert main(["run", "multiposition", "--serial", "../../x", "-o", "dwell_s=1", "--no-store"]) == 2
    err = capsys.readouterr().err
    assert "--serial '../../x'" in err and len(err.strip().splitlines()) == 1
    assert [p.name for p in tmp_path.iterdir()] in ([], ["w.db"])  # no runs/, nothing beside it
    assert not (tmp_path.parent.parent / "x").exists()


def test_files_get_the_users_umask(tmp_path):
    old = os.umask(0o022)
    try:
        path = atomic_write_text(tmp_path / "a.json", "{}")
        assert stat.S_IMODE(path.stat().st_mode) == 0o644
        os.umask(0o007)
        path = atomic_write_text(tmp_path / "b.json", "{}")
        assert stat.S_IMODE(path.stat().st_mode) == 0o660
    finally:
        os.umask(old)
