"""Fixtures of the dashboard tests: a temporary store (``WORKBENCH_DB``) seeded with two set versions."""

from __future__ import annotations

import numpy as np
import pytest

from workbench.calset import CalibrationSet, Provenance, TriadCalibration, Unit
from workbench.model import TriadModel
from workbench.store import Store

SERIAL = "DASH-001"
# gyro x bias moves by 3e-6 rad/s between versions with sigma 1e-6 each: (3e-6)/sqrt(2)/1e-6 = 2.12 sigma
BIAS_V1 = np.array([1e-5, -2e-5, 3e-5])
BIAS_V2 = BIAS_V1 + np.array([3e-6, 0.0, 0.0])
BIAS_SIGMA = np.array([1e-6, 1e-6, np.nan])  # z not observed


def make_set(bias: np.ndarray) -> CalibrationSet:
    """A gyro-only set with the given bias (rad/s) and a known sigma."""
    tc = TriadCalibration(TriadModel(bias=bias, scale_misalignment=np.diag([1e-4, -2e-4, 5e-5])),
                          {"bias": BIAS_SIGMA, "scale_misalignment": np.full((3, 3), 1e-5)})
    return CalibrationSet(Unit(SERIAL, "test-imu"), {"gyro": tc},
                          noise={"gyro": {"arw": [1e-4, 1e-4, None]}},
                          provenance=Provenance(procedures=("multiposition",)))


@pytest.fixture
def seeded_db(tmp_path, monkeypatch):
    """WORKBENCH_DB (and WORKBENCH_RUNS) pointing at a fresh store holding versions 1 and 2 of DASH-001."""
    url = f"sqlite:///{tmp_path / 'wb.db'}"
    monkeypatch.setenv("WORKBENCH_DB", url)
    monkeypatch.setenv("WORKBENCH_RUNS", str(tmp_path / "runs"))
    store = Store(url)
    store.add_set(make_set(BIAS_V1))
    store.add_set(make_set(BIAS_V2))
    return store


def make_session(n_per_step: int = 100, rate_hz: float = 10.0):
    """A two-step static session (z-down, x-up) at ``rate_hz`` with gravity on the down axis, in memory."""
    import pandas as pd

    from workbench.session import Session, Site, StepRecord
    from workbench.sequence import mount_matrix

    g = 9.80665  # m/s^2
    rows, steps = [], []
    for i, (mount, acc) in enumerate((("z-down", (0, 0, -g)), ("x-up", (g, 0, 0)))):
        t = (i * n_per_step + np.arange(n_per_step)) / rate_hz
        rows.append(pd.DataFrame({"t": t, "step": i, "gx": 1e-5, "gy": 0.0, "gz": 0.0,
                                  "ax": acc[0], "ay": acc[1], "az": acc[2]}))
        steps.append(StepRecord(i, "static", float(t[0]), float(t[-1]) + 0.5 / rate_hz, mount_matrix(mount),
                                label=mount))
    return Session("sess-0001", Unit(SERIAL, "test-imu"), Site(40.8, table_zero_azimuth_deg=0.0), rate_hz,
                   "multiposition", steps, pd.concat(rows, ignore_index=True))


@pytest.fixture
def stored_session(seeded_db, tmp_path):
    """A session folder written with write_session and recorded in the seeded store."""
    from workbench.session import write_session

    folder = write_session(make_session(), tmp_path / "session")
    seeded_db.add_session("sess-0001", SERIAL, "test-imu", "multiposition", str(folder), n_steps=2)
    return folder
