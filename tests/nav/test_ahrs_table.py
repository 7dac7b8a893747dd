"""The ahrs-table procedure on the simulated rig (consumer 9-axis board), raw vs calibrated."""

from __future__ import annotations

import json

import numpy as np
import pytest

import procedures.ahrs_table as proc
from tests.nav.conftest import calibration_from_truth
from workbench.calset import CalibrationSet
from workbench.errors import AnalysisError, ProcedureError
from workbench.grades import load_spec
from workbench.procedure import result_json
from workbench.jobs import simulate

SHORT = {"mounts": [[10.0, -5.0]], "rotate_s": 40.0, "dwell_s": 10.0}


@pytest.fixture(scope="module")
def run():
    spec = load_spec("consumer_9axis")
    session, truth = simulate(proc.sequence(spec, **SHORT), spec, seed=5)
    cal = calibration_from_truth(truth)
    return session, truth, cal, proc.analyze(session, calibration=cal)


def test_calibrated_ahrs_meets_the_accuracy_and_raw_does_not(run):
    *_, res = run
    cal, raw = res.result["calibrated"], res.result["raw"]
    for block in (cal, cal["complementary"]):
        assert block["heading_error_deg"] < 1.0
        assert block["roll_error_deg"] < 0.2 and block["pitch_error_deg"] < 0.2
    # consumer hard iron ~10 µT on a 24 µT horizontal field: tens of degrees raw (paper 004 Fig. 15)
    assert raw["heading_error_deg"] > 5.0 and raw["heading_error_deg"] > 10 * cal["heading_error_deg"]
    assert cal["velocity_error_mps"] is None
    assert cal["convergence_time_s"] is not None and cal["convergence_time_s"] < 30.0


def test_calibrated_bias_against_the_table(run):
    *_, res = run
    cal = res.result["calibrated"]
    assert np.all(np.abs(cal["gyro_bias_error"]) < 3 * np.array(cal["gyro_bias_sigma"]))
    doc = json.loads(result_json(res))
    assert set(doc["raw"]) >= {"roll_error_deg", "pitch_error_deg", "heading_error_deg", "velocity_error_mps",
                               "convergence_time_s", "gyro_bias_error"}
    assert len(proc.figures(res)) == 2


def test_industrial_calibrated_bias_within_3_sigma():
    # Industrial MEMS, one mount: 20 s hold, 60 s at +20 °/s, 90° index, 60 s at -45 °/s, 20 s hold.
    # The set's residual hard/soft iron (0.1 µT, 0.2 %: a heading error of ~0.3° that turns with
    # the table), counted as white noise, moved the filter's z gyro bias by 4.6-6.7 sigma on this
    # sequence (seeds 11-13); modelled as coloured measurement noise, the final bias error against the
    # table reference is within 3 sigma per axis (99.7 % for a consistent filter, fixed seed). The
    # sigma is the filter's and the reference's (20 s mean of 0.2 °/sqrt(h) ARW: 2.7 °/h) together.
    # Attitude: heading < 1° is the requirement; roll/pitch RMS < 0.05° is 5 sigma of the
    # table's 0.01° fixture error (the accelerometer residual adds 0.05 mg / g = 0.003°).
    spec = load_spec("industrial_mems")
    opts = {"mounts": [[-20.0, 15.0]], "rotate_s": 60.0, "dwell_s": 20.0}
    session, truth = simulate(proc.sequence(spec, **opts), spec, seed=11)
    cal = proc.analyze(session, calibration=calibration_from_truth(truth), **opts).result["calibrated"]
    assert np.all(np.abs(cal["gyro_bias_error"]) < 3 * np.array(cal["gyro_bias_sigma"]))
    assert cal["heading_error_deg"] < 1.0 and cal["roll_error_deg"] < 0.05 and cal["pitch_error_deg"] < 0.05


def test_needs_a_magnetometer(run):
    session, truth, cal, _ = run
    with pytest.raises(AnalysisError, match="no mag triad"):
        proc.analyze(session, calibration=CalibrationSet(cal.unit, {k: v for k, v in cal.triads.items()
                                                                    if k != "mag"}, cal.noise))
    with pytest.raises(ProcedureError, match="no magnetometer"):
        proc.sequence(load_spec("quasi_tactical"))


def test_magnetic_transient_is_rejected_and_reported():
    # +15 µT east (NED) for 10 s while the table turns at 20 °/s (a magnet brought near the unit):
    # a 32° step in the magnetic heading of the 24 µT horizontal field. The calibrated run detects it
    # by the field norm against the set's 48 µT and the dip, refuses the heading for the 10 s (to one
    # 0.1 s update) and keeps the heading error below the 1° required (unrejected: 22.7°, this seed).
    # The raw run's gate is the raw hard iron's size (~10 µT): it cannot tell a transient from its
    # own calibration error, and says so by detecting nothing.
    from workbench.nav.truth import table_truth

    spec = load_spec("consumer_9axis")
    session, truth = simulate(proc.sequence(spec, **SHORT), spec, seed=5)
    df = session.samples
    sel = np.nonzero((df["t"].to_numpy() >= 25.0) & (df["t"].to_numpy() < 35.0))[0]
    field = table_truth(session, sel).attitude.inv().apply(np.array([0.0, 15.0, 0.0]))
    df.loc[sel, ["mx", "my", "mz"]] = df[["mx", "my", "mz"]].to_numpy()[sel] + field
    res = proc.analyze(session, calibration=calibration_from_truth(truth), **SHORT)
    cal = res.result["calibrated"]
    assert cal["heading_max_deg"] < 1.0 and cal["complementary"]["heading_max_deg"] < 1.0
    (a, b), = cal["mag_disturbances"]
    assert abs(a - 25.0) < 0.15 and abs(b - 35.0) < 0.15 and abs(cal["mag_disturbed_s"] - 10.0) < 0.15
    assert res.result["raw"]["mag_disturbances"] == []
    assert any("magnetometer refused 10.0 s" in line for line in res.summary)
