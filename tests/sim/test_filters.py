"""The simulator's filters (workbench/sim/filters.py) give scipy.signal's numbers bit for bit, without importing it."""

import subprocess
import sys

import numpy as np
import pytest
from scipy.signal import lfilter, sosfilt

from workbench.sim import filters
from workbench.sim.noise import flicker_design


@pytest.fixture(params=["kernel", "public"])
def path(request, monkeypatch):
    """Both ways: scipy.signal's compiled kernels loaded on their own, and the public functions."""
    if request.param == "public":
        monkeypatch.setattr(filters, "_kernel", lambda module, name: None)
    return request.param


def test_sosfilt_rows_equals_sosfilt_chunk_by_chunk(path):
    sos = flicker_design(0.01)[0].copy()  # the bias-instability cascade at 100 Hz
    rng = np.random.default_rng(3)
    x = rng.standard_normal((4, 5000))
    whole = sosfilt(sos, x, axis=-1)
    y, zi = x.copy(), np.zeros((4, sos.shape[0], 2))
    for a in range(0, 5000, 1234):  # the state carries over from chunk to chunk
        chunk = np.ascontiguousarray(y[:, a:a + 1234])
        filters.sosfilt_rows(sos, chunk, zi)
        y[:, a:a + 1234] = chunk
    assert np.array_equal(y, whole)
    _, zf = sosfilt(sos, x, axis=-1, zi=np.zeros((sos.shape[0], 4, 2)))
    assert np.array_equal(zi, zf.transpose(1, 0, 2))


def test_first_order_lag_equals_lfilter(path):
    alpha = float(np.exp(-0.01 / 600.0))  # 100 Hz, 600 s time constant
    air = np.minimum(23.0 + 0.01 * np.arange(20000), 60.0)
    expected, _ = lfilter([1 - alpha], [1, -alpha], air, zi=[alpha * 21.5])
    assert np.array_equal(filters.first_order_lag(air, alpha, 21.5), expected)


def test_the_simulated_rig_does_not_import_scipy_signal():
    code = ("import sys, numpy as np; from workbench.jobs import simulate; from workbench.sequence import Hold, Sequence; "
            "simulate(Sequence('s', [Hold('z-down', dwell_s=2.0)]), 'industrial_mems', 1); "
            "print('scipy.signal' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
