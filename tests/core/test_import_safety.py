"""Import safety (issue 16): confined sections files, bounded YAML, --out never overwrites, no half folders."""

import json
import time
from pathlib import Path

import pytest
import yaml

from workbench.cli import main
from workbench.errors import ImportProfileError, WorkbenchError
from workbench.importer import import_file, load_profile

N = 400  # samples of the synthetic recording: two static sections of 200 at 100 Hz


def _recording(folder: Path, sections_file: str = "{stem}_list.json") -> tuple[Path, Path]:
    """A small static recording (gravity on -z in g, zero rate), its sections file and a profile."""
    folder.mkdir(parents=True, exist_ok=True)
    data = folder / "rec.csv"
    rows = ["n,gx,gy,gz,ax,ay,az"] + [f"{i},0.0,0.0,0.0,0.0,0.0,{-1.0 if i < 200 else 1.0}" for i in range(N)]
    data.write_text("\n".join(rows) + "\n")
    (folder / "rec_list.json").write_text(json.dumps({"a": {"start": 0, "end": 200}, "b": {"start": 200, "end": 400}}))
    prof = {"format": "workbench-import/1", "sample_rate_hz": 100.0, "time": {"counter": "n"},
            "site": {"latitude_deg": 45.0},
            "columns": {c: {"column": c, "unit": "deg/s" if c[0] == "g" else "g"} for c in
                        ("gx", "gy", "gz", "ax", "ay", "az")},
            "sections": {"file": sections_file, "steps": {"a": {"kind": "static", "mount": "z-down"},
                                                          "b": {"kind": "static", "mount": "z-up"}}}}
    profile = folder / "p.yaml"
    profile.write_text(yaml.safe_dump(prof))
    return profile, data


def _nothing_left(parent: Path, name: str) -> None:
    assert not (parent / name).exists()
    assert not [p for p in parent.iterdir() if p.name.startswith(f".{name}.")]  # no staging folder left


def test_the_synthetic_recording_imports(tmp_path):
    profile, data = _recording(tmp_path / "d")
    s = import_file(profile, data, tmp_path / "s")
    assert [st.label for st in s.steps] == ["a", "b"] and len(s.samples) == N


@pytest.mark.parametrize("name,match", [
    ("/etc/passwd", "no absolute path"),
    ("../outside.json", r"no '\.\.'"),
    ("sub/../../outside.json", r"no '\.\.'"),
    ("{stem.__class__}.json", r"field \{stem.__class__\} is not a plain name"),
    ("{stem[0]}.json", "is not a plain name"),
    ("{home}.json", r"unknown field \{home\}"),
])
def test_sections_file_confined_to_the_data_folder(tmp_path, name, match):
    (tmp_path / "outside.json").write_text(json.dumps({"a": [0, 200]}))
    profile, data = _recording(tmp_path / "d", name)
    with pytest.raises(ImportProfileError, match=match):
        import_file(profile, data, tmp_path / "s")
    _nothing_left(tmp_path, "s")


