"""A multi-stream, arrival-stamped, paused and saturating recording from the virtual lab, imported and
checked against its truth: instants, interpolation, repeated/saturated counts, and the calibration."""

import numpy as np
import pytest
import yaml

from workbench.analysis.mag_free import calibrate_free
from workbench.analysis.mag_fit import polar_rotation
from workbench.grade_fixtures import load_spec
from workbench.grades import draw_unit
from workbench.importer import import_file
from workbench.session import FLAG_REPEATED, FLAG_SATURATED
from workbench.sim.stream_files import write_stream_recording

T_REF = 25.0


def _profile(path):
    def stream(file, cols, rate, **extra):
        return {"file": file, "time": {"column": "t_s", "unit": "s", "stamps": "arrival"}, "rate_hz": rate,
                "columns": cols, **extra}
    prof = {"format": "workbench-import/1", "site": {"latitude_deg": 48.0}, "time_base": "accel", "streams": {
        "accel": stream("accelerometer.csv", {f"a{c}": {"column": f"a{c}_g", "unit": "g"} for c in "xyz"}, 100),
        "gyro": stream("gyroscope.csv", {f"g{c}": {"column": f"g{c}_dps", "unit": "deg/s"} for c in "xyz"}, 100,
                       range={"value": 250.0, "unit": "deg/s"}),
        "temperature": stream("temperature.csv", {"temp": {"column": "temp_c", "unit": "degC"}}, 100),
        "mag": stream("magnetometer.csv", {f"m{c}": {"column": f"m{c}_gauss", "unit": "gauss"} for c in "xyz"}, 75)}}
    path.write_text(yaml.safe_dump(prof))
    return path


@pytest.fixture(scope="module")
def imported(tmp_path_factory):
    root = tmp_path_factory.mktemp("rec")
    unit = draw_unit(load_spec("consumer_9axis"), 11)
    truth = write_stream_recording(root / "data", unit, 11, duration_s=60.0, temperature_c=T_REF)
    session = import_file(_profile(root / "p.yaml"), root / "data", root / "s")
    return session, truth


def test_reconstructed_instants_match_the_true_sampling(imported):
    session, truth = imported
    summary = session.options["import"]
    clock = summary["streams"]["accel"]["clock"]
    assert len(clock["gaps"]) == 1 and clock["gaps"][0]["lost_samples"] == pytest.approx(100, abs=1)
    # the merge drops base rows where the magnetometer has no data (its first and last reads, its pause),
    # so each session row is matched to the nearest true instant (one to one); the common offset (the
    # smallest latency, invisible in stamps) is the median error: every instant within T/2 of the truth
    # after it (the clock model, tests/importers/test_clock.py)
    t = session.samples["t"].to_numpy()
    true = truth.imu_instants
    guess = t + true[np.argmin(np.abs(true - true[0] - 0))]
    offset = 0.0
    for _ in range(3):  # the first kept row may not be the first true one
        j = np.clip(np.searchsorted(true, guess - offset), 1, len(true) - 1)
        j = np.where(np.abs(true[j - 1] - (guess - offset)) < np.abs(true[j] - (guess - offset)), j - 1, j)
        offset = float(np.median(guess - true[j]))
    assert len(np.unique(j)) == len(t)
    err = guess - true[j] - offset
    assert np.abs(err).max() < 0.5 / 100
    # the pause splits the recording into two free steps, none with a gap inside
    assert [s.kind for s in session.steps] == ["free", "free"]


def test_repeated_and_saturated_counts_against_truth(imported):
    session, truth = imported
    s = summary = session.options["import"]["streams"]
    assert s["gyro"]["saturated"] == int(truth.gyro_saturated.sum()) > 20
    flags = session.samples["flags"].to_numpy()
    assert np.count_nonzero(flags & FLAG_SATURATED["gyro"]) == int(truth.gyro_saturated[:len(flags)].sum())
    # every true repeat is found (exact equality); a fresh update can equal the previous by chance when
    # all three axes round to the same count: per axis at most LSB / (sqrt(2) sigma sqrt(2 pi)) =
    # 0.092 / (1.41 * 0.17 * 2.51) = 0.15 at rest, all three 0.0035: under 1 % of the reads
    true_rep = int(truth.mag_repeated.sum())
    assert true_rep > 50
    assert true_rep <= summary["mag"]["repeated"] <= true_rep + 0.01 * summary["mag"]["samples"]


