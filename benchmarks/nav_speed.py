"""Speed (and accuracy) of the navigation filters on 10-minute 100 Hz sessions.

Target (issue 9): each filter processes a 10-minute 100 Hz session in under 10 s on one core.
Prints CPU time (``time.process_time``: not inflated by other processes on a shared machine)
and wall time per filter (the Kalman AHRS also as ``ahrs-table`` runs it, with the set's residual
errors as coloured measurement noise), then the raw/calibrated figures of the two validation
procedures, with the gyro-bias errors in sigmas of the filter (consistency).

Run: ``/work/venv/bin/python benchmarks/nav_speed.py``
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import procedures.ahrs_table as ahrs_table  # noqa: E402
import procedures.zupt_alignment as zupt_alignment  # noqa: E402
from tests.nav.conftest import calibration_from_truth  # noqa: E402
from workbench.grades import load_spec  # noqa: E402
from workbench.nav import ahrs, zupt  # noqa: E402
from workbench.nav.compensate import compensate, imu_samples, process_noise  # noqa: E402
from workbench.sequence import Hold, Sequence  # noqa: E402
from workbench.jobs import simulate  # noqa: E402


def timed(label: str, fn):
    c0, w0 = time.process_time(), time.perf_counter()
    out = fn()
    print(f"{label:<34s} CPU {time.process_time() - c0:6.2f} s   wall {time.perf_counter() - w0:6.2f} s")
    return out


def main() -> None:
    spec = load_spec("industrial_mems")
    static, truth = simulate(Sequence("static-10min", [Hold("z-down", dwell_s=600.0)]), spec, seed=1)
    cal = calibration_from_truth(truth)
    noise = process_noise(cal)
    lat = static.site.latitude
    s = compensate(imu_samples(static.samples, static.sample_rate_hz), cal, ("gyro", "accel"))
    s = s.slice(len(s) - 60000, len(s))
    print(f"samples: {len(s)} at {1 / s.dt:.0f} Hz")
    timed("ZUPT (pos, vel, heading)", lambda: zupt.align(s, noise, lat, 0.0))
    timed("ZUPT + ZARUPT", lambda: zupt.align(s, noise, lat, 0.0, config=zupt.ZuptConfig(
        measurements=("position", "velocity", "heading", "zarupt"))))
    moving, truth_m = simulate(ahrs_table.sequence(spec), spec, seed=2)
    cal_m = calibration_from_truth(truth_m)
    sm = compensate(imu_samples(moving.samples, moving.sample_rate_hz), cal_m)
    sm = sm.slice(0, 60000)
    timed("AHRS Kalman (10 Hz updates)", lambda: ahrs.kalman(sm, process_noise(cal_m), lat))
    (ab, am), (mb, mm), (_, gm) = (ahrs_table._residual(cal_m, tr, True) for tr in ("accel", "mag", "gyro"))
    resid = ahrs.AhrsConfig(accel_bias_error=ab, accel_scale_error=am, mag_bias_error_ut=mb, mag_scale_error=mm)
    timed("AHRS Kalman, the set's residuals", lambda: ahrs.kalman(sm, process_noise(cal_m), lat, resid,
                                                                 scale_sigma=float(np.sqrt(np.mean(gm ** 2)))))
    timed("AHRS complementary (10 Hz updates)", lambda: ahrs.complementary(sm, lat))

    print("\nahrs-table, default 10-minute sequence, industrial_mems seed 2:")
    res = ahrs_table.analyze(moving, calibration=cal_m)
    print("\n".join(res.summary))
    cons = load_spec("consumer_9axis")
    moving_c, truth_c = simulate(ahrs_table.sequence(cons), cons, seed=2)
    print("\nahrs-table, default 10-minute sequence, consumer_9axis seed 2:")
    print("\n".join(ahrs_table.analyze(moving_c, calibration=calibration_from_truth(truth_c)).summary))
    print("\nzupt-alignment, default positions, industrial_mems seed 3:")
    za, truth_z = simulate(zupt_alignment.sequence(spec, **zupt_alignment.DEFAULTS), spec, seed=3)
    res = zupt_alignment.analyze(za, calibration=calibration_from_truth(truth_z))
    print("\n".join(res.summary))
    for mode in ("raw", "calibrated"):
        for p in res.result[mode]["positions"]:
            err = np.array(p["gyro_bias_error"]) / np.hypot(p["gyro_bias_sigma"], p["gyro_bias_reference_sigma"])
            print(f"  {mode:<10s} {p['label']:<12s} roll/pitch at 60 s {p['roll_error_60s_deg']:+.4f}° "
                  f"{p['pitch_error_60s_deg']:+.4f}°, |v| {p['velocity_error_mps'] * 1e3:.2f} mm/s, "
                  f"gyro-bias error / sigma {np.round(err, 2)}")


if __name__ == "__main__":
    main()