@pytest.mark.parametrize("content,match", [
    ("[[0, 200], [200, 400]]", "expected {section: {start: N, end: N}}, got list"),
    ('{"a": {"start": "x", "end": 200}, "b": [200, 400]}', "section a: expected whole sample counts"),
    ('{"a": [0, 200.5], "b": [200, 400]}', "section a: expected whole sample counts"),
    ('{"a": [200, 0], "b": [200, 400]}', "section a: expected whole sample counts 0 <= start < end"),
    ('{"a": [0], "b": [200, 400]}', "section a"),
    ('{"a": 5, "b": [200, 400]}', "section a"),
])
def test_a_malformed_sections_file_names_the_file_and_section(tmp_path, capsys, content, match):
    """The sections file is the recording's (another tool wrote it): its contents were KeyError / TypeError tracebacks."""
    profile, data = _recording(tmp_path / "d")
    (tmp_path / "d" / "rec_list.json").write_text(content)
    assert main(["import", str(profile), str(data), "--out", str(tmp_path / "s")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err and f"rec_list.json: {match}" in err, err
    _nothing_left(tmp_path, "s")


def test_a_data_file_whose_name_is_no_serial_needs_unit_serial(tmp_path, capsys):
    """Without unit.serial the data file's name is the serial, which names folders: 'my rec' is refused."""
    profile, data = _recording(tmp_path / "d")
    named = data.rename(data.with_name("my rec.csv"))
    (tmp_path / "d" / "my rec_list.json").write_text((tmp_path / "d" / "rec_list.json").read_text())
    assert main(["import", str(profile), str(named), "--out", str(tmp_path / "s")]) == 2
    assert "no unit.serial, and the data's name 'my rec': use 1-64 letters" in capsys.readouterr().err
    _nothing_left(tmp_path, "s")


def test_a_symlink_out_of_the_data_folder_is_refused(tmp_path):
    (tmp_path / "outside.json").write_text(json.dumps({"a": [0, 200]}))
    profile, data = _recording(tmp_path / "d", "link.json")
    (tmp_path / "d" / "link.json").symlink_to(tmp_path / "outside.json")
    with pytest.raises(ImportProfileError, match="resolves outside"):
        import_file(profile, data, tmp_path / "s")


def test_a_1kb_alias_bomb_is_refused_quickly(tmp_path):
    lines = ['a: &a ["x","x","x","x","x","x","x","x","x","x"]']
    for i in range(1, 9):
        lines.append(f"{chr(97 + i)}: &{chr(97 + i)} [{','.join(['*' + chr(96 + i)] * 10)}]")
    bomb = "\n".join(lines) + "\nformat: workbench-import/1\n"
    assert len(bomb) < 1024  # expands to 10^9 strings
    (tmp_path / "bomb.yaml").write_text(bomb)
    t0 = time.perf_counter()
    with pytest.raises(ImportProfileError, match="expands to more than 100000 nodes"):
        load_profile(tmp_path / "bomb.yaml")
    assert time.perf_counter() - t0 < 1.0


def test_a_profile_larger_than_the_limit_is_refused(tmp_path):
    big = tmp_path / "big.yaml"
    big.write_text("format: workbench-import/1\n# " + "x" * (1 << 20) + "\n")
    with pytest.raises(ImportProfileError, match="larger than 1048576 bytes"):
        load_profile(big)


def test_import_out_refuses_an_existing_session(tmp_path, capsys):
    profile, data = _recording(tmp_path / "d")
    out = tmp_path / "s"
    assert main(["import", str(profile), str(data), "--out", str(out)]) == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    capsys.readouterr()
    assert main(["import", str(profile), str(data), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "already exists" in err and len(err.strip().splitlines()) == 1
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before


def test_a_failed_import_leaves_no_folder(tmp_path, capsys):
    profile, data = _recording(tmp_path / "d")
    prof = yaml.safe_load(profile.read_text())
    prof["sections"]["steps"]["b"]["mount"] = "sideways"  # refused with the profile
    profile.write_text(yaml.safe_dump(prof))
    assert main(["import", str(profile), str(data), "--out", str(tmp_path / "s")]) == 2
    _nothing_left(tmp_path, "s")
    # a failure while writing, too
    profile, data = _recording(tmp_path / "d2")

    def broken(session, directory):
        (Path(directory) / "samples.parquet").write_bytes(b"half")
        raise WorkbenchError("disk full")
    import workbench.importer as importer

    original, importer.write_session = importer.write_session, broken
    try:
        with pytest.raises(WorkbenchError, match="disk full"):
            import_file(profile, data, tmp_path / "s2")
    finally:
        importer.write_session = original
    _nothing_left(tmp_path, "s2")


def test_an_unreadable_or_non_finite_recording_is_named_once_and_plainly(tmp_path, capsys):
    """The file's path once (was 'rec.csv: rec.csv: ...'), the bad cell as the file holds it (was np.float64(inf))."""
    profile, data = _recording(tmp_path / "d")
    data.write_bytes(data.read_bytes().replace(b"0,0.0,0.0,0.0,0.0,0.0,-1.0\n", b"0,inf,0.0,0.0,0.0,0.0,-1.0\n", 1))
    assert main(["import", str(profile), str(data), "--out", str(tmp_path / "s")]) == 2
    assert "column 'gx': not a finite number at row 0 (inf)" in capsys.readouterr().err
    data.write_bytes(b"n,gx\xff\n")
    assert main(["import", str(profile), str(data), "--out", str(tmp_path / "s")]) == 2
    err = capsys.readouterr().err
    assert err.count(str(data)) == 1 and "not a readable csv recording (UnicodeDecodeError" in err
    _nothing_left(tmp_path, "s")
