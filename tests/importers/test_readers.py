"""Readers of ROS 1 / ROS 2 (SQLite, MCAP) bags, PX4 ULog and ArduPilot DataFlash, each on a small file
written here with that format's library (or, for ULog and DataFlash, a minimal writer following the
documented format), imported through a profile and compared sample by sample with what was written."""

import struct
from pathlib import Path

import numpy as np
import pytest
import yaml

from workbench.cli import main
from workbench.session import load_session

N = 400  # samples at 100 Hz
RATE = 100.0
T = np.arange(N) / RATE + 1000.0  # s, sender clock
GYRO = np.c_[0.1 * np.sin(T), 0.2 * np.cos(T), 0.05 + 0 * T]  # rad/s
ACCEL = np.c_[0.3 + 0 * T, -0.2 + 0 * T, -9.8 + 0.01 * np.sin(3 * T)]  # m/s^2
MAG = np.c_[20e-6 + 0 * T, 1e-6 * np.sin(T), 43e-6 + 0 * T]  # T


def _check(tmp_path, capsys, profile: dict, data: Path, mag_scale: float = 1e6) -> None:
    """Import ``data`` through ``profile`` and compare the session with the written samples (SI; mag µT)."""
    prof = {"format": "workbench-import/1", "site": {"latitude_deg": 45.0}, **profile}
    p = tmp_path / "p.yaml"
    p.write_text(yaml.safe_dump(prof))
    assert main(["import", str(p), str(data), "--out", str(tmp_path / "s")]) == 0, capsys.readouterr().err
    s = load_session(tmp_path / "s")
    assert len(s.samples) >= N - 2 and s.sample_rate_hz == pytest.approx(RATE, rel=1e-3)
    # every stream carries the same instants, so the session holds the written samples row for row
    # (float32 storage in ULog and DataFlash: 1e-6 relative)
    n = len(s.samples)
    assert np.allclose(s.samples["t"].to_numpy(), T[:n] - T[0], atol=2e-6)
    assert np.allclose(s.gyro(), GYRO[:n], atol=1e-6)
    assert np.allclose(s.accel(), ACCEL[:n], atol=1e-5)
    assert np.allclose(s.mag(), MAG[:n] * mag_scale, atol=1e-3)


def _ros_streams(file: str, time_col: str = "header.stamp") -> dict:
    imu = {"file": file, "reader": {"type": "rosbag", "topic": "/imu/data"}, "time": {"column": time_col},
           "columns": {**{f"g{c}": {"column": f"angular_velocity.{c}", "unit": "rad/s"} for c in "xyz"},
                       **{f"a{c}": {"column": f"linear_acceleration.{c}", "unit": "m/s^2"} for c in "xyz"}}}
    mag = {"file": file, "reader": {"type": "rosbag", "topic": "/imu/mag"}, "time": {"column": time_col},
           "columns": {f"m{c}": {"column": f"magnetic_field.{c}", "unit": "T"} for c in "xyz"}}
    return {"time_base": "imu", "streams": {"imu": imu, "mag": mag}}


def _ros_messages(typestore):
    tt = typestore.types
    Time, Header = tt["builtin_interfaces/msg/Time"], tt["std_msgs/msg/Header"]
    V3, Q = tt["geometry_msgs/msg/Vector3"], tt["geometry_msgs/msg/Quaternion"]
    ros1 = "seq" in Header.__dataclass_fields__
    for i, ti in enumerate(T):
        stamp = Time(sec=int(ti), nanosec=int(round((ti - int(ti)) * 1e9)))
        header = Header(seq=i, stamp=stamp, frame_id="imu") if ros1 else Header(stamp=stamp, frame_id="imu")
        cov = np.zeros(9)
        imu = tt["sensor_msgs/msg/Imu"](header=header, orientation=Q(x=0.0, y=0.0, z=0.0, w=1.0),
                                        orientation_covariance=cov, angular_velocity=V3(*GYRO[i]),
                                        angular_velocity_covariance=cov, linear_acceleration=V3(*ACCEL[i]),
                                        linear_acceleration_covariance=cov)
        mag = tt["sensor_msgs/msg/MagneticField"](header=header, magnetic_field=V3(*MAG[i]),
                                                  magnetic_field_covariance=cov)
        yield int((ti + 0.003) * 1e9), imu, mag


