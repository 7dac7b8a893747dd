"""End to end: the multiposition procedure through the real drivers against the loopback rig.

The same unit (truth) is calibrated through the real drivers (VISA table, ASCII or Modbus
chamber, binary-TCP or text-UDP IMU stream) and, with K noise seeds, through the simulated rig.
The run-to-run scatter of the simulated rig is the noise reference: the loopback result must
fall inside the simulated rig's prediction interval, and so must the truth.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scipy.stats import t as student_t

import procedures.multiposition as mp
from tests.drivers.conftest import FS, hil_yaml
from workbench.calset import Unit
from workbench.drivers.rig import open_real_rig
from workbench.grades import draw_unit, load_spec
from workbench.runner import record, start
from workbench.jobs import simulate

DWELL_S = 5.0
K = 10  # simulated-rig runs giving the noise reference
SPEC = load_spec("industrial_mems")
TRUTH = replace(draw_unit(SPEC, 5), sample_rate_hz=FS)
SEQ = mp.sequence(SPEC, dwell_s=DWELL_S)


def _estimates(session) -> np.ndarray:
    """accel bias (3), gyro bias (3), accel scale-factor errors (3), SI."""
    p = mp.analyze(session).payload
    return np.concatenate([p["accel"].bias, p["gyro"].bias, np.diag(p["accel"].scale_misalignment)])


@pytest.fixture(scope="module")
def simulated():
    """Estimates from K simulated-rig runs of the same unit (independent noise and fixture errors)."""
    return np.array([_estimates(simulate(SEQ, TRUTH, 100 + k)[0]) for k in range(K)])


@pytest.mark.parametrize("base", ["hil", "hil_modbus"])
def test_multiposition_through_real_drivers_matches_the_simulated_rig(base, simulated, tmp_path, start_lab, closing):
    lab = start_lab(hil_yaml(tmp_path, base), truth=TRUTH, seed=11)
    rig = closing(open_real_rig(lab.config))
    session = record(start(SEQ, rig, Unit(TRUTH.serial, TRUTH.model), mp.NAME, None), rig)
    assert [s.label for s in session.steps] == ["x-up", "x-down", "y-up", "y-down", "z-up", "z-down"]
    assert all(s.extra["dropped_frames"] == 0 and s.extra["corrupt_frames"] == 0 for s in session.steps)
    real = _estimates(session)
    # Prediction interval of one more run from K runs: mean +- t(K-1) * s * sqrt(1 + 1/K); two-sided
    # 1e-4 per quantity keeps the family of 9 quantities x 2 configurations below 0.2 % false alarms.
    mean, s = simulated.mean(axis=0), simulated.std(axis=0, ddof=1)
    half = student_t.ppf(1 - 0.5e-4, K - 1) * s * np.sqrt(1 + 1 / K)
    assert np.all(np.abs(real - mean) < half), (real - mean) / half
    # the truth at the unit temperature (23 °C) lies in the same band around the loopback result
    unit_c = float(session.samples["temp"].mean())
    acc, gyr = TRUTH.accel, TRUTH.gyro
    # scale factor at unit_c: (out(+1) - out(-1)) / 2 - 1 cancels bias and the quadratic nonlinearity
    sf = 0.5 * (acc.apply(np.eye(3), None, unit_c) - acc.apply(-np.eye(3), None, unit_c)).diagonal() - 1.0
    truth = np.concatenate([acc.apply(np.zeros((1, 3)), None, unit_c)[0], gyr.apply(np.zeros((1, 3)), None, unit_c)[0],
                            sf])
    assert np.all(np.abs(real - truth) < half), (real - truth) / half
    assert np.all(np.abs(mean - truth) < half), (mean - truth) / half
