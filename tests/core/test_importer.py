from pathlib import Path

import numpy as np
import pytest

from workbench.cli import main
from workbench.errors import ImportProfileError, WorkbenchError
from workbench.importer import import_file
from workbench.session import load_session

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT.parent / "shared" / "data" / "imucal_ferraris"
PROFILE = ROOT / "fixtures" / "import_profiles" / "imucal_ferraris.yaml"
needs_data = pytest.mark.skipif(not DATA.exists(), reason="shared/data/imucal_ferraris is not beside the checkout")


@needs_data
def test_imucal_recording_imports_with_right_mounts_and_turns(tmp_path):
    assert main(["import", str(PROFILE), str(DATA / "example_ferraris_session.csv"), "--out", str(tmp_path / "s")]) == 0
    s = load_session(tmp_path / "s")
    static = s.steps_of_kind("static")
    assert [st.label for st in static] == ["x_p", "x_a", "y_p", "y_a", "z_p", "z_a"]
    for st in static:
        # the raw data is uncalibrated (static |a| 9.23-10.48), so check the direction only:
        # the named axis carries the largest specific force, + when up, - when down
        a = s.accel(st.index).mean(0)
        axis = "xyz".index(st.label[0])
        up_in_body = -st.mount.T @ np.array([0.0, 0.0, 1.0])
        assert np.argmax(np.abs(a)) == axis and np.sign(a[axis]) == np.sign(up_in_body[axis])
        assert 9.2 < np.linalg.norm(a) < 10.5
    turns = s.steps_of_kind("rate")
    assert [st.label for st in turns] == ["x_rot", "y_rot", "z_rot"]
    for st in turns:
        axis = "xyz".index(st.extra["axis"])
        turned = np.degrees(s.gyro(st.index)[:, axis].sum() / s.sample_rate_hz)
        assert turned == pytest.approx(-360.0, abs=15.0)  # raw gyro: scale error of a few %
        # the table-rate sign matches the body turn through the mount
        table_axis_in_body = st.mount.T @ np.array([0.0, 0.0, 1.0])
        assert np.sign(st.table_rate * table_axis_in_body[axis]) == np.sign(turned)


def test_profile_and_file_errors(tmp_path):
    bad = tmp_path / "p.yaml"
    bad.write_text("format: workbench-import/1\nsample_rate_hz: 100\nsite: {latitude_deg: 1}\n"
                   "columns: {gx: {column: a, unit: g}}\n")
    with pytest.raises(ImportProfileError, match="columns.gx.unit 'g' is not a unit of rad/s"):
        import_file(bad, tmp_path / "x.csv", tmp_path / "o")
    not_rec = tmp_path / "x.csv"
    not_rec.write_bytes(b"\x00\x01garbage")
    with pytest.raises(WorkbenchError, match="x.csv"):
        import_file(PROFILE, not_rec, tmp_path / "o")
    other = tmp_path / "y.csv"
    other.write_text("a,b\n1,2\n")
    with pytest.raises(ImportProfileError, match="profile column 'gyr_x'"):
        import_file(PROFILE, other, tmp_path / "o")