def test_ros1_bag(tmp_path, capsys):
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS1_NOETIC)
    (tmp_path / "d").mkdir()
    with Writer(tmp_path / "d" / "run.bag") as w:
        ci = w.add_connection("/imu/data", "sensor_msgs/msg/Imu", typestore=ts)
        cm = w.add_connection("/imu/mag", "sensor_msgs/msg/MagneticField", typestore=ts)
        for t_ns, imu, mag in _ros_messages(ts):
            w.write(ci, t_ns, ts.serialize_ros1(imu, "sensor_msgs/msg/Imu"))
            w.write(cm, t_ns, ts.serialize_ros1(mag, "sensor_msgs/msg/MagneticField"))
    _check(tmp_path, capsys, _ros_streams("run.bag"), tmp_path / "d")


@pytest.mark.parametrize("storage", ["sqlite3", "mcap", "bare-mcap"])
def test_ros2_bag(tmp_path, capsys, storage):
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    (tmp_path / "d").mkdir()
    plugin = StoragePlugin.SQLITE3 if storage == "sqlite3" else StoragePlugin.MCAP
    with Writer(tmp_path / "d" / "bag", version=9, storage_plugin=plugin) as w:
        ci = w.add_connection("/imu/data", "sensor_msgs/msg/Imu", typestore=ts)
        cm = w.add_connection("/imu/mag", "sensor_msgs/msg/MagneticField", typestore=ts)
        for t_ns, imu, mag in _ros_messages(ts):
            w.write(ci, t_ns, ts.serialize_cdr(imu, "sensor_msgs/msg/Imu"))
            w.write(cm, t_ns, ts.serialize_cdr(mag, "sensor_msgs/msg/MagneticField"))
    file = "bag"
    if storage == "bare-mcap":
        file = next(p.name for p in (tmp_path / "d" / "bag").iterdir() if p.suffix == ".mcap")
        (tmp_path / "d" / "bag" / file).rename(tmp_path / "d" / file)
    _check(tmp_path, capsys, _ros_streams(file), tmp_path / "d")


def test_a_missing_topic_is_named(tmp_path, capsys):
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS1_NOETIC)
    (tmp_path / "d").mkdir()
    with Writer(tmp_path / "d" / "run.bag") as w:
        ci = w.add_connection("/imu/data", "sensor_msgs/msg/Imu", typestore=ts)
        for t_ns, imu, _ in _ros_messages(ts):
            w.write(ci, t_ns, ts.serialize_ros1(imu, "sensor_msgs/msg/Imu"))
    p = tmp_path / "p.yaml"
    p.write_text(yaml.safe_dump({"format": "workbench-import/1", "site": {"latitude_deg": 45.0},
                                 **_ros_streams("run.bag")}))
    assert main(["import", str(p), str(tmp_path / "d"), "--out", str(tmp_path / "s")]) == 2
    err = capsys.readouterr().err
    assert "streams.mag: reader.topic '/imu/mag' not in run.bag (topics: /imu/data)" in err
    assert not (tmp_path / "s").exists()


# -- PX4 ULog: a minimal writer following the documented format (docs.px4.io, "ULog File Format") ------
def _ulog_msg(kind: bytes, payload: bytes) -> bytes:
    return struct.pack("<HB", len(payload), kind[0]) + payload


