"""A thermal session of holds at several chamber setpoints WITHOUT soak steps is analysed (issue 21).

Other labs' software records the holds at each setpoint and does not label the soak. The virtual-lab
soak session (industrial_mems, 10 Hz, unit time constant 120 s: the settings of test_thermal_sim.py) is
analysed as recorded, then stripped of its soak steps three ways: the soak samples unlabelled
(step -1), the soak samples not recorded at all, and also without any chamber setpoints on the holds
(grouped by the unit temperature). The soaks are found from the data; the fitted thermal coefficients
must be those of the labelled session: they are fitted on the same holds, so they agree to far below
their sigma (required: 0.01 sigma).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from procedures import thermal as proc
from workbench.analysis.thermal_points import found_soak_groups
from workbench.errors import SessionError
from workbench.grades import draw_unit, load_spec
from workbench.jobs import simulate

SPEC = load_spec("industrial_mems")


@pytest.fixture(scope="module")
def labelled():
    truth = replace(draw_unit(SPEC, 2), sample_rate_hz=10.0, thermal_time_constant_s=120.0)
    seq = proc.sequence(SPEC, t_min_c=-10.0, t_max_c=50.0, step_c=20.0, dwell_s=10.0)
    session, _ = simulate(seq, truth, 2)
    return session, proc.analyze(session)


def _strip(session, how: str):
    soaks = {s.index for s in session.steps_of_kind("soak")}
    df = session.samples.copy()
    is_soak = df["step"].isin(soaks)
    if how == "dropped":
        df = df[~is_soak].reset_index(drop=True)
    else:
        df.loc[is_soak, "step"] = -1
    steps = [s for s in session.steps if s.index not in soaks]
    if how == "no setpoints":
        steps = [replace(s, temperature_c=None) for s in steps]
    return replace(session, steps=steps, samples=df)


@pytest.mark.parametrize("how", ["unlabelled", "dropped", "no setpoints"])
def test_soaks_found_from_the_data_give_the_same_coefficients(labelled, how):
    session, ref = labelled
    stripped = _strip(session, how)
    groups = found_soak_groups(stripped)
    assert len(groups) == 4 and all(len(g.steps) == 6 for g in groups)  # four setpoints, six positions each
    result = proc.analyze(stripped)
    for key, fit in ref.payload.fits.items():
        other = result.payload.fits[key]
        assert other.order == fit.order, key
        diff = np.abs(other.coeffs - fit.coeffs)
        fitted = np.isfinite(fit.coeffs_sigma)  # NaN sigma: a coefficient above the chosen order (0 in both)
        assert np.all(diff[fitted] <= 0.01 * fit.coeffs_sigma[fitted]) and np.all(diff[~fitted] == 0), key


def test_one_setpoint_is_not_a_thermal_session(labelled):
    session, _ = labelled
    stripped = _strip(session, "dropped")
    first = {s.index for s in stripped.steps[:6]}
    one = replace(stripped, steps=stripped.steps[:6], samples=stripped.samples[stripped.samples["step"].isin(first)])
    with pytest.raises(SessionError, match="no holds at two or more setpoints"):
        proc.analyze(one)
