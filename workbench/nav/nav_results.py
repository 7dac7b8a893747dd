"""The result protocol (:mod:`workbench.result`) of the navigation filters' results, written once.

``to_dict`` / ``summary`` bodies of :class:`~workbench.nav.lns.LnsResult`,
:class:`~workbench.nav.zupt.ZuptResult` and :class:`~workbench.nav.land_ins.LandInsResult`
(their methods call these): the end state of the run, ``to_dict`` in SI (rad, m, m/s, rad/s,
m/s²; a scale factor as a fraction, NaN -> None), ``summary`` in lab units (°, m, mm/s, °/h,
mg, mrad, %) through :mod:`workbench.units`.
"""

from __future__ import annotations

import numpy as np

from workbench import units
from workbench.json_values import json_value
from workbench.nav.land_ins_model import A_, BA, BG, BW, LA, P_, SA, SG, V_

_AXES = "xyz"


def _angles(v_rad, s_rad=None) -> str:
    """Angles (rad) as ``'1.000, 2.000, 3.000 ± 0.01, 0.01, 0.1 °'`` (the sigma part only where finite)."""
    text = ", ".join(f"{x:.3f}" for x in units.to_unit(np.asarray(v_rad, float), "deg"))
    if s_rad is not None and np.isfinite(s_rad).any():
        text += " ± " + ", ".join(f"{x:.2g}" for x in units.to_unit(np.asarray(s_rad, float), "deg"))
    return text + " °"


def _triad(triad: str, values, sigmas) -> str:
    """A body-frame triad's bias per axis in its lab unit with its 1-sigma: ``'x 1.2 ± 0.1 °/h, y ...'``."""
    return ", ".join(f"{a} {units.show(triad, 'bias', v, s)}" for a, v, s in zip(_AXES, values, sigmas))


def _position_line(name: str, t: float, lat: float, lon: float, h: float) -> str:
    """``'<name> at T s: lat ..°, lon ..°, h .. m'``."""
    return (f"{name} at {t:.1f} s: lat {units.to_unit(lat, 'deg'):.6f}°, lon {units.to_unit(lon, 'deg'):.6f}°, "
            f"h {h:.1f} m")


def lns_dict(r) -> dict:
    """End state of an :class:`~workbench.nav.lns.LnsResult`, SI; ``sigma`` keyed by state."""
    s = r.sigma[-1]
    return {"t_end": float(r.t[-1]), "lat": float(r.lat[-1]), "lon": float(r.lon[-1]), "h": float(r.h[-1]),
            "heading": float(r.heading[-1]), "pitch": float(r.pitch[-1]), "speed": float(r.speed[-1]),
            "odo_scale": json_value(r.odo_scale[-1]), "gyro_bias": json_value(r.gyro_bias[-1]),
            "sigma": {"d_n": json_value(s[0]), "d_e": json_value(s[1]), "odo_scale": json_value(s[2]),
                      "heading": json_value(s[3]), "gyro_bias": json_value(s[4])},
            "gps_steps": int(np.sum(r.gps_used)), "steps": len(r.t),
            "resets": [float(x) for x in r.resets], "t_heading": json_value(r.t_heading),
            "warnings": list(r.warnings)}


def lns_summary(r) -> list[str]:
    """Lines: end position; heading, pitch (°) and speed; odometer scale-factor error (%) and gyro z bias (°/h);
    position 1-sigma (m) and GPS use."""
    s = r.sigma[-1]
    sf = ("not estimated" if not np.isfinite(r.odo_scale[-1]) else
          f"{units.to_unit(r.odo_scale[-1], '%'):+.3f} ± {units.to_unit(s[2], '%'):.2g} %")
    return [_position_line("LNS", r.t[-1], r.lat[-1], r.lon[-1], r.h[-1]),
            f"LNS: heading {units.to_unit(r.heading[-1], 'deg'):.3f} ± {units.to_unit(s[3], 'deg'):.2g} °, "
            f"pitch {units.to_unit(r.pitch[-1], 'deg'):.3f} °, speed {r.speed[-1]:.2f} m/s",
            f"LNS: odometer scale-factor error {sf}, gyro z bias {units.show('gyro', 'bias', r.gyro_bias[-1], s[4])}",
            f"LNS: position 1-sigma N {s[0]:.1f} m, E {s[1]:.1f} m; GPS used in {int(np.sum(r.gps_used))} of "
            f"{len(r.t)} steps; {len(r.resets)} heading reset(s)"]


def zupt_dict(r) -> dict:
    """End state of a :class:`~workbench.nav.zupt.ZuptResult`, SI; ``convergence_time`` s from the EKF start
    (None = never)."""
    return {"t_start": float(r.t_start), "t_end": float(r.t[-1]), "rph": json_value(r.rph[-1]),
            "attitude_sigma": json_value(r.attitude_sigma[-1]), "initial_rph": json_value(r.initial_rph),
            "level_sigma": json_value(r.level_sigma), "tilt_observed": r.tilt_observed,
            "position": json_value(r.position[-1]), "velocity": json_value(r.velocity[-1]),
            "accel_bias": json_value(r.accel_bias[-1]), "accel_bias_sigma": json_value(r.accel_bias_sigma[-1]),
            "gyro_bias": json_value(r.gyro_bias[-1]), "gyro_bias_sigma": json_value(r.gyro_bias_sigma[-1]),
            "measurements": list(r.measurements), "drift_noise": json_value(r.drift_noise),
            "convergence_time": r.convergence_time(), "warnings": list(r.warnings)}


