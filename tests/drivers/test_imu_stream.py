"""IMU stream reader: frame formats, scale factors, dropped / corrupt frames, timestamp jumps, lost links."""

from __future__ import annotations

import socket
import threading

import numpy as np
import pytest

from workbench.sim.hil import free_port
from workbench.drivers.imu_stream import FrameFormat, ImuStream, xor8
from workbench.errors import RigError

FIELDS = ["counter", "gx", "gy", "gz", "ax", "ay", "az", "temp"]
TEXT = {"format": "text", "fields": FIELDS, "checksum": "xor8",
        "scale": {"gx": np.pi / 180, "gy": np.pi / 180, "gz": np.pi / 180, "ax": 9.80665, "ay": 9.80665, "az": 9.80665}}
BINARY = {"format": "binary", "fields": FIELDS, "sync": "a55a", "struct": "<I7f", "checksum": "xor8"}


def _values(n: int, start: int = 0) -> dict:
    rng = np.random.default_rng(3)
    v = {c: rng.normal(0.0, 0.1, n) for c in FIELDS[1:7]}
    v["az"] = v["az"] - 9.8
    v.update(temp=np.full(n, 23.0), counter=np.arange(start, start + n))
    return v


@pytest.mark.parametrize("settings", [TEXT, BINARY], ids=["text", "binary"])
def test_round_trip_through_the_wire_format(settings):
    fmt = FrameFormat.from_settings(settings, "imu")
    v = _values(4)
    data = fmt.encode(v)
    frames = [x for x in data.split(b"\n") if x] if fmt.kind == "text" else \
        [data[i + 2:i + fmt.frame_size] for i in range(0, len(data), fmt.frame_size)]
    got = np.array([fmt.parse(f) for f in frames])
    # text: 10 significant digits; binary: float32 (relative 6e-8)
    for i, c in enumerate(FIELDS):
        np.testing.assert_allclose(got[:, i], v[c], rtol=1e-6, atol=1e-9)


def test_format_errors_name_the_field():
    with pytest.raises(RigError, match=r"imu: fields .* \(unknown \['gq'\]"):
        FrameFormat.from_settings({**TEXT, "fields": ["gq", *FIELDS]}, "imu")
    with pytest.raises(RigError, match=r"imu: struct '<I6f' holds 7 items for 8 fields"):
        FrameFormat.from_settings({**BINARY, "struct": "<I6f"}, "imu")
    with pytest.raises(RigError, match=r"imu: fields lack az"):
        FrameFormat.from_settings({**TEXT, "fields": FIELDS[:6]}, "imu")
    with pytest.raises(RigError, match=r"imu: a binary format needs 'sync'"):
        FrameFormat.from_settings({**BINARY, "sync": ""}, "imu")


class _Sender:
    """A one-client TCP server on 127.0.0.1 that sends the given bytes, then holds or closes the link."""

    def __init__(self, data: bytes, close: bool = False) -> None:
        self.sock = socket.create_server(("127.0.0.1", 0))
        self.port = self.sock.getsockname()[1]
        self.data, self.close_after = data, close
        self.done = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self) -> None:
        conn, _ = self.sock.accept()
        with conn:
            conn.sendall(self.data)
            if not self.close_after:
                self.done.wait(5.0)

    def stop(self) -> None:
        self.done.set()
        self.thread.join(2.0)
        self.sock.close()


@pytest.fixture
def stream(closing):
    senders = []

    def make(data: bytes, settings=BINARY, close=False, **extra) -> ImuStream:
        s = _Sender(data, close)
        senders.append(s)
        st = closing(ImuStream({**settings, "address": f"socket://127.0.0.1:{s.port}", "sample_rate_hz": 100,
                                "timeout_s": 0.3, **extra}, "imu", start_sample=1000))
        st.open()
        return st

    yield make
    for s in senders:
        s.stop()


def test_times_from_the_counter_and_one_dropped_frame(stream):
    v = _values(10)
    keep = np.r_[0:4, 5:10]  # frame with counter 4 lost on the way
    fmt = FrameFormat.from_settings(BINARY, "imu")
    s = stream(fmt.encode({k: a[keep] for k, a in v.items()}))
    block = s.take(9)
    # session sample index continues from start_sample 1000; the lost frame leaves one 2/fs gap
    np.testing.assert_allclose(block.t * 100, 1000 + keep)
    np.testing.assert_allclose(block.columns["gx"], v["gx"][keep], rtol=1e-6)
    assert s.reset_counts() == {"frames": 9, "dropped_frames": 1, "corrupt_frames": 0}


def test_timestamp_jump_names_the_frame(stream):
    v = _values(8)
    v["counter"] = np.r_[0:4, 40:44]
    s = stream(FrameFormat.from_settings(BINARY, "imu").encode(v))
    with pytest.raises(RigError, match=r"imu \(socket://127\.0\.0\.1:\d+\): timestamps jump at frame 5 after sample "
                                       r"1003: counter 3 -> 40 \(37 sample intervals\)"):
        s.take(8)


def test_frames_that_do_not_parse(stream):
    fmt = FrameFormat.from_settings(TEXT, "imu")
    good = fmt.encode(_values(3))
    s = stream(good + b"1,2,3\n" + b"4,5,6*00\n", settings=TEXT, max_corrupt_frames=1)
    assert len(s.take(3).t) == 3
    with pytest.raises(RigError, match=r"imu \(socket://127\.0\.0\.1:\d+\): frame after sample 1002 does not parse "
                                       r"\(checksum mismatch\): b'4,5,6\*00' \(2 bad frames in this step"):
        s.take(1)


def test_stream_that_stops(stream):
    s = stream(FrameFormat.from_settings(BINARY, "imu").encode(_values(2)))
    with pytest.raises(RigError, match=r"imu \(socket://127\.0\.0\.1:\d+\): no frame for 0\.3 s \(after sample 1001\)"):
        s.take(3)


def test_lost_link(stream):
    s = stream(FrameFormat.from_settings(BINARY, "imu").encode(_values(2)), close=True)
    with pytest.raises(RigError, match=r"imu \(socket://127\.0\.0\.1:\d+\): connection lost after sample 1001"):
        s.take(3)


def test_udp_text_stream_in_lab_units(closing):
    port = free_port()
    st = closing(ImuStream({**TEXT, "address": f"udp://127.0.0.1:{port}", "sample_rate_hz": 50}, "imu"))
    st.open()
    body = "7,90.0,0,-45.0,0.5,0,-1.0,23.5"  # the unit sends °/s and g
    line = f"{body}*{xor8(body.encode()):02X}\n".encode()
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as tx:
        tx.sendto(line, ("127.0.0.1", port))
    block = st.take(1)
    assert block.t[0] == 0.0
    got = [block.columns[c][0] for c in ("gx", "gz", "ax", "az", "temp")]
    np.testing.assert_allclose(got, [np.pi / 2, -np.pi / 4, 0.5 * 9.80665, -9.80665, 23.5], rtol=1e-12)


def test_address_that_does_not_answer():
    st = ImuStream({**BINARY, "address": f"socket://127.0.0.1:{free_port()}", "sample_rate_hz": 100}, "imu")
    with pytest.raises(RigError, match=r"imu \(socket://127\.0\.0\.1:\d+\): cannot connect"):
        st.open()
