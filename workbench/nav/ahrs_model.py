"""The AHRS filters' shared parts: options, result, mechanisation and measurement model (:mod:`workbench.nav.ahrs`).

:class:`AhrsConfig` (options, SI), :class:`AhrsResult` (the output at the update epochs),
:func:`initial_attitude` / :func:`initial_state` (levelling and tilt-compensated compass over the
first samples), :func:`mag_white_noise`, the update :class:`Block` and its tilt and heading
innovations (:func:`measure`), the field check for magnetic disturbances (:func:`field_gate`),
the residual sensor errors' 1-sigma (:func:`residual_sigma`) and :func:`run_blocks`, the loop both
filters share (propagate a block, measure, check the field, let the filter correct). The
equations and frames are in :mod:`workbench.nav.ahrs`'s docstring (paper 004 sec. 4.1.1, 5).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from workbench.angles import wrap_pi
from workbench.earth import earth_rate_ned
from workbench.errors import AnalysisError
from workbench.json_values import json_value
from workbench.nav.compensate import ImuSamples
from workbench.nav.strapdown import BlockPropagator, coarse_level, euler_rph, from_rph, with_previous


@dataclass(frozen=True)
class AhrsConfig:
    """Options of the AHRS filters (SI).

    ``update_interval_s`` measurement/correction period; ``declination`` rad (magnetic north
    east of true north); ``tau_tilt_s``, ``tau_heading_s`` time constants of the complementary
    loops; ``gyro_bias_prior`` 1-sigma rad/s of the Kalman filter's initial bias; the noise
    floors (rad) are added in quadrature to the white measurement noise derived from the sensors
    (vibration, unmodelled errors); ``init_s`` data used for the initial attitude.

    Magnetic-disturbance rejection (module docstring): ``mag_rejection`` switches it on;
    ``mag_reference_norm_ut`` µT and ``mag_reference_dip`` rad (None: from the first ``init_s``);
    ``mag_gate_sigma`` the detection threshold in sigmas; ``mag_norm_floor_ut`` µT and
    ``mag_dip_floor`` rad the floors of the expected norm and dip scatter (local gradients, tilt
    errors); ``c0``, ``c1`` the heading gate (paper 001 eq. 47); ``mag_reject_max_s`` s.

    The calibration errors left in the aiding sensors' samples (e.g. a calibration set's
    1-sigma), body frame, per element, scalars broadcast: ``accel_bias_error`` (3,) m/s^2,
    ``accel_scale_error`` (3, 3) dimensionless (of ``M``), ``mag_bias_error_ut`` (3,) µT (hard
    iron), ``mag_scale_error`` (3, 3) (soft iron). They are constant errors, not white noise:
    the Kalman filter carries them as coloured measurement noise (see :func:`kalman`).
    """

    update_interval_s: float = 0.1
    declination: float = 0.0
    tau_tilt_s: float = 5.0
    tau_heading_s: float = 20.0
    gyro_bias_prior: float = np.radians(1.0)
    tilt_noise_floor: float = np.radians(0.01)
    heading_noise_floor: float = np.radians(0.05)
    accel_bias_error: float | np.ndarray = 0.0
    accel_scale_error: float | np.ndarray = 0.0
    mag_bias_error_ut: float | np.ndarray = 0.0
    mag_scale_error: float | np.ndarray = 0.0
    init_s: float = 1.0
    mag_rejection: bool = True
    mag_reference_norm_ut: float | None = None
    mag_reference_dip: float | None = None
    mag_gate_sigma: float = 5.0
    mag_norm_floor_ut: float = 0.3
    mag_dip_floor: float = np.radians(0.3)
    c0: float = 3.0
    c1: float = 6.0
    mag_reject_max_s: float = 30.0


@dataclass(frozen=True)
class AhrsResult:
    """AHRS output at the E update epochs.

    ``t`` (E,) s; ``attitude`` Rotation (E,) body-to-NED; ``rph`` (E, 3) roll, pitch, heading
    rad; ``attitude_sigma`` (E, 3) 1-sigma of the attitude error about north, east, down, rad
    (NaN for the complementary filter, which has none);
    ``gyro_bias``, ``gyro_bias_sigma`` (E, 3) rad/s body frame; ``filter`` its name;
    ``mag_weight`` (E,) the weight the heading measurement got (1 full, 0 refused);
    ``mag_disturbed`` (E,) bool, the field's norm or dip off the reference (module docstring);
    ``mag_reference`` (norm µT, dip rad) the reference used.
    """

    t: np.ndarray
    attitude: Rotation
    rph: np.ndarray
    attitude_sigma: np.ndarray
    gyro_bias: np.ndarray
    gyro_bias_sigma: np.ndarray
    filter: str
    mag_weight: np.ndarray
    mag_disturbed: np.ndarray
    mag_reference: tuple[float, float]
    warnings: tuple[str, ...] = ()

    def to_dict(self) -> dict:
        """The end state, JSON-ready (SI; NaN -> None): time, roll/pitch/heading and their sigmas (rad),
        gyro bias and sigma (rad/s), the field reference (µT, rad) and the disturbed intervals (s)."""
        return {"filter": self.filter, "t_end": float(self.t[-1]), "rph": json_value(self.rph[-1]),
                "attitude_sigma": json_value(self.attitude_sigma[-1]), "gyro_bias": json_value(self.gyro_bias[-1]),
                "gyro_bias_sigma": json_value(self.gyro_bias_sigma[-1]), "mag_reference": json_value(self.mag_reference),
                "mag_disturbances": [list(iv) for iv in self.disturbed_intervals()], "warnings": list(self.warnings)}

    def summary(self) -> list[str]:
        """Lines for people: the end attitude (°) with its 1-sigma, the gyro bias (°/h), the disturbed time (s)."""
        from workbench import units

        def angles(v, s):
            sig = "" if not np.isfinite(s).any() else " ± " + ", ".join(f"{x:.2g}" for x in np.degrees(s))
            return ", ".join(f"{x:.3f}" for x in np.degrees(v)) + sig + " °"

        dt = float(np.median(np.diff(self.t))) if len(self.t) > 1 else 0.0
        return [f"{self.filter}: roll, pitch, heading at {self.t[-1]:.1f} s: "
                f"{angles(self.rph[-1], self.attitude_sigma[-1])}",
                f"{self.filter}: gyro bias " + ", ".join(
                    f"{a} {units.show('gyro', 'bias', b, s if np.isfinite(s) else None)}"
                    for a, b, s in zip("xyz", self.gyro_bias[-1], self.gyro_bias_sigma[-1])),
                f"{self.filter}: field disturbed {dt * int(np.sum(self.mag_disturbed)):.1f} s "
                f"in {len(self.disturbed_intervals())} interval(s)"]

    def disturbed_intervals(self) -> list[tuple[float, float]]:
        """(start, end) s of the runs of update epochs whose field was detected as disturbed."""
        d = np.concatenate([[False], self.mag_disturbed, [False]]).astype(int)
        starts, ends = np.nonzero(np.diff(d) == 1)[0], np.nonzero(np.diff(d) == -1)[0] - 1
        return [(float(self.t[a]), float(self.t[b])) for a, b in zip(starts, ends)]


def mag_white_noise(mag: np.ndarray) -> np.ndarray:
    """Per-axis white-noise 1-sigma (3,) µT of magnetometer samples (N, 3).

    From second differences, which cancel the field's slow change under table rotation:
    ``var(m[k+1] - 2 m[k] + m[k-1]) = 6 sigma^2`` for white noise. The set's noise block has no
    magnetometer terms, so the AHRS takes this figure from the data.
    """
    d2 = np.diff(np.asarray(mag, float), n=2, axis=0)
    return np.std(d2, axis=0) / np.sqrt(6.0)


def initial_attitude(samples: ImuSamples, declination: float, n: int) -> np.ndarray:
    """Body-to-NED DCM (3, 3) one sample before the first (where the filters start), from the first ``n``.

    Roll and pitch from accelerometer levelling, heading from the tilt-compensated magnetometer.

    The accelerometer and magnetometer samples are rotated into the first sample's body frame
    with the integrated gyros before averaging, so the unit may already be turning.
    """
    return initial_state(samples, declination, n)[0]


def initial_state(samples: ImuSamples, declination: float, n: int) -> tuple[np.ndarray, float, float]:
    """:func:`initial_attitude` and the field's norm (µT) and dip (rad, down positive) over the first ``n``."""
    rel = BlockPropagator(n, samples.dt, np.zeros(3)).propagate(np.eye(3), with_previous(samples.gyro, 0, n))
    f0, m0 = np.einsum("nij,knj->ki", rel, np.stack([samples.accel[:n], samples.mag[:n]])) / n
    roll, pitch = coarse_level(f0)
    m_level = from_rph(roll, pitch, 0.0).apply(m0)
    heading = declination - np.arctan2(m_level[1], m_level[0])
    dip = float(np.arctan2(m_level[2], np.hypot(m_level[0], m_level[1])))
    return from_rph(roll, pitch, heading).as_matrix(), float(np.linalg.norm(m0)), dip