def zupt_summary(r) -> list[str]:
    """Lines: end attitude (°) with its 1-sigma; |v_NED| (mm/s) and convergence (s); gyro (°/h) and
    accelerometer (mg) bias with their 1-sigma."""
    conv = r.convergence_time()
    return [f"ZUPT: roll, pitch, heading at {r.t[-1]:.1f} s: {_angles(r.rph[-1], r.attitude_sigma[-1])}",
            f"ZUPT: |v_NED| {units.to_unit(float(np.linalg.norm(r.velocity[-1])), 'mm/s'):.2f} mm/s, converged "
            + ("never" if conv is None else f"after {conv:.0f} s"),
            "ZUPT: gyro bias " + _triad("gyro", r.gyro_bias[-1], r.gyro_bias_sigma[-1]),
            "ZUPT: accel bias " + _triad("accel", r.accel_bias[-1], r.accel_bias_sigma[-1])]


def land_ins_dict(r) -> dict:
    """End state of a :class:`~workbench.nav.land_ins.LandInsResult`, SI, each estimate with its 1-sigma
    (None for a state the filter lacks); ``modes`` the fraction of steps per update mode."""
    s = r.sigma[-1]
    b_g, b_a = _bias_sigmas(r)
    out = {"t_end": float(r.t[-1]), "lat": float(r.lat[-1]), "lon": float(r.lon[-1]), "h": float(r.h[-1]),
           "position_sigma": json_value(s[P_]), "v_ned": json_value(r.v_ned[-1]), "v_ned_sigma": json_value(s[V_]),
           "rph": json_value(r.rph[-1]), "attitude_sigma": json_value(s[A_]),
           "accel_bias": json_value(r.accel_bias[-1]), "accel_bias_sigma": json_value(b_a),
           "gyro_bias": json_value(r.gyro_bias[-1]), "gyro_bias_sigma": json_value(b_g),
           "boresight": json_value(r.boresight[-1]), "boresight_sigma": json_value(s[BW]),
           "lever_arm": json_value(r.lever_arm[-1]), "lever_arm_sigma": json_value(s[LA]),
           "modes": {m: float(np.mean(r.mode == m)) for m in sorted(set(r.mode.tolist()))},
           "warnings": list(r.warnings)}
    for key, arr, sl in (("gyro_scale", r.gyro_scale, SG), ("accel_scale", r.accel_scale, SA)):
        if arr is not None and np.isfinite(s[sl]).any():
            out[key], out[key + "_sigma"] = json_value(arr[-1]), json_value(s[sl])
    return out


def _bias_sigmas(r) -> tuple[np.ndarray, np.ndarray]:
    """End 1-sigma of a land-INS result's gyro and accel bias (with the Gauss-Markov part where there is one)."""
    if r.bias_sigma is None:
        return r.sigma[-1][BG], r.sigma[-1][BA]
    return r.bias_sigma[-1, :3], r.bias_sigma[-1, 3:]


def land_ins_summary(r) -> list[str]:
    """Lines: end position with its horizontal 1-sigma (m); velocity (m/s); attitude (°) with its 1-sigma;
    gyro (°/h) and accelerometer (mg) bias; boresight (mrad) and lever arm (m); the update modes (%)."""
    s = r.sigma[-1]
    b_g, b_a = _bias_sigmas(r)
    modes = ", ".join(f"{m.upper() if m in ('zupt', 'nhc') else m} "
                      f"{units.to_unit(float(np.mean(r.mode == m)), '%'):.0f} %" for m in sorted(set(r.mode.tolist())))
    return [_position_line("land INS", r.t[-1], r.lat[-1], r.lon[-1], r.h[-1])
            + f" (1-sigma N {s[P_][0]:.1f} m, E {s[P_][1]:.1f} m)",
            "land INS: v_NED " + ", ".join(f"{v:+.3f}" for v in r.v_ned[-1]) + " m/s",
            f"land INS: roll, pitch, heading {_angles(r.rph[-1], s[A_])}",
            "land INS: gyro bias " + _triad("gyro", r.gyro_bias[-1], b_g),
            "land INS: accel bias " + _triad("accel", r.accel_bias[-1], b_a),
            "land INS: boresight pitch, yaw " + ", ".join(
                units.pm(v, q, "mrad", 3) for v, q in zip(r.boresight[-1], s[BW])) + ", lever arm "
            + ", ".join(f"{v:+.3f}" for v in r.lever_arm[-1]) + " m",
            f"land INS: steps {modes}"]