def test_interpolated_field_against_the_true_field(imported):
    session, truth = imported
    t_host = session.samples["t"].to_numpy() + truth.imu_instants[0]
    m = session.mag()
    good = session.good("mag")
    ref = truth.true_mag(t_host)
    err = np.linalg.norm(m - ref, axis=1)
    # the field seen by the body changes at |dm/dt|; a value is late by up to one update period
    # (1/75 s: read after the update) plus the two clocks' instants (T/2 each) plus the offset of the
    # smallest latencies (a poll phase, < 1 period): delta <= 1/75 + 0.5/100 + 0.5/77 + 1/77 = 0.038 s;
    # noise 0.17 µT per axis and LSB 0.092 µT: 3-axis 3.5-sigma 1.1 µT
    dmdt = np.linalg.norm(np.gradient(ref, t_host, axis=0), axis=1)
    bound = 1.1 + 0.038 * dmdt + 0.01 * np.linalg.norm(ref, axis=1)  # + chord error (pi f T)^2/2 < 1 %
    assert np.mean(err[good] <= bound[good]) > 0.99
    still = dmdt < 1.0  # µT/s: nearly at rest the interpolation error is the noise alone
    assert np.sqrt(np.mean(err[good & still] ** 2)) < 0.5


def test_magnetometer_calibration_from_the_import_matches_truth(imported):
    session, truth = imported
    unit = truth.unit
    cal = calibrate_free(session, robust="auto", accel_model=unit.accel)
    fit = cal.fit
    b = unit.mag.apply(np.zeros((3, 3)), None, np.full(3, T_REF))[0]
    a = (unit.mag.apply(np.eye(3), None, np.full(3, T_REF)) - b).T
    k = np.cbrt(np.linalg.det(a))  # no reference norm: det(I + M) = 1 fixes the scale
    # the same 4-sigma criterion as on the in-memory session (tests/analysis/test_mag_free.py)
    assert np.all(np.abs(fit.bias - b) < 4 * fit.bias_sigma)
    assert np.all(np.abs(fit.soft_iron - a / k) < 4 * fit.soft_iron_sigma)
    assert np.all(np.abs(fit.alignment - polar_rotation(a)[1]) < 4 * fit.alignment_sigma)
    assert abs(np.degrees(fit.dip) - 60.0) < 4 * np.degrees(fit.dip_sigma)


def test_the_axis_check_passes_on_the_virtual_recording(imported):
    session, _ = imported
    checks = {c["reference"]: c for c in session.options["import"]["axis_check"]}
    assert checks["accel"]["agrees"] is True and checks["mag"]["agrees"] is True


def test_a_flipped_gyro_axis_in_the_files_is_named_on_import(tmp_path):
    unit = draw_unit(load_spec("consumer_9axis"), 12)
    write_stream_recording(tmp_path / "data", unit, 12, duration_s=30.0, pause_s=0.0, temperature_c=T_REF)
    gyro = (tmp_path / "data" / "gyroscope.csv").read_text().splitlines()
    rows = [gyro[0]] + [",".join([r.split(",")[0], r.split(",")[1], str(-float(r.split(",")[2])), r.split(",")[3]])
                        for r in gyro[1:]]  # the logger wrote gy with the wrong sign
    (tmp_path / "data" / "gyroscope.csv").write_text("\n".join(rows) + "\n")
    s = import_file(_profile(tmp_path / "p.yaml"), tmp_path / "data", tmp_path / "s")
    checks = {c["reference"]: c for c in s.options["import"]["axis_check"]}
    for ref in ("accel", "mag"):
        assert checks[ref]["agrees"] is False
        assert np.allclose(checks[ref]["best"], np.diag([1.0, -1.0, 1.0]))
        assert "DISAGREE" in checks[ref]["message"] and "gy <- -gy" in checks[ref]["message"]


def test_sections_count_the_time_base_rows(tmp_path):
    unit = draw_unit(load_spec("consumer_9axis"), 13)
    write_stream_recording(tmp_path / "data", unit, 13, duration_s=20.0, pause_s=0.0, temperature_c=T_REF)
    p = _profile(tmp_path / "p.yaml")
    prof = yaml.safe_load(p.read_text())
    prof["sections"] = {"inline": {"first": [100, 900], "second": [1000, 1800]},
                        "steps": {"first": {"kind": "free"}, "second": {"kind": "free"}}}
    p.write_text(yaml.safe_dump(prof))
    s = import_file(p, tmp_path / "data", tmp_path / "s")
    assert [st.label for st in s.steps] == ["first", "second"]
    # 800 rows each, less the base rows the merge dropped before the magnetometer's first read (none here)
    assert [int((s.samples["step"] == st.index).sum()) for st in s.steps] == [800, 800]
