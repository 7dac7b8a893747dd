"""Sampling instants from arrival stamps against the true instants of the virtual lab's bursty host."""

import numpy as np
import pytest

from workbench.errors import ImportProfileError
from workbench.importers.clock import fit_arrival_clock
from workbench.sim.arrival import arrival_stamps

RATE = 100.0
T = 1.0 / RATE


def _recording(seed: int, drop: tuple[tuple[int, int], ...] = ((1000, 1030), (3000, 3100))):
    """True instants of 60 s at 100 Hz on a clock 50 ppm fast with a 200 ppm slow wander, minus lost stretches."""
    k = np.arange(6000)
    t = 5.0 + k * T * (1 + 50e-6) * (1 + 200e-6 * np.sin(k / 6000 * 3))
    keep = np.ones(len(k), bool)
    for a, b in drop:
        keep[a:b] = False
    return t[keep], arrival_stamps(t[keep], seed)


@pytest.mark.parametrize("seed", range(6))
def test_instants_and_gaps_match_the_true_sampling(seed):
    t, a = _recording(seed)
    assert np.diff(a).max() > 0.2 and np.median(np.diff(a)) < 1e-3  # bursts, pauses of 40-250 ms
    fit = fit_arrival_clock(a, RATE, "imu")
    assert [g[0] for g in fit.gaps] == [1000, 2970]
    # the envelope rests on the newest sample of a burst, late by the transport (2 ms), the poll
    # phase (uniform in 0..T) and 0.1 ms per sample ahead of it in the burst (up to 2.5 ms for a
    # 250-ms poll); the side lines of a loss take the least-late of ~30 bursts in 5 s (its excess
    # ~T/30 + ~1 ms), far under the T/2 that would miscount, so the lost counts are exact; the
    # envelope between its supports is off by at most their excess: every instant within T/2 of
    # the truth after the common offset (the smallest latency, which no stamp can show)
    assert fit.gaps[0][1] == 30 and fit.gaps[1][1] == 100
    err = fit.instants - t
    offset = np.median(err)
    assert 0.0 < offset < 0.002 + T  # transport + poll phase: never earlier than the truth
    assert np.abs(err - offset).max() < T / 2
    assert np.all(fit.latency >= -1e-12)
    assert fit.rate_hz == pytest.approx(RATE * (1 + 50e-6), rel=5e-4)


def test_no_gap_found_in_a_recording_without_losses():
    t, a = _recording(0, drop=())
    fit = fit_arrival_clock(a, None, "imu")  # no nominal rate: the stamps' mean rate starts the fit
    assert fit.gaps == ()
    assert np.abs(fit.instants - t - np.median(fit.instants - t)).max() < T / 4


def test_stamps_going_back_in_time_are_refused():
    a = np.array([0.0, 0.01, 0.02, 0.015, 0.03])
    with pytest.raises(ImportProfileError, match=r"imu: arrival stamps go back in time at row 3 \(0.015 s; row 2: 0.02 s\)"):
        fit_arrival_clock(a, RATE, "imu")
