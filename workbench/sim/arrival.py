"""Host arrival time stamps of a simulated sensor stream: bursts, latency, transfer spacing.

A host that polls a buffered sensor at irregular intervals receives its samples in bursts:
every sample taken since the previous poll arrives at the next poll, one after the other.
:func:`arrival_stamps` models that: poll instants ``p_j`` with intervals drawn uniformly in
``[poll_min_s, poll_max_s]``; sample ``i`` taken at ``t_i`` arrives at the first poll after
``t_i + transport_s``, plus ``spacing_s`` per sample ahead of it in the same burst. Latencies
are then ``transport_s`` to about ``poll_max_s + transport_s``: bursts a few ms apart with tens
to hundreds of ms between them, as a USB/serial logger on a desktop host records.
"""

from __future__ import annotations

import numpy as np


def arrival_stamps(instants: np.ndarray, seed: int, poll_min_s: float = 0.04, poll_max_s: float = 0.25,
                   transport_s: float = 0.002, spacing_s: float = 1e-4) -> np.ndarray:
    """Arrival times (N,) s, host clock, of samples taken at ``instants`` (N,) s (increasing)."""
    t = np.asarray(instants, float)
    rng = np.random.default_rng(seed)
    span = t[-1] - t[0] + poll_max_s + transport_s
    n_polls = int(span / poll_min_s) + 2
    polls = t[0] + np.cumsum(rng.uniform(poll_min_s, poll_max_s, n_polls))
    j = np.searchsorted(polls, t + transport_s, side="left")  # first poll at or after the sample is ready
    # position inside the burst: samples before it in the same burst
    first = np.r_[0, np.flatnonzero(np.diff(j)) + 1]
    pos = np.arange(len(t)) - np.repeat(first, np.diff(np.r_[first, len(t)]))
    return polls[j] + pos * spacing_s
