"""Multi-stream import from the command line: one folder, four files, arrival stamps; bad profiles refused."""

from pathlib import Path

import numpy as np
import pytest
import yaml

from workbench.cli import main
from workbench.session import FLAG_REPEATED, FLAG_SATURATED, load_session
from workbench.sim.arrival import arrival_stamps


def _write(path: Path, header: str, t: np.ndarray, values: np.ndarray) -> None:
    rows = [header] + [",".join(repr(float(x)) for x in (ti, *v)) for ti, v in zip(t, values)]
    path.write_text("\n".join(rows) + "\n")


def _folder(root: Path) -> Path:
    """A still board: accel/gyro/temp 100 Hz (one read: same stamps), mag 75 Hz with stale reads every 40th."""
    d = root / "rec"
    d.mkdir(parents=True)
    t = np.arange(2000) / 100.0
    a = arrival_stamps(t, 1)
    n = len(t)
    rng = np.random.default_rng(0)
    acc = np.c_[0.01 * rng.standard_normal(n), 0.01 * rng.standard_normal(n), 1 + 0.01 * rng.standard_normal(n)]
    gyr = 0.5 * rng.standard_normal((n, 3))
    gyr[500:505, 2] = 250.1374  # at the rail
    _write(d / "accelerometer.csv", "t_s,ax_g,ay_g,az_g", a, acc)
    _write(d / "gyroscope.csv", "t_s,gx_dps,gy_dps,gz_dps", a, gyr)
    _write(d / "temperature.csv", "t_s,temp_c", a, 23 + 0.01 * rng.standard_normal((n, 1)))
    tm = np.arange(1490) / 75.0
    mag = np.c_[0.2 + 0.002 * rng.standard_normal(len(tm)), 0.01 * rng.standard_normal(len(tm)),
                0.43 + 0.002 * rng.standard_normal(len(tm))]
    mag[40::40] = mag[39::40][:len(mag[40::40])]
    _write(d / "magnetometer.csv", "t_s,mx_gauss,my_gauss,mz_gauss", arrival_stamps(tm, 2), mag)
    return d


def _profile(root: Path, **changes) -> Path:
    def stream(file, cols, rate, **extra):
        return {"file": file, "time": {"column": "t_s", "unit": "s", "stamps": "arrival"}, "rate_hz": rate,
                "columns": cols, **extra}
    prof = {"format": "workbench-import/1", "site": {"latitude_deg": 49.0}, "time_base": "accel",
            "streams": {
                "accel": stream("accelerometer.csv", {f"a{c}": {"column": f"a{c}_g", "unit": "g"} for c in "xyz"}, 100),
                "gyro": stream("gyroscope.csv", {f"g{c}": {"column": f"g{c}_dps", "unit": "deg/s"} for c in "xyz"}, 100,
                               range={"value": 250, "unit": "deg/s"}),
                "temperature": stream("temperature.csv", {"temp": {"column": "temp_c", "unit": "degC"}}, 100),
                "mag": stream("magnetometer.csv", {f"m{c}": {"column": f"m{c}_gauss", "unit": "gauss"} for c in "xyz"},
                              75)}}
    for key, value in changes.items():
        node = prof
        *path, last = key.split(".")
        for p in path:
            node = node[p]
        if value is None:
            del node[last]
        else:
            node[last] = value
    p = root / "p.yaml"
    p.write_text(yaml.safe_dump(prof))
    return p


