"""The hand-held stream recording writer (workbench/sim/stream_files.py): the files against the
truth it returns and against the clock and magnetometer model of its docstring."""

import numpy as np
import pandas as pd
import pytest

from workbench.grade_fixtures import load_spec
from workbench.grades import draw_unit
from workbench.sim.stream_files import GAUSS_LSB, write_stream_recording

FS, DURATION, PAUSE_AT, PAUSE = 100.0, 20.0, 10.0, 1.0
HOST_PPM, MAG_UPDATE, MAG_READ, MAG_PPM = 80.0, 75.0, 77.0, -120.0


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    folder = tmp_path_factory.mktemp("streams")
    unit = draw_unit(load_spec("consumer_9axis"), 7)
    truth = write_stream_recording(folder, unit, 4, duration_s=DURATION, pause_at_s=PAUSE_AT, pause_s=PAUSE,
                                   host_ppm=HOST_PPM, mag_update_hz=MAG_UPDATE, mag_read_hz=MAG_READ, mag_ppm=MAG_PPM)
    files = {name: pd.read_csv(folder / f"{name}.csv") for name in
             ("accelerometer", "gyroscope", "temperature", "magnetometer")}
    return truth, files


def test_imu_rows_are_the_samples_outside_the_pause_on_the_host_clock(recording):
    """1 s pause at 100 Hz: 100 of 2000 rows dropped. Instants: k / fs on the IMU clock, host clock
    offset and running 80 ppm fast: host_to_motion gives back k / fs (1e-9 s rounding)."""
    truth, files = recording
    n = int(DURATION * FS) - int(PAUSE * FS)
    assert len(truth.imu_instants) == n
    assert all(len(files[f]) == n for f in ("accelerometer", "gyroscope", "temperature"))
    k = np.round(truth.host_to_motion(truth.imu_instants) * FS)
    np.testing.assert_allclose(truth.host_to_motion(truth.imu_instants), k / FS, atol=1e-9)
    kept = np.r_[np.arange(int(PAUSE_AT * FS)), np.arange(int((PAUSE_AT + PAUSE) * FS), int(DURATION * FS))]
    np.testing.assert_array_equal(k, kept)
    step = np.diff(truth.imu_instants)
    assert np.median(step) == pytest.approx((1 + HOST_PPM * 1e-6) / FS, rel=1e-9)


def test_stamps_are_arrivals_after_the_sampling_instants(recording):
    """Arrival = the first host poll after the sample is ready (transport 2 ms), polls 40-250 ms
    apart, 0.1 ms per sample within a burst: latency in [2 ms, 250 ms + 2 ms + burst]; non-decreasing."""
    truth, files = recording
    stamps = files["accelerometer"]["t_s"].to_numpy()
    latency = stamps - truth.imu_instants
    assert latency.min() >= 0.002 - 1e-12
    assert latency.max() <= 0.25 + 0.002 + 30 * 1e-4
    assert np.all(np.diff(stamps) >= 0)
    np.testing.assert_array_equal(files["gyroscope"]["t_s"], stamps)  # one read: the same stamps


def test_files_are_in_g_and_degrees_per_second_with_the_saturated_rows_at_the_range(recording):
    """Still rows: |accel| is 1 g within the consumer unit's bias and scale errors (a few %: 5 % used);
    in m/s^2 it would read 9.8. Saturated gyro rows read the ±250 °/s range and their count is the truth's."""
    truth, files = recording
    acc = files["accelerometer"][["ax_g", "ay_g", "az_g"]].to_numpy()
    k = np.round(truth.host_to_motion(truth.imu_instants) * FS).astype(int)
    still = truth.motion.still[k]
    assert still.sum() > 500
    assert np.median(np.linalg.norm(acc[still], axis=1)) == pytest.approx(1.0, abs=0.05)
    gyro = files["gyroscope"][["gx_dps", "gy_dps", "gz_dps"]].to_numpy()
    at_rail = np.any(np.abs(gyro) >= 250.0 * (1 - 1e-9), axis=1)
    np.testing.assert_array_equal(at_rail, truth.gyro_saturated)
    assert at_rail.sum() > 0 and np.abs(gyro).max() <= 250.0 * (1 + 1e-12)
    assert files["temperature"]["temp_c"].mean() == pytest.approx(truth.temperature_c, abs=0.5)


def test_magnetometer_reads_repeat_updates_as_the_two_clocks_beat(recording):
    """Reads at 77 Hz of updates at 75 Hz (its clock 120 ppm slow): a fraction 1 - 75 / (77 (1 - 1.2e-4))
    of the reads repeats the previous update (beat of deterministic clocks: +-2 reads). A repeated
    row equals the previous one in the file; rows not flagged differ except when noise rounds all three
    axes to the same counts (at most 1 % of the rows)."""
    truth, files = recording
    mag = files["magnetometer"][["mx_gauss", "my_gauss", "mz_gauss"]].to_numpy()
    n = len(mag)
    assert len(truth.mag_read_instants) == n == len(truth.mag_repeated)
    expected = 1 - MAG_UPDATE / (MAG_READ * (1 + MAG_PPM * 1e-6))
    assert truth.mag_repeated.sum() == pytest.approx(expected * n, abs=2)
    same = np.r_[False, np.all(mag[1:] == mag[:-1], axis=1)]
    assert np.all(same[truth.mag_repeated])
    assert (same & ~truth.mag_repeated).sum() <= 0.01 * n


def test_magnetometer_values_are_the_true_field_plus_noise_in_counts(recording):
    """Still reads (still for the 0.05 s before, so the shown update saw the same attitude): the file in
    gauss x 100 minus the unit's noise-free output is white noise of the update (0.02 µT/√Hz x sqrt(75)
    = 0.17 µT) plus rounding to 1/1090 gauss (LSB^2/12): its std within 4/sqrt(2N) of that, its mean
    within 4 std / sqrt(N) of 0 per axis; every value a whole number of counts."""
    truth, files = recording
    mag = files["magnetometer"][["mx_gauss", "my_gauss", "mz_gauss"]].to_numpy()
    np.testing.assert_allclose(mag / GAUSS_LSB, np.round(mag / GAUSS_LSB), atol=1e-6)
    u = truth.host_to_motion(truth.mag_read_instants)
    k = np.clip(np.round(u * FS).astype(int), 0, len(truth.motion.still) - 1)
    k5 = np.clip(k - 5, 0, None)
    ok = truth.motion.still[k] & truth.motion.still[k5] & ~truth.mag_repeated
    res = 100.0 * mag[ok] - truth.true_mag(truth.mag_read_instants[ok])
    n = ok.sum()
    assert n > 300
    white = truth.unit.mag_noise.white * np.sqrt(MAG_UPDATE)
    lsb = 100.0 * GAUSS_LSB
    std = np.sqrt(white ** 2 + lsb ** 2 / 12)
    np.testing.assert_allclose(res.std(axis=0), std, rtol=4 / np.sqrt(2 * n))
    assert np.all(np.abs(res.mean(axis=0)) < 4 * std / np.sqrt(n))
