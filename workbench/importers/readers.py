"""Readers of the logs labs and flight controllers write, each into a plain table of named columns.

A stream's ``reader.type`` picks one; the table then goes through the same ``time`` and
``columns`` mapping of the profile as a CSV file (units, signs, arrival stamps, flags):

- ``csv`` / ``parquet``: pandas (``delimiter``, ``skip_rows``, ``comment``).
- ``rosbag``: a ROS 1 bag (``.bag``), a ROS 2 bag folder (SQLite or MCAP storage) or a bare
  ``.mcap`` file, read with ``rosbags`` (``topic``). ``sensor_msgs/Imu`` gives
  ``angular_velocity.x`` ... (rad/s), ``linear_acceleration.x`` ... (m/s^2);
  ``sensor_msgs/MagneticField`` gives ``magnetic_field.x`` ... (T); ``sensor_msgs/Temperature``
  ``temperature`` (degC); every message also ``header.stamp`` (s, the sender's sampling time)
  and ``log_time`` (s, when the recorder received it: an arrival stamp).
- ``ulog``: a PX4 ULog, read with ``pyulog`` (``message``: ``sensor_combined``, ``sensor_accel``,
  ``sensor_gyro``, ``sensor_mag``; ``multi_id``, default 0): the message's fields as logged
  (``timestamp`` in us, ``gyro_rad[0]``, ``x``, ...); ``sensor_combined`` also gets
  ``accelerometer_timestamp`` (us: ``timestamp + accelerometer_timestamp_relative``), the
  accelerometer's own sample time, for a stream of its accelerometer fields.
- ``dataflash``: an ArduPilot DataFlash ``.bin`` log, read with ``pymavlink`` (``message``: ``IMU``,
  ``MAG``; ``instance``: the ``I`` field, default 0): its fields (``TimeUS`` in us, ``GyrX``, ``AccX``,
  ``MagX`` in mGauss, ...).

A ULog or DataFlash log cut mid-message or holding skipped bytes is read up to the damage and the
damage returned with the table (:mod:`workbench.importers.damage`); the libraries' own prints
about it are swallowed.

Public: :func:`read_log`, :data:`READER_TYPES`, :data:`READER_KEYS`.
"""

from __future__ import annotations

import io
from collections.abc import Iterator, Mapping
from contextlib import contextmanager, redirect_stderr, redirect_stdout
from pathlib import Path

import pandas as pd

from workbench.errors import ImportProfileError, WorkbenchError
from workbench.importers.damage import ULOG_HEADER, Damage, dataflash_damage, ulog_damage

READER_TYPES = ("csv", "parquet", "rosbag", "ulog", "dataflash")
READER_KEYS = {"csv": {"delimiter", "skip_rows", "comment"}, "parquet": set(), "rosbag": {"topic"},
               "ulog": {"message", "multi_id"}, "dataflash": {"message", "instance"}}
RELATIVE_INVALID = 2**31 - 1  # sensor_combined's accelerometer_timestamp_relative when there is no accelerometer
REQUIRED_KEYS = {"rosbag": ("topic",), "ulog": ("message",), "dataflash": ("message",)}


def _ros_rows(msgtype: str, msg, log_time_ns: int) -> dict:
    row = {"log_time": log_time_ns * 1e-9}
    header = getattr(msg, "header", None)
    if header is not None:
        row["header.stamp"] = header.stamp.sec + header.stamp.nanosec * 1e-9
    short = msgtype.replace("/msg/", "/")
    if short == "sensor_msgs/Imu":
        for part in ("angular_velocity", "linear_acceleration"):
            vec = getattr(msg, part)
            row.update({f"{part}.{c}": getattr(vec, c) for c in "xyz"})
    elif short == "sensor_msgs/MagneticField":
        row.update({f"magnetic_field.{c}": getattr(msg.magnetic_field, c) for c in "xyz"})
    elif short == "sensor_msgs/Temperature":
        row["temperature"] = msg.temperature
    else:
        raise ImportProfileError(f"message type {msgtype} is not read (sensor_msgs/Imu, MagneticField, Temperature)")
    return row