@dataclass(frozen=True)
class Block:
    """One update block: DCMs ``att`` (n, 3, 3) and their mean ``c_mean``; ``rate`` (3,) rad/s the
    mean bias-corrected body rate, ``turn`` rad the angle turned w.r.t. NED over the block;
    ``outer`` (2, 3, 3, 3) = ``mean_k C_k[:, i] x_k[j]`` for x = accelerometer, magnetometer (body);
    the NED means ``f = mean_k C_k f_k``, ``m = mean_k C_k m_k`` (its diagonal sums), ``|f|``, ``|m_h|``."""

    att: np.ndarray
    c_mean: np.ndarray
    rate: np.ndarray
    turn: float
    outer: np.ndarray
    f: np.ndarray
    m: np.ndarray
    fn: float
    mh: float


def measure(blk: Block, declination: float) -> np.ndarray:
    """Tilt and heading innovations (3,) ~ (dtheta_N, dtheta_E, -dtheta_D) of a block."""
    f, m = blk.f, blk.m
    psi = np.arctan2(m[1], m[0]) - declination
    return np.array([-f[1] / blk.fn, f[0] / blk.fn, wrap_pi(psi)])


def block_sizes(samples: ImuSamples, config: AhrsConfig) -> tuple[int, int]:
    """(samples per update block, samples of the initial attitude); AnalysisError naming the source
    when the magnetometer is missing or the record is too short."""
    if samples.mag is None:
        raise AnalysisError(f"{samples.source}: the AHRS needs magnetometer columns mx, my, mz")
    n_blk = max(1, int(round(config.update_interval_s / samples.dt)))
    n_init = max(1, int(round(config.init_s / samples.dt)))
    if len(samples) < n_init + 2 * n_blk:
        raise AnalysisError(f"{samples.source}: {len(samples)} samples are too few for the AHRS")
    return n_blk, n_init


