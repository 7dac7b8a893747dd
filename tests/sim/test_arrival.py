"""The simulated host's arrival stamps: latencies, bursts and pauses as the model states."""

import numpy as np

from workbench.sim.arrival import arrival_stamps


def test_latency_bursts_and_pauses():
    t = np.arange(20000) / 100.0
    a = arrival_stamps(t, 3, poll_min_s=0.04, poll_max_s=0.25, transport_s=0.002, spacing_s=1e-4)
    lat = a - t
    assert lat.min() >= 0.002 - 1e-12  # a sample is never received before it is ready
    # the newest sample of a poll waited at most one poll interval after being ready
    assert lat.max() <= 0.25 + 0.002 + 30 * 1e-4
    assert np.all(np.diff(a) > 0)  # one after the other, never reordered
    pause = np.diff(a) > 0.01
    gaps = np.diff(a)[pause]
    assert 0.03 < gaps.min() and gaps.max() < 0.25 + 0.01  # bursts 40-250 ms apart (less the burst length)
    assert np.allclose(np.diff(a)[~pause], 1e-4)  # inside a burst: the transfer spacing
    # the same seed gives the same stamps
    assert np.array_equal(a, arrival_stamps(t, 3))