def _write_ulog(path: Path, rel_us: int = 0) -> None:
    """sensor_combined and sensor_mag at T; ``rel_us`` the accelerometer_timestamp_relative."""
    out = bytearray(b"ULog\x01\x12\x35" + bytes([1]) + struct.pack("<Q", int(T[0] * 1e6)))
    out += _ulog_msg(b"B", bytes(8) + bytes(8) + bytes(24))  # flag bits: no incompatibilities, no appended data
    fmt = "sensor_combined:uint64_t timestamp;float[3] gyro_rad;uint32_t gyro_integral_dt;" \
          "int32_t accelerometer_timestamp_relative;float[3] accelerometer_m_s2;" \
          "uint32_t accelerometer_integral_dt;uint8_t accelerometer_clipping;uint8_t[3] _padding0"
    out += _ulog_msg(b"F", fmt.encode())
    out += _ulog_msg(b"F", b"sensor_mag:uint64_t timestamp;uint64_t timestamp_sample;uint32_t device_id;"
                          b"float x;float y;float z;float temperature;uint32_t error_count;bool is_external;"
                          b"uint8_t[7] _padding0")
    out += _ulog_msg(b"A", struct.pack("<BH", 0, 0) + b"sensor_combined")
    out += _ulog_msg(b"A", struct.pack("<BH", 0, 1) + b"sensor_mag")
    for i, ti in enumerate(T):
        us = int(round(ti * 1e6))
        out += _ulog_msg(b"D", struct.pack("<H", 0) + struct.pack("<Q3fIi3fIB", us, *GYRO[i], 4000, rel_us, *ACCEL[i],
                                                                   4000, 0))  # trailing padding not logged
        out += _ulog_msg(b"D", struct.pack("<H", 1) + struct.pack("<QQI4fIB", us, us, 1, *(MAG[i] * 1e4), 25.0, 0,
                                                                   0))  # gauss
    path.write_bytes(bytes(out))


def test_px4_ulog(tmp_path, capsys):
    (tmp_path / "d").mkdir()
    _write_ulog(tmp_path / "d" / "log.ulg")
    imu = {"file": "log.ulg", "reader": {"type": "ulog", "message": "sensor_combined"},
           "time": {"column": "timestamp", "unit": "us"},
           "columns": {**{f"g{c}": {"column": f"gyro_rad[{i}]", "unit": "rad/s"} for i, c in enumerate("xyz")},
                       **{f"a{c}": {"column": f"accelerometer_m_s2[{i}]", "unit": "m/s^2"} for i, c in enumerate("xyz")}}}
    mag = {"file": "log.ulg", "reader": {"type": "ulog", "message": "sensor_mag"},
           "time": {"column": "timestamp_sample", "unit": "us"},
           "columns": {f"m{c}": {"column": c, "unit": "gauss"} for c in "xyz"}}
    _check(tmp_path, capsys, {"time_base": "imu", "streams": {"imu": imu, "mag": mag}}, tmp_path / "d")


def test_ulog_sensor_combined_gives_the_accelerometer_its_own_time(tmp_path):
    from workbench.importers.readers import read_log

    _write_ulog(tmp_path / "log.ulg", rel_us=700)
    df, damage = read_log(tmp_path / "log.ulg", {"type": "ulog", "message": "sensor_combined"}, "imu")
    assert not damage.any
    assert np.array_equal(df["accelerometer_timestamp"], df["timestamp"] + 700)
    assert np.allclose(df["timestamp"] * 1e-6, T, atol=1e-6)