def field_gate(config: AhrsConfig, sig_m: float, n_blk: int, ref_norm: float):
    """``disturbed(blk) -> bool``: the block's field norm or dip beyond ``mag_gate_sigma`` of the reference's.

    Expected 1-sigma of a block's norm (µT): the white noise of the block mean, the residual hard
    iron (rms per axis) and soft iron (rms per element times the field) of ``config``, and the
    floor; of its dip: the same over the field magnitude, and the dip floor.
    """
    res = residual_sigma(config)
    s_mag = np.sqrt(sig_m ** 2 / n_blk + np.mean(res[12:15] ** 2) + np.mean(res[15:] ** 2) * ref_norm ** 2)
    lim_norm = config.mag_gate_sigma * np.hypot(s_mag, config.mag_norm_floor_ut)
    lim_dip = config.mag_gate_sigma * np.hypot(s_mag / ref_norm, config.mag_dip_floor)

    def disturbed(blk: Block, ref_dip: float) -> bool:
        if not config.mag_rejection:
            return False
        dip = np.arctan2(blk.m[2], blk.mh)
        return bool(abs(np.linalg.norm(blk.m) - ref_norm) > lim_norm or abs(dip - ref_dip) > lim_dip)

    return disturbed


def run_blocks(samples: ImuSamples, latitude: float, config: AhrsConfig, correct, name: str,
         sig_m: float) -> AhrsResult:
    """Shared loop: propagate each block, measure, check the field (``sig_m`` µT white noise per axis),
    let ``correct(z, block, disturbed)`` return (dtheta, db, sigmas, heading weight)."""
    n_blk, n_init = block_sizes(samples, config)
    w_ie = earth_rate_ned(latitude)
    prop = BlockPropagator(n_blk, samples.dt, w_ie)
    c, norm0, dip0 = initial_state(samples, config.declination, n_init)
    ref = (norm0 if config.mag_reference_norm_ut is None else float(config.mag_reference_norm_ut),
           dip0 if config.mag_reference_dip is None else float(config.mag_reference_dip))
    disturbed = field_gate(config, sig_m, n_blk, ref[0])
    bg = np.zeros(3)
    dtheta = np.zeros(3)
    out_t, out_c, out_d, out_b, out_s, out_w, out_x = [], [], [], [], [], [], []
    for i0 in range(0, len(samples) - n_blk + 1, n_blk):
        rates = with_previous(samples.gyro, i0, i0 + n_blk) - bg
        att = prop.propagate(c, rates, dtheta)
        outer = np.einsum("kai,skj->saij", att, np.stack([samples.accel[i0:i0 + n_blk],
                                                          samples.mag[i0:i0 + n_blk]])) / n_blk
        f, m = np.einsum("saii->sa", outer)
        c_mean = att.mean(axis=0)
        rate = rates[1:].mean(axis=0)
        blk = Block(att, c_mean, rate, float(np.linalg.norm(rate - c_mean.T @ w_ie)) * n_blk * samples.dt,
                     outer, f, m, float(np.linalg.norm(f)), float(np.hypot(m[0], m[1])))
        dist = disturbed(blk, ref[1])
        dtheta, dbg, sig, weight = correct(measure(blk, config.declination), blk, dist)
        c = att[-1]  # dtheta is applied at the start of the next block
        bg = bg + dbg
        out_t.append(samples.t[i0 + n_blk - 1])
        out_c.append(c)
        out_d.append(dtheta)
        out_b.append(bg.copy())
        out_s.append(sig)
        out_w.append(weight)
        out_x.append(dist)
    attitude = Rotation.from_rotvec(np.array(out_d)) * Rotation.from_matrix(np.array(out_c))
    sig = np.array(out_s)
    return AhrsResult(np.array(out_t), attitude, euler_rph(attitude), sig[:, :3], np.array(out_b), sig[:, 3:], name,
                      np.array(out_w, float), np.array(out_x, bool), ref)


def residual_sigma(config: AhrsConfig) -> np.ndarray:
    """1-sigma (24,) of the residual sensor errors ``[db_a, vec dM_a, db_m, vec dM_m]`` (row-major ``M``)."""
    return np.concatenate([np.broadcast_to(np.asarray(v, float), shape).ravel() for v, shape in (
        (config.accel_bias_error, (3,)), (config.accel_scale_error, (3, 3)),
        (config.mag_bias_error_ut, (3,)), (config.mag_scale_error, (3, 3)))])
