"""Every MARG recording (shared/data/marg_mpu6050_hmc5883l/) imports with one command from its raw files."""

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from workbench.cli import main
from workbench.session import FLAG_SATURATED, load_session

ROOT = Path(__file__).resolve().parents[2]
# beside the checkout (/work/main) or beside the worktrees' folder (/work/wt/NAME)
DATA = next((p / "shared" / "data" / "marg_mpu6050_hmc5883l" for p in (ROOT.parent, ROOT.parent.parent)
             if (p / "shared" / "data" / "marg_mpu6050_hmc5883l").exists()), ROOT.parent / "shared" / "data")
PROFILE = ROOT / "fixtures" / "import_profiles" / "marg_mpu6050_hmc5883l.yaml"
RECORDINGS = sorted(p.name for p in DATA.iterdir() if p.is_dir()) if DATA.exists() else []
pytestmark = pytest.mark.skipif(not DATA.exists(), reason="shared/data/marg_mpu6050_hmc5883l is not beside the checkout")


def test_all_fifteen_recordings_are_there():
    assert len(RECORDINGS) == 15


@pytest.mark.parametrize("name", RECORDINGS)
def test_recording_imports_with_one_command(tmp_path, capsys, name):
    assert main(["import", str(PROFILE), str(DATA / name), "--out", str(tmp_path / "s")]) == 0
    printed = capsys.readouterr().out
    s = load_session(tmp_path / "s")
    summary = s.options["import"]
    assert [st.kind for st in s.steps] == ["free"]
    assert 98.0 < s.sample_rate_hz < 101.0
    # gravity in m/s^2 and the field in µT after the unit conversions; the raw MPU6050 is uncalibrated
    # (datasheet: zero-g offset up to 150 mg on z, sensitivity ±3 %), so |a| is within 18 % of g
    g = s.gyro()
    still = np.linalg.norm(g - np.median(g, axis=0), axis=1) < np.radians(5.0)  # raw bias of a few °/s
    assert np.median(np.linalg.norm(s.accel()[still], axis=1)) == pytest.approx(9.81, rel=0.18)
    assert 20.0 < np.median(np.linalg.norm(s.mag(), axis=1)) < 80.0
    # the magnetometer is read faster than it updates: repeats found, none on the MPU6050 streams
    assert summary["streams"]["mag"]["repeated"] > 0 and summary["streams"]["accel"]["repeated"] == 0
    # saturation counts equal the rail samples in the raw file
    raw = pd.read_csv(DATA / name / "gyroscope.csv")
    raw = raw[(raw != 0).any(axis=1)]
    rail = int((raw[["gx_dps", "gy_dps", "gz_dps"]].abs() >= 250.0).any(axis=1).sum())
    assert summary["streams"]["gyro"]["saturated"] == rail
    assert np.count_nonzero(s.samples["flags"].to_numpy() & FLAG_SATURATED["gyro"]) == rail
    # the axis mapping of the profile agrees with the data wherever there was motion to tell
    assert all(c["agrees"] in (True, None) for c in summary["axis_check"])
    assert "axis check gyro vs accel" in printed and "arrival stamps -> sample clock" in printed


def test_the_axis_check_decides_on_the_moving_recordings(tmp_path):
    assert main(["import", str(PROFILE), str(DATA / "tilt-sphere"), "--out", str(tmp_path / "s")]) == 0
    checks = {c["reference"]: c for c in load_session(tmp_path / "s").options["import"]["axis_check"]}
    assert checks["accel"]["agrees"] is True and checks["mag"]["agrees"] is True