# -- ArduPilot DataFlash: FMT records, then IMU and MAG records (pymavlink's format characters) --------
def _write_dataflash(path: Path) -> None:
    from pymavlink.DFReader import DFFormat

    def record(kind: int, fmt: DFFormat, *values) -> bytes:
        return bytes([0xA3, 0x95, kind]) + struct.pack(fmt.msg_struct, *values)

    fmt_fmt = DFFormat(0x80, "FMT", 89, "BBnNZ", "Type,Length,Name,Format,Columns")
    imu = DFFormat(1, "IMU", 0, "QBffffff", "TimeUS,I,GyrX,GyrY,GyrZ,AccX,AccY,AccZ")
    mag = DFFormat(2, "MAG", 0, "QBfff", "TimeUS,I,MagX,MagY,MagZ")
    out = bytearray()
    for f in (fmt_fmt, imu, mag):
        length = 3 + struct.calcsize(f.msg_struct)
        out += record(0x80, fmt_fmt, f.type, length, f.name.encode(), f.format.encode(), ",".join(f.columns).encode())
    for i, ti in enumerate(T):
        us = int(round(ti * 1e6))
        out += record(1, imu, us, 0, *GYRO[i], *ACCEL[i])
        out += record(1, imu, us, 1, *(GYRO[i] + 1.0), *ACCEL[i])  # a second IMU: not the chosen instance
        out += record(2, mag, us, 0, *(MAG[i] * 1e7))  # mGauss
    path.write_bytes(bytes(out))


def test_ardupilot_dataflash(tmp_path, capsys):
    (tmp_path / "d").mkdir()
    _write_dataflash(tmp_path / "d" / "log.bin")
    imu = {"file": "log.bin", "reader": {"type": "dataflash", "message": "IMU", "instance": 0},
           "time": {"column": "TimeUS", "unit": "us"},
           "columns": {**{f"g{c}": {"column": f"Gyr{c.upper()}", "unit": "rad/s"} for c in "xyz"},
                       **{f"a{c}": {"column": f"Acc{c.upper()}", "unit": "m/s^2"} for c in "xyz"}}}
    mag = {"file": "log.bin", "reader": {"type": "dataflash", "message": "MAG"},
           "time": {"column": "TimeUS", "unit": "us"},
           "columns": {f"m{c}": {"column": f"Mag{c.upper()}", "unit": "mgauss"} for c in "xyz"}}
    _check(tmp_path, capsys, {"time_base": "imu", "streams": {"imu": imu, "mag": mag}}, tmp_path / "d")


