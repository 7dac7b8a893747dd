"""Roads of the seed experiments, as leg lists for :func:`workbench.sim.vehicle.drive_config`.

* :func:`thesis_drive`: a drive like the thesis' PC simulation (shared/seeds/000_... sec. 2.4.2,
  Fig. 2.15-2.20): a rest for the initialisation, ~50 minutes of mixed road (straights of
  150-1500 m at 8-18 m/s, turns of 45-100° at 6-10 °/s that keep the road heading
  within ~±100° of its start direction, short stops, gentle slopes), a five-minute
  stop near 3000 s (where the odometer scale factor steps by +4 %), then ~50 more minutes; the
  GPS is lost a few minutes after the restart (``GPS_LOSS_S``), leaving ~28 km in ~45 min.
  The thesis does not give its road (it replays a van test): this one is drawn from a seed.
* :func:`constant_rate_drive`: paper 001 (shared/seeds/001_...) sec. 4.2: the pre-calibration
  profile (stop after each 90° heading change until back at the start azimuth) and a one-hour
  cruise at constant speed and constant heading rate.

Public: ``THESIS_STOP_S``, ``THESIS_GPS_LOSS_S``, :func:`thesis_drive`, :func:`precalibration_legs`,
:func:`constant_rate_drive`, :func:`leg_duration`.
"""

from __future__ import annotations

import numpy as np

THESIS_STOP_S = 3000.0  # the five-minute stop (wheel deflation) starts here
THESIS_STOP_DURATION_S = 300.0
THESIS_GPS_LOSS_S = 3600.0  # "after few minutes" from the restart near 3300-3400 s
THESIS_END_S = THESIS_GPS_LOSS_S + 2700.0  # 45 minutes without GPS


def _random_legs(rng: np.random.Generator, duration_s: float) -> list[dict]:
    """Mixed road legs of about ``duration_s`` s (straights, turns, occasional short stops)."""
    legs: list[dict] = []
    total = 0.0
    heading = float(rng.uniform(-30.0, 30.0))  # deg, relative to the start direction
    while total < duration_s:
        speed = float(rng.uniform(8.0, 18.0))
        length = float(rng.uniform(150.0, 1500.0))
        legs.append({"kind": "straight", "length_m": length, "speed_mps": speed,
                     "slope_deg": float(np.round(rng.normal(0.0, 1.5), 1))})
        total += length / speed
        # turn back towards the drive's general direction: a road that gets somewhere (the van
        # tests' displacement is close to their distance), not a random walk
        angle = float(-np.sign(heading + 1e-9) * rng.uniform(45.0, 100.0))
        heading += angle
        rate = float(rng.uniform(6.0, 10.0))
        turn_speed = min(speed, 9.0)
        legs.append({"kind": "straight", "duration_s": 10.0, "speed_mps": turn_speed, "label": "slow down"})
        legs.append({"kind": "turn", "angle_deg": angle, "rate_dps": rate, "speed_mps": turn_speed})
        total += 10.0 + abs(angle) / rate
        if rng.uniform() < 0.08:
            legs.append({"kind": "stop", "duration_s": float(rng.uniform(15.0, 40.0))})
            total += legs[-1]["duration_s"]
    return legs


def _pad_to(legs: list[dict], until_s: float) -> list[dict]:
    """Stretch the last straight so the legs last until ``until_s`` s (approximately: legs are
    timed at their target speeds)."""
    total = sum(leg_duration(leg) for leg in legs)
    for leg in reversed(legs):
        if leg["kind"] == "straight" and "length_m" in leg:
            leg["length_m"] = max(50.0, leg["length_m"] + (until_s - total) * leg["speed_mps"])
            break
    return legs


def leg_duration(leg: dict) -> float:
    """Duration (s) of one road leg (lab units) at its target speed and rate."""
    if "duration_s" in leg:
        return leg["duration_s"]
    if leg["kind"] == "straight":
        return leg["length_m"] / leg["speed_mps"]
    if leg["kind"] == "turn":
        return abs(leg["angle_deg"]) / leg["rate_dps"]
    return leg["duration_s"]


def thesis_drive(seed: int = 1, rest_s: float = 120.0) -> tuple[list[dict], dict, dict]:
    """(road legs, odometer, gps) of the thesis-like drive (lab units, see the module docstring).

    The odometer reads true distance until the stop and +4 % from the end of it (the thesis'
    simulated wheel deflation); the GPS is lost at ``THESIS_GPS_LOSS_S`` (kept in the session:
    the procedure ignores it from ``gps_loss_s`` on and uses it as the reference, as the thesis).
    """
    rng = np.random.default_rng([seed, 2024])
    first = _pad_to(_random_legs(rng, THESIS_STOP_S - rest_s - 200.0), THESIS_STOP_S - rest_s - 20.0)
    second = _pad_to(_random_legs(rng, THESIS_END_S - THESIS_STOP_S - THESIS_STOP_DURATION_S - 200.0),
                     THESIS_END_S - THESIS_STOP_S - THESIS_STOP_DURATION_S - 20.0)
    road = ([{"kind": "stop", "duration_s": rest_s, "label": "initial rest"},
             {"kind": "straight", "length_m": 200.0, "speed_mps": 10.0, "label": "heading initialisation"}]
            + first + [{"kind": "stop", "duration_s": THESIS_STOP_DURATION_S, "label": "wheel deflation"}] + second
            + [{"kind": "stop", "duration_s": 20.0, "label": "end"}])
    t_restart = rest_s + 20.0 + sum(leg_duration(leg) for leg in first) + THESIS_STOP_DURATION_S - 5.0
    odometer = {"scale_steps": [[t_restart, 4.0]], "pulse_m": 0.01}
    gps = {"rate_hz": 1.0, "sigma_h_m": 2.0, "sigma_v_m": 4.0}
    return road, odometer, gps


def precalibration_legs(speed_mps: float = 5.0, rate_dps: float = 10.0, stop_s: float = 120.0,
                        first_rest_s: float = 300.0) -> list[dict]:
    """Paper 001 pre-calibration: rest, then four 90° heading changes with a stop after each,
    back at the start azimuth (ZUPT/ZARUPT at each stop)."""
    legs = [{"kind": "stop", "duration_s": first_rest_s, "label": "alignment"}]
    for i in range(4):
        legs += [{"kind": "straight", "duration_s": 10.0, "speed_mps": speed_mps},
                 {"kind": "turn", "angle_deg": 90.0, "rate_dps": rate_dps, "speed_mps": speed_mps},
                 {"kind": "straight", "duration_s": 10.0, "speed_mps": 0.0},
                 {"kind": "stop", "duration_s": stop_s, "label": f"pre-calibration stop {i + 1}"}]
    return legs


def constant_rate_drive(rate_dps: float, speed_mps: float = 20.0, duration_s: float = 3600.0,
                        precalibration: bool = True) -> list[dict]:
    """Paper 001 sec. 4.2 trajectory: (pre-calibration and) one hour at constant speed and heading rate."""
    legs = precalibration_legs() if precalibration else [{"kind": "stop", "duration_s": 60.0}]
    legs.append({"kind": "straight", "duration_s": 30.0, "speed_mps": speed_mps, "label": "accelerate"})
    if rate_dps == 0:
        legs.append({"kind": "straight", "duration_s": duration_s, "speed_mps": speed_mps, "label": "cruise"})
    else:
        legs.append({"kind": "turn", "angle_deg": rate_dps * duration_s, "rate_dps": abs(rate_dps),
                     "speed_mps": speed_mps, "label": "cruise"})
    return legs