def _read_rosbag(path: Path, topic: str, where: str) -> pd.DataFrame:
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    rows = []
    with AnyReader([path], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as reader:
        conns = [c for c in reader.connections if c.topic == topic]
        if not conns:
            topics = sorted({c.topic for c in reader.connections})
            raise ImportProfileError(f"{where}: reader.topic {topic!r} not in {path.name} (topics: {', '.join(topics)})")
        for conn, log_time, raw in reader.messages(connections=conns):
            try:
                rows.append(_ros_rows(conn.msgtype, reader.deserialize(raw, conn.msgtype), log_time))
            except ImportProfileError as exc:
                raise ImportProfileError(f"{where}: topic {topic}: {exc}") from None
    return pd.DataFrame(rows)


def _read_ulog(path: Path, message: str, multi_id: int, where: str) -> tuple[pd.DataFrame, Damage]:
    from pyulog import ULog

    data = path.read_bytes()
    if len(data) < ULOG_HEADER:
        raise ImportProfileError(f"{where}: {path.name} is truncated: {len(data)} bytes, shorter than the "
                                 f"{ULOG_HEADER}-byte ULog header; nothing to import")
    with _quiet():  # pyulog prints what it finds damaged; the damage is reported here instead
        log = ULog(str(path), [message])
    damage = ulog_damage(data, log.file_corruption)
    names = sorted({(d.name, d.multi_id) for d in log.data_list})
    for d in log.data_list:
        if d.name == message and d.multi_id == multi_id:
            df = pd.DataFrame(d.data)
            if "accelerometer_timestamp_relative" in df:  # sensor_combined: the accelerometer's own sample time
                rel = df["accelerometer_timestamp_relative"].astype("int64")
                df["accelerometer_timestamp"] = df["timestamp"].astype("int64") + rel.where(rel != RELATIVE_INVALID, 0)
            return df, damage
    if damage.any:
        raise ImportProfileError(f"{where}: {damage.text(path.name)}: no {message} (multi_id {multi_id}) data "
                                 "before the damage; nothing to import")
    raise ImportProfileError(f"{where}: reader.message {message!r} (multi_id {multi_id}) not in {path.name} "
                             f"(messages: {', '.join(f'{n}[{i}]' for n, i in names) or 'none'})")


def _read_dataflash(path: Path, message: str, instance: int, where: str) -> tuple[pd.DataFrame, Damage]:
    from pymavlink.DFReader import DFReader_binary

    rows = []
    with _quiet():  # pymavlink prints each bad header and skip on stderr; the damage is reported here instead
        log = DFReader_binary(str(path), zero_time_base=False)
        while True:
            m = log.recv_match(type=message)
            if m is None:
                break
            d = m.to_dict()
            if int(d.get("I", 0)) == instance:
                d.pop("mavpackettype", None)
                rows.append(d)
    damage = dataflash_damage(path.read_bytes(), {t: f.len for t, f in log.formats.items()})
    if not rows:
        if damage.any:
            raise ImportProfileError(f"{where}: {damage.text(path.name)}: no {message} (instance {instance}) "
                                     "records before the damage; nothing to import")
        seen = sorted(log.name_to_id) if hasattr(log, "name_to_id") else []
        raise ImportProfileError(f"{where}: reader.message {message!r} (instance {instance}) has no records in "
                                 f"{path.name} (messages: {', '.join(seen[:20]) or 'none'})")
    return pd.DataFrame(rows), damage


@contextmanager
def _quiet() -> Iterator[None]:
    """Swallow what a reader library prints on stdout and stderr."""
    with redirect_stdout(io.StringIO()), redirect_stderr(io.StringIO()):
        yield


def read_log(path: Path, reader: Mapping, where: str) -> tuple[pd.DataFrame, Damage | None]:
    """The table of ``path`` as ``reader`` says (module docstring), and for a ULog or DataFlash log
    what of it could not be read (:mod:`workbench.importers.damage`; None for the other readers);
    WorkbenchError naming ``where``, also for a damaged log with nothing of the message before the damage."""
    kind = reader.get("type") or ("parquet" if path.suffix == ".parquet" else "csv")
    place = where if where == str(path) else f"{where}: {path}"  # a single file is its own place
    if not path.exists():
        raise WorkbenchError(f"{place}: no such file")
    try:
        if kind == "parquet":
            return pd.read_parquet(path), None
        if kind == "csv":
            return pd.read_csv(path, sep=reader.get("delimiter", ","), skiprows=reader.get("skip_rows", 0),
                               comment=reader.get("comment")), None
        if kind == "rosbag":
            return _read_rosbag(path, str(reader["topic"]), where), None
        if kind == "ulog":
            return _read_ulog(path, str(reader["message"]), int(reader.get("multi_id", 0)), where)
        return _read_dataflash(path, str(reader["message"]), int(reader.get("instance", 0)), where)
    except WorkbenchError:
        raise
    except Exception as exc:  # each library raises its own types for files that are not its format
        cut = kind == "rosbag" and "index looks damaged" in str(exc)  # a ROS 1 bag whose recorder did not close it
        raise WorkbenchError(f"{place}: not a readable {kind} recording ({type(exc).__name__}: {str(exc)[:120]})"
                             + ("; a bag cut short: 'rosbag reindex' rebuilds its index" if cut else "")) from None
