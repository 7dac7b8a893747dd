"""End to end: the multiposition procedure through the real drivers against the loopback rig.

The same unit (truth) is calibrated through the real drivers (VISA table, ASCII or Modbus
chamber, binary-TCP or text-UDP IMU stream) and through the simulated rig; both must agree with
each other and with the truth within their 1-sigma uncertainties.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import procedures.multiposition as mp
from tests.drivers.conftest import FS, hil_yaml
from workbench.calset import Unit
from workbench.drivers.rig import open_real_rig
from workbench.grades import draw_unit, load_spec
from workbench.runner import record, start
from workbench.sim import simulate

DWELL_S = 5.0


def _bias_at(model, temp_c: float) -> np.ndarray:
    """True bias (3,) at the unit temperature, SI: the model's output for zero input."""
    return model.apply(np.zeros((1, 3)), None, temp_c)[0]


@pytest.mark.parametrize("base", ["hil", "hil_modbus"])
def test_multiposition_through_real_drivers_matches_the_simulated_rig(base, tmp_path, start_lab, closing):
    spec = load_spec("industrial_mems")
    truth = replace(draw_unit(spec, 5), sample_rate_hz=FS)
    lab = start_lab(hil_yaml(tmp_path, base), truth=truth, seed=11)
    rig = closing(open_real_rig(lab.config))
    seq = mp.sequence(spec, dwell_s=DWELL_S)
    session = record(start(seq, rig, Unit(truth.serial, truth.model), mp.NAME, None), rig)
    assert [s.label for s in session.steps] == ["x-up", "x-down", "y-up", "y-down", "z-up", "z-down"]
    assert all(s.extra["dropped_frames"] == 0 and s.extra["corrupt_frames"] == 0 for s in session.steps)
    real = mp.analyze(session).payload
    sim_session, _ = simulate(seq, truth, 12)
    sim = mp.analyze(sim_session).payload
    unit_c = float(session.samples["temp"].mean())  # the unit sits at the chamber's 23 °C
    for triad in ("accel", "gyro"):
        a, b = real[triad], sim[triad]
        # two independent noise / fixture-error realisations: the difference has sigma sqrt(sa^2 + sb^2)
        tol = 4.0 * np.hypot(a.bias_sigma, b.bias_sigma)
        assert np.all(np.abs(a.bias - b.bias) < tol), (triad, a.bias, b.bias, tol)
        truth_bias = _bias_at(getattr(truth, triad), unit_c)
        assert np.all(np.abs(a.bias - truth_bias) < 4.0 * a.bias_sigma), (triad, a.bias, truth_bias, a.bias_sigma)
    ka, kb = real["accel"].scale_misalignment, sim["accel"].scale_misalignment
    sk = np.hypot(real["accel"].scale_misalignment_sigma, sim["accel"].scale_misalignment_sigma)
    d = np.diag(ka - kb) / np.diag(sk)
    assert np.all(np.abs(d) < 4.0), d