@pytest.mark.parametrize("reader,match", [
    ({"type": "rosbg", "topic": "/x"}, r"reader\.type 'rosbg': expected one of"),
    ({"type": "rosbag"}, r"reader\.topic: missing \(a rosbag reader needs it\)"),
    ({"type": "ulog", "topic": "/x"}, r"reader\.topic: not a key of a ulog reader"),
])
def test_bad_reader_keys(tmp_path, capsys, reader, match):
    import re
    streams = _ros_streams("run.bag")
    streams["streams"]["imu"]["reader"] = reader
    p = tmp_path / "p.yaml"
    p.write_text(yaml.safe_dump({"format": "workbench-import/1", "site": {"latitude_deg": 45.0}, **streams}))
    (tmp_path / "d").mkdir()
    assert main(["import", str(p), str(tmp_path / "d"), "--out", str(tmp_path / "s")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and re.search(match, err), err


# -- truncated logs: a recorder that lost power, a copy that did not finish ---------------------------
def _one_stream(kind: str) -> dict:
    if kind == "ulog":
        imu = {"file": "log.ulg", "reader": {"type": "ulog", "message": "sensor_combined"},
               "time": {"column": "timestamp", "unit": "us"},
               "columns": {**{f"g{c}": {"column": f"gyro_rad[{i}]"} for i, c in enumerate("xyz")},
                           **{f"a{c}": {"column": f"accelerometer_m_s2[{i}]"} for i, c in enumerate("xyz")}}}
    else:
        imu = {"file": "log.bin", "reader": {"type": "dataflash", "message": "IMU"},
               "time": {"column": "TimeUS", "unit": "us"},
               "columns": {**{f"g{c}": {"column": f"Gyr{c.upper()}"} for c in "xyz"},
                           **{f"a{c}": {"column": f"Acc{c.upper()}"} for c in "xyz"}}}
    return {"format": "workbench-import/1", "site": {"latitude_deg": 45.0}, "streams": {"imu": imu}}


def _cut_log(tmp_path: Path, kind: str, keep) -> Path:
    """The test log of ``kind`` cut to ``keep(len)`` bytes, in a data folder; returns the profile."""
    (tmp_path / "d").mkdir()
    file = tmp_path / "d" / ("log.ulg" if kind == "ulog" else "log.bin")
    (_write_ulog if kind == "ulog" else _write_dataflash)(file)
    data = file.read_bytes()
    file.write_bytes(data[:keep(len(data))])
    p = tmp_path / "p.yaml"
    p.write_text(yaml.safe_dump(_one_stream(kind)))
    return p


@pytest.mark.parametrize("kind", ["ulog", "dataflash"])
def test_a_log_cut_mid_message_imports_what_it_holds_and_says_it_was_truncated(tmp_path, capsys, kind):
    # 7 bytes short: the last message (mag in the ULog, IMU instance 1 / MAG in the DataFlash log) is cut
    p = _cut_log(tmp_path, kind, lambda n: n - 7)
    assert main(["import", str(p), str(tmp_path / "d"), "--out", str(tmp_path / "s")]) == 0
    out_text = capsys.readouterr().out
    size = (tmp_path / "d" / ("log.ulg" if kind == "ulog" else "log.bin")).stat().st_size
    line = next(x for x in out_text.splitlines() if "truncated" in x)
    assert line.strip().startswith("warning:") and f"truncated at byte {size}" in line and "1 message lost" in line
    assert f"last sample is at {T[-1]:.6f} s" in line  # the last IMU sample before the cut, log clock
    s = load_session(tmp_path / "s")
    damage = s.options["import"]["streams"]["imu"]["damage"]
    assert damage["file_bytes"] == size and 0 < damage["cut_bytes"] < damage["cut_message_bytes"]
    assert np.allclose(s.gyro(), GYRO[:len(s.samples)], atol=1e-6) and len(s.samples) == N


@pytest.mark.parametrize("kind", ["ulog", "dataflash"])
def test_a_whole_log_reports_no_damage(tmp_path, capsys, kind):
    p = _cut_log(tmp_path, kind, lambda n: n)
    assert main(["import", str(p), str(tmp_path / "d"), "--out", str(tmp_path / "s")]) == 0
    assert "truncated" not in capsys.readouterr().out
    assert load_session(tmp_path / "s").options["import"]["streams"]["imu"]["damage"] is None


@pytest.mark.parametrize("kind,keep,match", [
    ("ulog", lambda n: 10, "log.ulg is truncated: 10 bytes, shorter than the 16-byte ULog header"),
    ("ulog", lambda n: 30, "log.ulg is truncated at byte 30: .* no sensor_combined .* data before the damage"),
    ("ulog", lambda n: 600, "log.ulg is truncated at byte 600: .*: 1 sample left; nothing to import"),
    ("dataflash", lambda n: 30, "log.bin is truncated at byte 30: .* no IMU .* records before the damage"),
])
def test_a_log_cut_before_its_data_is_one_line(tmp_path, capsys, kind, keep, match):
    import re

    p = _cut_log(tmp_path, kind, keep)
    assert main(["import", str(p), str(tmp_path / "d"), "--out", str(tmp_path / "s")]) == 2
    captured = capsys.readouterr()
    err_lines = captured.err.strip().splitlines()
    assert len(err_lines) == 1 and re.search(match, err_lines[0]), err_lines
    assert captured.out == ""  # the libraries' own prints about the damage are swallowed
    assert not (tmp_path / "s").exists()


def test_dataflash_block_padding_and_skipped_bytes():
    from workbench.importers.damage import dataflash_damage, ulog_damage

    rec = bytes([0xA3, 0x95, 1]) + bytes(7)  # a 10-byte record of type 1
    assert not dataflash_damage(rec * 3 + b"\xff" * 200, {1: 10}).any  # block padding of a flash log
    d = dataflash_damage(rec + b"junk" + rec + rec[:4], {1: 10})
    assert (d.skipped_bytes, d.cut_bytes, d.cut_of, d.whole_bytes) == (4, 4, 10, 24)
    u = ulog_damage(bytes(16) + struct.pack("<HB", 2, 68) + b"ab" + struct.pack("<HB", 5, 68) + b"a")
    assert (u.cut_bytes, u.cut_of, u.whole_bytes) == (4, 8, 21)


def test_a_csv_with_a_header_and_no_rows_names_the_file_once(tmp_path, capsys):
    cols = {f"{k}{c}": {"column": f"{k}{c}"} for k in "ga" for c in "xyz"}
    p = tmp_path / "p.yaml"
    p.write_text(yaml.safe_dump({"format": "workbench-import/1", "site": {"latitude_deg": 45.0},
                                 "sample_rate_hz": 100.0, "columns": cols, "unit": {"serial": "S1"}}))
    (tmp_path / "rec.csv").write_text(",".join(cols) + "\n")
    assert main(["import", str(p), str(tmp_path / "rec.csv"), "--out", str(tmp_path / "s")]) == 2
    assert capsys.readouterr().err.strip() == f"error: {tmp_path / 'rec.csv'}: no rows"  # was 'rec.csv: rec.csv: no rows'


@pytest.mark.parametrize("inline,match", [
    # were: 'step 0: column t: gap of 0.505 s ...' (b's labels overwrote a's) and a silent import of b cut at 400
    ({"a": [0, 100], "b": [50, 200]}, "section b (50..200) overlaps section a (0..100)"),
    ({"a": [0, 100], "b": [350, 9000]}, "section b (350..9000) reaches past the recording's 400 samples"),
])
def test_sections_that_overlap_or_reach_past_the_recording_are_one_line(tmp_path, capsys, inline, match):
    cols = {f"{k}{c}": {"column": f"{k}{c}"} for k in "ga" for c in "xyz"}
    p = tmp_path / "p.yaml"
    p.write_text(yaml.safe_dump({"format": "workbench-import/1", "site": {"latitude_deg": 45.0},
                                 "sample_rate_hz": RATE, "columns": cols, "unit": {"serial": "S1"},
                                 "sections": {"inline": inline, "steps": {n: {"kind": "static"} for n in inline}}}))
    import pandas as pd

    pd.DataFrame(np.c_[GYRO, ACCEL], columns=list(cols)).to_csv(tmp_path / "rec.csv", index=False)
    assert main(["import", str(p), str(tmp_path / "rec.csv"), "--out", str(tmp_path / "s")]) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert match in line and not (tmp_path / "s").exists()


def test_a_ros1_bag_cut_short_is_one_line_saying_how_to_rebuild_it(tmp_path, capsys):
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS1_NOETIC)
    (tmp_path / "d").mkdir()
    with Writer(tmp_path / "full.bag") as w:
        ci = w.add_connection("/imu/data", "sensor_msgs/msg/Imu", typestore=ts)
        for t_ns, imu, _ in _ros_messages(ts):
            w.write(ci, t_ns, ts.serialize_ros1(imu, "sensor_msgs/msg/Imu"))
    data = (tmp_path / "full.bag").read_bytes()
    (tmp_path / "d" / "run.bag").write_bytes(data[:len(data) - 7])  # the index at the end is cut
    p = tmp_path / "p.yaml"
    streams = _ros_streams("run.bag")
    del streams["streams"]["mag"]
    p.write_text(yaml.safe_dump({"format": "workbench-import/1", "site": {"latitude_deg": 45.0}, **streams}))
    assert main(["import", str(p), str(tmp_path / "d"), "--out", str(tmp_path / "s")]) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert "run.bag: not a readable rosbag recording" in line and "'rosbag reindex' rebuilds its index" in line