def test_a_four_stream_folder_imports_as_one_free_step(tmp_path, capsys):
    data = _folder(tmp_path)
    assert main(["import", str(_profile(tmp_path)), str(data), "--out", str(tmp_path / "s")]) == 0
    printed = capsys.readouterr().out
    assert "arrival stamps -> sample clock" in printed and "mag repeated" in printed and "gyro saturated 5" in printed
    s = load_session(tmp_path / "s")
    assert [st.kind for st in s.steps] == ["free"]
    assert s.sample_rate_hz == pytest.approx(100.0, rel=1e-3)
    flags = s.samples["flags"].to_numpy()
    assert np.count_nonzero(flags & FLAG_SATURATED["gyro"]) == 5
    assert np.count_nonzero(s.good("mag")) < len(flags)
    summary = s.options["import"]
    assert summary["streams"]["mag"]["repeated"] == len(range(40, 1490, 40))
    assert np.median(np.linalg.norm(s.mag(), axis=1)) == pytest.approx(47.0, rel=0.02)  # 0.47 gauss in µT
    assert (np.diff(s.samples["t"]) > 0).all()
    assert 22.9 < s.samples["temp"].mean() < 23.1


@pytest.mark.parametrize("key,value,match", [
    ("streams.mag.file", "../outside.csv", r"streams\.mag\.file '\.\./outside\.csv': must be a file inside"),
    ("streams.mag.file", "/etc/passwd", r"streams\.mag\.file '/etc/passwd': must be a file inside"),
    ("streams.mag.file", "link.csv", r"streams\.mag\.file 'link\.csv': resolves outside"),
    ("streams.mag.file", "missing.csv", r"streams\.mag: .*missing\.csv: no such file"),
    ("streams.mag.time.stamp", "arrival", r"streams\.mag\.time\.stamp: unknown key"),
    ("streams.mag.time.stamps", "host", r"streams\.mag\.time\.stamps 'host'"),
    ("streams.gyro.range", {"value": 250, "unit": "g"}, r"streams\.gyro\.range\.unit 'g' is not a unit of rad/s"),
    ("streams.mag.columns.mx.column", "mx_gaus", r"streams\.mag: profile column 'mx_gaus' \(for mx\) not in the file"),
    ("streams.mag.columns.mx.unit", "degC", r"streams\.mag\.columns\.mx\.unit 'degC' is not a unit of uT"),
    ("time_base", "imu", r"time_base 'imu': must name one of the streams"),
    ("streams.temperature.columns.ax", {"column": "temp_c", "unit": "g"}, r"columns\.ax: already given by stream"),
    ("streams.mag.rate_hz", -3, r"streams\.mag\.rate_hz: expected a finite number"),
    ("streams.mag.rate_hz", 150, r"streams\.mag: rate_hz 150 Hz: the arrival stamps give 75(\.\d+)? Hz \(more than 10% off"),
])
def test_bad_profiles_are_one_line_exit_2_and_nothing_written(tmp_path, capsys, key, value, match):
    data = _folder(tmp_path)
    (tmp_path / "outside.csv").write_text((data / "magnetometer.csv").read_text())
    (data / "link.csv").symlink_to(tmp_path / "outside.csv")
    profile = _profile(tmp_path, **{key: value})
    assert main(["import", str(profile), str(data), "--out", str(tmp_path / "s")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    import re
    assert re.search(match, err), err
    assert not (tmp_path / "s").exists() and not [p for p in tmp_path.iterdir() if p.name.startswith(".s.")]


def test_bad_data_names_the_stream_and_row(tmp_path, capsys):
    data = _folder(tmp_path)
    text = (data / "magnetometer.csv").read_text().splitlines()
    text[20] = text[20].split(",")[0] + ",abc,0.1,0.2"
    (data / "magnetometer.csv").write_text("\n".join(text) + "\n")
    assert main(["import", str(_profile(tmp_path)), str(data), "--out", str(tmp_path / "s")]) == 2
    err = capsys.readouterr().err.strip()
    assert "streams.mag: columns.mx: column 'mx_gauss': not a finite number at row 19" in err
    assert not (tmp_path / "s").exists()


def test_a_streams_profile_needs_a_folder(tmp_path, capsys):
    data = _folder(tmp_path)
    assert main(["import", str(_profile(tmp_path)), str(data / "accelerometer.csv"), "--out", str(tmp_path / "s")]) == 2
    assert "not a folder" in capsys.readouterr().err
