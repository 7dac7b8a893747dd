"""Per-step data extraction and quality checks for turntable analyses.

What a multi-position or rate fit needs from one step, and the checks a lab tool usually
skips: a static step with motion in it, a rate step shorter than one revolution, and the
detection of a position that does not fit the model (a mounting or fixture error), by
externally studentised (leave-one-out) residuals of a weighted least-squares fit.

Public: :class:`StepStats`, :func:`step_stats`, :func:`motion_in_static`, :func:`mean_variance`,
:func:`static_mean_variance`, :func:`whole_revolutions`, :func:`whole_revolution_samples`, :func:`deleted_residual_statistics`, :func:`step_name`.

Noise of a step mean is estimated by batch means (the scatter of the means of ``K`` equal
blocks divided by sqrt(K)), which also sees the low-frequency noise (bias instability) that
a sample standard deviation would miss.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from workbench.errors import AnalysisError
from workbench.session import ACCEL, GYRO, Session, StepRecord

_BLOCKS = 10  # batch-means blocks per step
MOTION_GYRO_FLOOR = np.radians(0.05)  # rad/s; block-mean rate change always accepted below this
MOTION_ACCEL_FLOOR = 2e-3  # relative change of |block-mean specific force| direction, rad


@dataclass(frozen=True)
class StepStats:
    """Means of one step's samples with the variance of those means (SI, body frame).

    ``gyro``/``accel`` (3,) means; ``gyro_var``/``accel_var`` (3,) variance of each mean from
    batch means; ``n`` samples used; ``table_rate`` mean encoder rate (rad/s, NaN if the
    samples have no ``table_rate`` column); ``table_angle`` mean table angle (rad, NaN if
    absent); ``revolutions`` whole revolutions used (0 for a static step).
    """

    step: StepRecord
    gyro: np.ndarray
    accel: np.ndarray
    gyro_var: np.ndarray
    accel_var: np.ndarray
    n: int
    table_rate: float
    table_angle: float
    revolutions: int = 0


def step_name(step: StepRecord) -> str:
    """``'step 7 (x-up)'``: how errors and warnings name a step."""
    label = step.label or step.kind
    return f"step {step.index} ({label})"


def _batch_var(x: np.ndarray) -> np.ndarray:
    """Variance of the mean of ``x`` (N, 3) by batch means; falls back to white noise for short steps."""
    n = x.shape[0]
    k = _BLOCKS if n >= 20 * _BLOCKS else max(2, n // 20)
    if n < 4 or k < 2:
        return np.full(3, np.nan)
    m = n // k
    blocks = x[: m * k].reshape(k, m, 3).mean(axis=1)
    var_batch = blocks.var(axis=0, ddof=1) / k
    var_white = np.diff(x, axis=0).var(axis=0, ddof=1) / 2.0 / n  # white-noise floor (difference estimator)
    return np.maximum(var_batch, var_white)


def _frame(session: Session, step: StepRecord, settle_s: float) -> pd.DataFrame:
    df = session.step_samples(step.index)
    if len(df) == 0:
        raise AnalysisError(f"{session.name}: {step_name(step)} has no samples")
    t = df["t"].to_numpy(float)
    settle = min(settle_s, 0.2 * (t[-1] - t[0]))
    return df[t >= t[0] + settle]


def step_stats(session: Session, step: StepRecord, settle_s: float = 0.0) -> StepStats:
    """Means and variance of the means of a static step, after dropping the first ``settle_s`` s.

    At most 20 % of the step is dropped.
    """
    df = _frame(session, step, settle_s)
    return _stats(step, df, 0)


def _stats(step: StepRecord, df: pd.DataFrame, revolutions: int) -> StepStats:
    g, a = df[GYRO].to_numpy(float), df[ACCEL].to_numpy(float)
    rate = float(df["table_rate"].mean()) if "table_rate" in df.columns else float("nan")
    angle = float(df["table_angle"].mean()) if "table_angle" in df.columns else float("nan")
    return StepStats(step, g.mean(axis=0), a.mean(axis=0), _batch_var(g), _batch_var(a), len(df), rate, angle,
                     revolutions)


def mean_variance(signals: list[np.ndarray], fs: float) -> np.ndarray:
    """Variance (n, 3) of the mean of each signal (N_i, 3), from a two-term noise model pooled over them.

    The Allan variance of each signal is taken at ``tau1 = T/20`` and ``tau2 = T/4`` (``T`` the
    shortest signal; non-overlapping blocks) and averaged over the signals;
    ``AVAR(tau) = W / tau + F`` (white noise plus a flat bias-instability floor, IEEE 952) is
    solved for ``W, F >= 0``. The variance of a mean over ``T_i`` is then ``W / T_i + F``: the
    white part averages down, the bias wander between steps does not.
    """
    n_min = min(len(x) for x in signals)
    m1, m2 = n_min // 20, n_min // 4
    if m1 < 1:
        raise AnalysisError(f"steps of {n_min} samples are too short to estimate their noise")
    avar = []
    for m in (m1, m2):
        vals, dof = [], 0
        for x in signals:
            blocks = x[: (len(x) // m) * m].reshape(-1, m, 3).mean(axis=1)
            vals.append(0.5 * np.mean(np.diff(blocks, axis=0) ** 2, axis=0))
            dof += len(blocks) - 1
        avar.append(np.mean(vals, axis=0))
    tau1, tau2 = m1 / fs, m2 / fs
    a1, a2 = avar
    w = np.maximum((a1 - a2) / (1 / tau1 - 1 / tau2), 0.0)
    f = np.maximum(a2 - w / tau2, 0.0)
    # keep the floor only where it stands out of the scatter of AVAR(tau2) (2 sigma, chi2 with
    # `dof` degrees of freedom); otherwise the noise is white and the short tau estimates it best
    f = np.where(f > 2 * a2 * np.sqrt(2.0 / max(dof, 1)), f, 0.0)
    w = np.where(f == 0, a1 * tau1, w)
    t = np.array([len(x) / fs for x in signals])
    return w[None, :] / t[:, None] + f[None, :]


def static_mean_variance(session: Session, stats: list[StepStats], triad: str, settle_s: float = 0.0) -> np.ndarray:
    """:func:`mean_variance` of the ``triad`` ("gyro" or "accel") samples of static steps."""
    cols = GYRO if triad == "gyro" else ACCEL
    return mean_variance([_frame(session, s.step, settle_s)[cols].to_numpy(float) for s in stats],
                         session.sample_rate_hz)


def motion_in_static(session: Session, step: StepRecord, settle_s: float = 0.0) -> str | None:
    """A one-line reason if the static ``step`` shows motion, else None.

    Motion = a 1-s block mean of the gyro that departs from the step median by more than
    max(8 sigma of a block mean, 0.05 °/s), or a change of the accelerometer direction
    between 1-s blocks larger than max(8 sigma, 2 mrad). Sigma is estimated from the
    sample-to-sample differences (white noise).
    """
    df = _frame(session, step, settle_s)
    rate_hz = session.sample_rate_hz
    m = max(2, int(round(rate_hz)))
    k = len(df) // m
    if k < 3:
        return None
    for name, cols, floor in (("gyro", GYRO, MOTION_GYRO_FLOOR), ("accel", ACCEL, None)):
        x = df[cols].to_numpy(float)
        blocks = x[: k * m].reshape(k, m, 3).mean(axis=1)
        sig = np.sqrt(np.diff(x, axis=0).var(axis=0) / 2.0 / m)
        if name == "gyro":
            dev = np.abs(blocks - np.median(blocks, axis=0))
            lim = np.maximum(8 * sig, floor)
            if np.any(dev > lim):
                worst = float(np.max(dev))
                return (f"{step_name(step)}: not static: gyro 1-s mean departs by {np.degrees(worst):.3g} °/s "
                        f"(limit {np.degrees(lim.max()):.3g} °/s)")
        else:
            ref = np.median(blocks, axis=0)
            norm = np.linalg.norm(ref)
            ang = np.linalg.norm(np.cross(blocks / np.linalg.norm(blocks, axis=1)[:, None], ref / norm), axis=1)
            lim = max(8 * float(np.linalg.norm(sig)) / norm, MOTION_ACCEL_FLOOR)
            if np.any(ang > lim):
                return (f"{step_name(step)}: not static: accelerometer direction moves by "
                        f"{1e3 * float(ang.max()):.3g} mrad between 1-s blocks (limit {1e3 * lim:.3g} mrad)")
    return None


def whole_revolutions(session: Session, step: StepRecord) -> StepStats:
    """Statistics of a rate step over its whole revolutions (see :func:`whole_revolution_samples`)."""
    df, revs = whole_revolution_samples(session, step)
    return _stats(step, df, revs)


def whole_revolution_samples(session: Session, step: StepRecord) -> tuple[pd.DataFrame, int]:
    """Samples of a rate step over its whole revolutions from its first sample, and their number.

    The turned angle comes from the ``table_angle`` column (unwrapped) when present, else
    from the encoder rate (``table_rate``) or the commanded rate times time. Raises
    AnalysisError naming the step if it turns less than one revolution.
    """
    df = session.step_samples(step.index)
    if len(df) == 0:
        raise AnalysisError(f"{session.name}: {step_name(step)} has no samples")
    t = df["t"].to_numpy(float)
    dt = 1.0 / session.sample_rate_hz
    if "table_angle" in df.columns:
        turned = np.unwrap(df["table_angle"].to_numpy(float))
        turned = np.abs(turned - turned[0]) + np.abs(np.gradient(turned)).mean()  # angle after each sample
    else:
        rate = df["table_rate"].to_numpy(float) if "table_rate" in df.columns else np.full(len(df), step.table_rate)
        turned = np.abs(np.cumsum(rate) * dt)
    revs = int(np.floor(turned[-1] / (2 * np.pi) + 1e-3))
    if revs < 1:
        raise AnalysisError(f"{session.name}: {step_name(step)}: turns {np.degrees(turned[-1]):.1f}° "
                            f"in {t[-1] - t[0] + dt:.3g} s, less than one revolution")
    keep = turned <= revs * 2 * np.pi * (1 + 1e-9) + 0.5 * np.abs(np.gradient(turned)).mean()
    return df[keep], revs


def deleted_residual_statistics(designs: list[np.ndarray], y: np.ndarray, var: np.ndarray,
                                min_scale: float = 1.0) -> np.ndarray:
    """Leave-one-out test statistic of each row of a per-axis weighted least-squares fit.

    ``designs`` holds one (n, p_j) design matrix per axis j, ``y`` (n, 3) the observations
    and ``var`` (n, 3) their variances. For row i, each axis is refitted without row i; the
    prediction error ``d_ij`` of the deleted row is divided by its variance
    ``var_ij + x_ij' C_j x_ij``, with ``C_j`` the refit's covariance scaled by
    ``max(min_scale, chi2/dof)`` of the refit (pooled over axes). Returns (n,) statistics
    ``T_i = sum_j d_ij^2 / V_ij``, chi-square with 3 degrees of freedom for a row that fits;
    NaN where the refit cannot predict row i (the row is the only one observing a parameter).
    """
    n = y.shape[0]
    out = np.full(n, np.nan)
    for i in range(n):
        keep = np.arange(n) != i
        stat, chi2, dof = 0.0, 0.0, 0
        preds = []
        for j, x in enumerate(designs):
            xk, yk, wk = x[keep], y[keep, j], 1.0 / var[keep, j]
            a = xk * np.sqrt(wk)[:, None]
            if np.linalg.matrix_rank(a) < x.shape[1]:
                break
            beta, *_ = np.linalg.lstsq(a, yk * np.sqrt(wk), rcond=None)
            cov = np.linalg.inv(a.T @ a)
            chi2 += float(np.sum((yk - xk @ beta) ** 2 * wk))
            dof += int(keep.sum()) - x.shape[1]
            preds.append((y[i, j] - x[i] @ beta, var[i, j] + x[i] @ cov @ x[i]))
        else:
            scale = max(min_scale, chi2 / dof) if dof > 0 else min_scale
            for d, v_unscaled in preds:
                stat += d**2 / (v_unscaled * scale)
            out[i] = stat
    return out
