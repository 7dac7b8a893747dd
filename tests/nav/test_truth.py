"""Tests of workbench.nav.truth: the table as the reference, checked on the simulated rig."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from tests.nav.conftest import calibration_from_truth
from workbench.earth import gravity_ned
from workbench.errors import AnalysisError, SessionError
from workbench.grades import load_spec
from workbench.nav.compensate import compensate, imu_samples
from workbench.nav.truth import mount_segments, reference_gyro_bias, table_truth
from workbench.rigsites import declination
from workbench.sequence import Hold, Rotate, Sequence
from workbench.session import Site
from workbench.jobs import simulate


@pytest.fixture(scope="module")
def run():
    seq = Sequence("truth-test", [Hold("z-down", table_angle=np.radians(30.0), dwell_s=10.0),
                                  Rotate("y-down", rate=np.radians(30.0), revolutions=None, duration_s=12.0)])
    session, truth = simulate(seq, load_spec("industrial_mems"), seed=4)
    exact = calibration_from_truth(truth, errors={"gyro": (0, 0), "accel": (0, 0), "mag": (0, 0)})
    return session, truth, compensate(imu_samples(session.samples, session.sample_rate_hz), exact)


def test_truth_attitude_explains_the_compensated_accelerometer(run):
    session, truth, comp = run
    tt = table_truth(session)
    f_pred = tt.attitude.inv().apply(np.tile(-gravity_ned(session.site.latitude, session.site.height_m),
                                             (len(tt.rows), 1)))
    for st in session.steps:
        sel = session.samples["step"].to_numpy() == st.index
        a, b = comp.accel[sel].mean(axis=0), f_pred[sel].mean(axis=0)
        angle = np.arccos(np.clip(a @ b / np.linalg.norm(a) / np.linalg.norm(b), -1, 1))
        # fixture error 0.01° (1.7e-4 rad) 1-sigma per axis, accel noise 3e-5 rad: 5 sigma = 8.7e-4 rad
        assert angle < 8.7e-4


def test_reference_bias_of_an_exactly_compensated_gyro_is_zero(run):
    session, truth, comp = run
    for st in session.steps:
        rows = np.nonzero(session.samples["step"].to_numpy() == st.index)[0]
        ref, sig = reference_gyro_bias(comp.gyro[rows], table_truth(session, rows), session.site.latitude)
        # what remains is noise: white (sig) and the bias-instability wander (B) plus the
        # fixture error times the table rate (1.7e-4 rad x 0.52 rad/s = 9e-5 rad/s on the rotating step)
        wander = truth.gyro_noise.bias_instability + 1.7e-4 * abs(st.table_rate)
        assert np.all(np.abs(ref) < 4 * np.hypot(sig, wander))


def test_segments_split_at_mount_changes_and_declination(run):
    session, *_ = run
    segs = mount_segments(session)
    assert len(segs) == 2 and segs[0][0] == 0 and segs[-1][-1] == len(session.samples) - 1
    assert declination(session) == 0.0  # the sim rig's configuration
    assert declination(session, 3.0) == pytest.approx(np.radians(3.0))
    with pytest.raises(AnalysisError, match="declination unknown"):
        declination(replace(session, rig="unknown-rig"))
    with pytest.raises(SessionError, match="table_zero_azimuth"):
        table_truth(replace(session, site=Site(session.site.latitude_deg)))
