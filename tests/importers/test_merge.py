"""Interpolation onto the time base: delay and amplitude error on a known sinusoid; flags."""

import numpy as np
import pandas as pd
import pytest

from workbench.importers.merge import merge_streams
from workbench.importers.streams import Stream
from workbench.session import FLAG_REPEATED, FLAG_SATURATED


def _stream(name, t, values, repeated=None, saturated=None):
    n = len(t)
    return Stream(name, f"{name}.csv", np.asarray(t, float), pd.DataFrame(values),
                  np.zeros(n, bool) if repeated is None else repeated,
                  np.zeros(n, bool) if saturated is None else saturated, None, np.arange(n), True)


@pytest.mark.parametrize("f_hz", [0.5, 2.0, 5.0])
def test_linear_interpolation_has_no_delay_and_the_chord_amplitude_error(f_hz):
    # a 75 Hz stream onto a 100 Hz base, unrelated phases
    T = 1 / 75.0
    ts = 0.0037 + np.arange(int(20 / T)) * T
    tb = np.arange(int(19.5 * 100)) / 100.0 + 0.1
    w = 2 * np.pi * f_hz
    base = _stream("imu", tb, {"gx": np.zeros(len(tb)), "gy": np.zeros(len(tb)), "gz": np.zeros(len(tb)),
                               "ax": np.zeros(len(tb)), "ay": np.zeros(len(tb)), "az": np.zeros(len(tb))})
    mag = _stream("mag", ts, {"mx": np.sin(w * ts), "my": np.cos(w * ts), "mz": np.zeros(len(ts))})
    m = merge_streams({"imu": base, "mag": mag}, "imu").samples
    t = m["t"].to_numpy() + 0.1
    y = m["mx"].to_numpy()
    # least-squares fit of A sin(w (t - d)): amplitude and delay
    c, s = np.linalg.lstsq(np.c_[np.sin(w * t), np.cos(w * t)], y, rcond=None)[0]
    amp, delay = np.hypot(c, s), -np.arctan2(s, c) / w
    bound = (np.pi * f_hz * T) ** 2 / 2  # chord under an arc: T^2/8 * max|x''| = (pi f T)^2 / 2 of A
    assert abs(delay) < 1e-3 * T  # no delay: the error is in phase with the second derivative
    assert 0.0 <= 1.0 - amp <= bound  # the chord lies inside the arc: never an overshoot
    assert np.abs(y - np.sin(w * t)).max() <= bound * 1.0001


def test_flags_mark_saturated_neighbours_and_spanned_repeats():
    tb = np.arange(100) / 100.0
    zeros = np.zeros(100)
    sat = np.zeros(100, bool)
    sat[10] = True
    base = _stream("gyro", tb, {c: zeros for c in ("gx", "gy", "gz")}, saturated=sat)
    acc = _stream("accel", tb, {c: zeros for c in ("ax", "ay", "az")})  # same instants: copied
    ts = np.arange(80) / 80.0
    rep = np.zeros(80, bool)
    rep[40] = True  # a stale read at 0.5 s: left out, the neighbours 0.4875 and 0.5125 bracket it
    magv = np.arange(80.0)
    magv[40] = magv[39]
    mag = _stream("mag", ts, {"mx": magv, "my": magv, "mz": magv}, repeated=rep)
    m = merge_streams({"gyro": base, "accel": acc, "mag": mag}, "gyro")
    flags = m.samples["flags"].to_numpy()
    assert flags[10] == FLAG_SATURATED["gyro"] and np.all(m.samples["ax"] == 0)
    t = m.samples["t"].to_numpy()
    spans = (t > 39 / 80) & (t < 41 / 80)
    assert np.all(flags[spans] & FLAG_REPEATED["mag"]) and not np.any(flags[~spans] & FLAG_REPEATED["mag"])
    # the stale value is not used: the interpolation joins the fresh neighbours
    assert np.allclose(m.samples["mx"].to_numpy()[spans], t[spans] * 80)
    # base rows after the mag's last sample are dropped and counted
    assert m.dropped["mag"] == int(np.count_nonzero(tb > ts[-1]))


def test_nothing_interpolated_across_a_stream_gap():
    tb = np.arange(300) / 100.0
    zeros = np.zeros(300)
    base = _stream("imu", tb, {c: zeros for c in ("gx", "gy", "gz", "ax", "ay", "az")})
    ts = np.r_[np.arange(0, 1, 1 / 75), np.arange(2, 3, 1 / 75)]
    mag = _stream("mag", ts, {"mx": ts, "my": ts, "mz": ts})
    m = merge_streams({"imu": base, "mag": mag}, "imu")
    t = m.samples["t"].to_numpy()
    assert not np.any((t > 1.0) & (t < 2.0))
