"""Apply a calibration set to raw samples, and derive the filters' process noise from it.

Navigation filters use only :func:`compensate` to correct raw samples (nothing here or in the
filters re-implements the error model: it is :meth:`workbench.model.TriadModel.compensate`),
and :func:`process_noise` to turn the set's noise block (Allan-variance terms) into the
continuous-time noise densities of the filter's process noise, as thesis (shared/seeds/000_...)
eq. 3.50-3.53 asks: "the diagonal elements of Q shall be evaluated through an Allan Variance
analysis".

Public: :class:`ImuSamples`, :func:`imu_samples`, :func:`compensate`, :func:`check_calibration`,
:class:`ProcessNoise`, :func:`process_noise`, :func:`white_density`.

Units: SI throughout (rad/s, m/s^2, µT, °C, s); body frame x fwd, y right, z down.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import pandas as pd

from workbench.calset import CalibrationSet
from workbench.errors import AnalysisError, SessionError
from workbench.session import ACCEL, GYRO, MAG

_GAP_FACTOR = 1.5  # a sample interval longer than 1.5 nominal intervals is a gap


@dataclass(frozen=True)
class ImuSamples:
    """Uniformly sampled triad outputs, SI, body frame.

    ``t`` (N,) s; ``gyro`` (N, 3) rad/s; ``accel`` (N, 3) m/s^2 (specific force);
    ``mag`` (N, 3) µT or None; ``temperature_c`` (N,) °C or None; ``dt`` the sample interval, s;
    ``compensated`` names the triads a calibration set was applied to; ``source`` names the
    data in error messages.
    """

    t: np.ndarray
    gyro: np.ndarray
    accel: np.ndarray
    mag: np.ndarray | None
    temperature_c: np.ndarray | None
    dt: float
    compensated: tuple[str, ...] = ()
    source: str = "samples"

    def __len__(self) -> int:
        return len(self.t)

    def slice(self, start: int, stop: int) -> ImuSamples:
        """Samples ``start:stop`` (row indices)."""
        def cut(a):
            return None if a is None else a[start:stop]
        return replace(self, t=self.t[start:stop], gyro=self.gyro[start:stop], accel=self.accel[start:stop],
                       mag=cut(self.mag), temperature_c=cut(self.temperature_c))


def imu_samples(df: pd.DataFrame, sample_rate_hz: float, source: str = "samples") -> ImuSamples:
    """Raw samples from a session's samples table (columns ``t``, ``gx..gz``, ``ax..az``, [``mx..mz``, ``temp``]).

    Raises SessionError naming the time of the first gap (an interval over 1.5 nominal
    intervals) or the first non-finite value: the filters need uniform sampling.
    """
    if len(df) < 2:
        raise SessionError(f"{source}: fewer than 2 samples")
    t = df["t"].to_numpy(float)
    dt_nom = 1.0 / float(sample_rate_hz)
    d = np.diff(t)
    bad = (d > _GAP_FACTOR * dt_nom) | (d <= 0)
    if bad.any():
        i = int(np.argmax(bad))
        raise SessionError(f"{source}: column t: gap of {d[i]:.4g} s after t={t[i]:.3f} s "
                           f"(sample interval {dt_nom:.4g} s); the filters need gap-free samples")
    cols = {"gyro": GYRO, "accel": ACCEL, "mag": MAG}
    arrays = {}
    for name, c in cols.items():
        if not all(x in df.columns for x in c):
            if name == "mag":
                arrays[name] = None
                continue
            raise SessionError(f"{source}: missing column(s) {', '.join(x for x in c if x not in df.columns)}")
        a = df[c].to_numpy(float)
        if not np.all(np.isfinite(a)):
            row = int(np.argmax(~np.isfinite(a).all(axis=1)))
            raise SessionError(f"{source}: columns {', '.join(c)}: NaN or infinite value at t={t[row]:.3f} s")
        arrays[name] = a
    temp = df["temp"].to_numpy(float) if "temp" in df.columns else None
    return ImuSamples(t, arrays["gyro"], arrays["accel"], arrays["mag"], temp, dt_nom, (), source)


def check_calibration(calibration: CalibrationSet | None, unit_serial: str, triads: tuple[str, ...],
                      force: bool = False, procedure: str = "this procedure") -> list[str]:
    """Check that ``calibration`` fits a unit and a filter; returns warnings.

    Raises AnalysisError when there is no set (the message says to pass ``--calibration SET``),
    when the set belongs to another unit serial (unless ``force``, which turns it into a
    warning) or when it lacks one of ``triads``.
    """
    if calibration is None:
        raise AnalysisError(f"{procedure} compares raw and calibrated runs: pass --calibration SET "
                            "(a calibration set of the unit, from the store or a JSON file)")
    warnings: list[str] = []
    if calibration.unit.serial != unit_serial:
        msg = (f"calibration set {calibration.id} is for unit {calibration.unit.serial!r}, "
               f"the session's unit is {unit_serial!r}")
        if not force:
            raise AnalysisError(f"{msg}; pass force=True (--force) to use it anyway")
        warnings.append(msg + " (used because force=True)")
    missing = [tr for tr in triads if tr not in calibration.triads]
    if missing:
        raise AnalysisError(f"calibration set {calibration.id}: no {', '.join(missing)} triad "
                            f"(the filter needs {', '.join(triads)})")
    return warnings


def compensate(samples: ImuSamples, calibration: CalibrationSet,
               triads: tuple[str, ...] = ("gyro", "accel", "mag")) -> ImuSamples:
    """Apply ``calibration`` to raw ``samples``: bias, ``M``, nonlinearity, g-sensitivity, thermal terms.

    Each triad in ``triads`` is corrected with its :meth:`TriadModel.compensate`, the thermal
    terms evaluated at the ``temp`` column (°C). The accelerometer is compensated first; the
    gyro g-sensitivity then uses the *compensated* specific force. A triad absent from
    ``samples`` (no magnetometer columns) is skipped; a triad absent from the set raises
    AnalysisError, as does a thermal model without a ``temp`` column.
    """
    out: dict[str, np.ndarray | None] = {"gyro": samples.gyro, "accel": samples.accel, "mag": samples.mag}
    done = list(samples.compensated)
    for name in ("accel", "gyro", "mag"):  # accel first: the gyro g-sensitivity needs it
        if name not in triads or out[name] is None or name in done:
            continue
        if name not in calibration.triads:
            raise AnalysisError(f"calibration set {calibration.id}: no {name} triad to compensate {samples.source}")
        model = calibration.model(name)
        if model.thermal is not None and samples.temperature_c is None:
            raise AnalysisError(f"{samples.source}: no temp column, but the {name} calibration has thermal terms")
        force = out["accel"] if name == "gyro" else None
        out[name] = model.compensate(out[name], specific_force=force, temperature_c=samples.temperature_c)
        done.append(name)
    return replace(samples, gyro=out["gyro"], accel=out["accel"], mag=out["mag"], compensated=tuple(done))


@dataclass(frozen=True)
class ProcessNoise:
    """Continuous-time noise densities (per body axis, (3,) arrays) for the filters' Q.

    ``gyro_white`` rad/s/√Hz (= ARW, rad/√s); ``accel_white`` m/s^2/√Hz (= VRW, m/s/√s);
    ``gyro_bias_rw`` rad/s/√s and ``accel_bias_rw`` m/s^2/√s drive the bias random walks
    (thesis eq. 3.20, 3.23). ``notes`` says where each value came from.
    """

    gyro_white: np.ndarray
    accel_white: np.ndarray
    gyro_bias_rw: np.ndarray
    accel_bias_rw: np.ndarray
    notes: tuple[str, ...] = ()


def white_density(x: np.ndarray, dt: float) -> np.ndarray:
    """White-noise density (3,) of samples (N, 3) at interval ``dt``: SI unit per √Hz.

    From second differences, which cancel a slowly varying input (a turning table, a drifting
    bias): ``var(x[k+1] - 2 x[k] + x[k-1]) = 6 sigma^2``, with a robust (MAD) sigma so the
    rate changes of a table sequence do not count; density = ``sigma sqrt(dt)``.
    """
    d2 = np.diff(np.asarray(x, float), n=2, axis=0)
    mad = np.median(np.abs(d2 - np.median(d2, axis=0)), axis=0)
    return 1.4826 * mad / np.sqrt(6.0) * np.sqrt(dt)


def process_noise(calibration: CalibrationSet, bias_correlation_s: float = 600.0,
                  fallback: ImuSamples | None = None) -> ProcessNoise:
    """Process-noise densities from the set's noise block (thesis eq. 3.50-3.53).

    White noise: gyro ARW, accelerometer VRW. When the set did not observe one (no Allan
    analysis in its provenance) it is estimated from ``fallback`` samples with
    :func:`white_density` and said in ``notes``; without fallback samples AnalysisError names
    the term. Bias random walk: the rate random walk ``rrw`` plus the bias instability
    spread over ``bias_correlation_s`` (a random walk reaching the bias-instability level
    after that time: density ``B / sqrt(tau)``), combined in quadrature; a term that is not
    observed counts as zero and is named in ``notes``.
    """
    notes: list[str] = []
    white = {}
    for triad, term in (("gyro", "arw"), ("accel", "vrw")):
        v = calibration.noise_term(triad, term)
        if not np.all(np.isfinite(v)):
            if fallback is None:
                raise AnalysisError(f"calibration set {calibration.id}: noise.{triad}.{term} is not observed "
                                    "(run an Allan-variance procedure first)")
            est = white_density(getattr(fallback, triad), fallback.dt)
            v = np.where(np.isfinite(v), v, est)
            notes.append(f"noise.{triad}.{term} not in the set: estimated from {fallback.source} "
                         f"(second differences): {np.array2string(est, precision=3)} SI")
        white[triad] = v
    walk = {}
    for triad in ("gyro", "accel"):
        rrw = calibration.noise_term(triad, "rrw")
        bi = calibration.noise_term(triad, "bias_instability")
        for name, v in (("rrw", rrw), ("bias_instability", bi)):
            if not np.all(np.isfinite(v)):
                notes.append(f"noise.{triad}.{name} not observed: taken as zero")
        walk[triad] = np.sqrt(np.nan_to_num(rrw) ** 2 + np.nan_to_num(bi) ** 2 / bias_correlation_s)
    return ProcessNoise(white["gyro"], white["accel"], walk["gyro"], walk["accel"], tuple(notes))
