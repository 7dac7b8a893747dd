"""Per-step data extraction and quality checks for turntable analyses.

What a multi-position or rate fit needs from one step, and the checks a lab tool usually
skips: a static step with motion in it, a rate step shorter than one revolution, and the
detection of a position that does not fit the model (a mounting or fixture error), by
externally studentised (leave-one-out) residuals of a weighted least-squares fit.

Public: :class:`StepStats`, :class:`MeanNoise`, :func:`step_stats`, :func:`motion_in_static`,
:func:`mean_variance`, :func:`static_mean_variance`, :func:`whole_revolutions`,
:func:`whole_revolution_samples`, :func:`deleted_residual_statistics`, :func:`step_name`.

The noise of step means comes from a two-term model (white noise + bias-instability floor)
fitted to the Allan variance of the steps (:func:`mean_variance`), which also sees the
low-frequency noise that a sample standard deviation would miss.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import pandas as pd

from workbench.analysis.effective_n import tau_int_records
from workbench.errors import AnalysisError
from workbench.session import ACCEL, GYRO, Session, StepRecord

MOTION_GYRO_FLOOR = np.radians(0.05)  # rad/s; block-mean rate change always accepted below this
MOTION_ACCEL_FLOOR = 2e-3  # relative change of |block-mean specific force| direction, rad


@dataclass(frozen=True)
class StepStats:
    """Means of one step's samples (SI, body frame).

    ``gyro``/``accel`` (3,) means; ``n`` samples used; ``table_rate`` mean encoder rate
    (rad/s, NaN if the samples have no ``table_rate`` column); ``table_angle`` mean table angle (rad, NaN if
    absent); ``revolutions`` whole revolutions used (0 for a static step).
    """

    step: StepRecord
    gyro: np.ndarray
    accel: np.ndarray
    n: int
    table_rate: float
    table_angle: float
    revolutions: int = 0


def step_name(step: StepRecord) -> str:
    """``'step 7 (x-up)'``: how errors and warnings name a step."""
    label = step.label or step.kind
    return f"step {step.index} ({label})"


def _frame(session: Session, step: StepRecord, settle_s: float) -> pd.DataFrame:
    df = session.step_samples(step.index)
    if len(df) == 0:
        raise AnalysisError(f"{session.name}: {step_name(step)} has no samples")
    t = df["t"].to_numpy(float)
    settle = min(settle_s, 0.2 * (t[-1] - t[0]))
    return df.iloc[int(np.searchsorted(t, t[0] + settle)):]  # t increases: the rows from t[0] + settle on


def step_stats(session: Session, step: StepRecord, settle_s: float = 0.0) -> StepStats:
    """Means of a static step, after dropping the first ``settle_s`` s.

    At most 20 % of the step is dropped.
    """
    df = _frame(session, step, settle_s)
    return _stats(step, df, 0)


def _stats(step: StepRecord, df: pd.DataFrame, revolutions: int) -> StepStats:
    g, a = df[GYRO].to_numpy(float), df[ACCEL].to_numpy(float)
    rate = float(df["table_rate"].mean()) if "table_rate" in df.columns else float("nan")
    angle = float(df["table_angle"].mean()) if "table_angle" in df.columns else float("nan")
    return StepStats(step, g.mean(axis=0), a.mean(axis=0), len(df), rate, angle, revolutions)


@dataclass(frozen=True)
class MeanNoise:
    """Noise of step means: ``white`` (3,) density sqrt(W), u/√Hz; ``floor`` (3,) sqrt(F), u;
    ``variance`` (n, 3) variance of each step's mean, u^2 (u = the triad's SI unit);
    ``floor_limit`` (3,) sqrt of the detection threshold of F (two standard errors of the Allan
    variance at ``T/4``): a floor up to it can hide in these steps, u."""

    white: np.ndarray
    floor: np.ndarray
    variance: np.ndarray
    floor_limit: np.ndarray
    tau_int: np.ndarray | None = None  # (3,) integrated autocorrelation time within the steps, samples

    def with_floor(self, floor: np.ndarray | float) -> MeanNoise:
        """The noise with its floor raised to at least ``floor`` (scalar or (3,), sqrt(F), u).

        For a unit whose bias instability the session's dwells are too short to show: ``floor``
        = ``0.664 B`` from the unit's Allan characterisation (IEEE 952, B its bias instability).
        """
        new = np.maximum(self.floor, np.broadcast_to(np.asarray(floor, float), (3,)))
        return replace(self, floor=new, variance=self.variance - self.floor**2 + new**2)


def mean_variance(signals: list[np.ndarray], fs: float) -> MeanNoise:
    """Variance of the mean of each signal (N_i, 3), from a two-term noise model pooled over them.

    ``AVAR(tau) = W / tau + F``: white noise ``W`` (from the sample-to-sample differences,
    ``W = var(diff) / 2 / fs``) plus a flat bias-instability floor ``F`` (IEEE 952), the
    excess of the Allan variance at ``tau = T/4`` (``T`` the shortest signal, non-overlapping
    blocks, averaged over the signals) over the white part. ``F`` is kept on an axis where it
    exceeds two standard errors of that Allan variance (chi-square with the pooled
    block-difference count; 2.3 % false alarms on white noise), and on all three axes (clipped
    at 0) where their summed excess exceeds two standard errors of the sum (the triad shares
    one technology; √3 more power). Else the noise is taken as white: a floor of about the
    white level at ``T/4`` goes undetected in a short session (six 5-s positions); that
    threshold is returned as ``floor_limit`` (sqrt, u) so that a caller can say so, or raise the
    floor to the unit's Allan result (:meth:`MeanNoise.with_floor`). The variance of a mean over
    ``T_i`` is ``W / T_i + F``: the white part averages down, the bias wander between steps does
    not. (A rate random walk that grows over the whole session is not seen at ``T/4``; the
    scatter between positions is what can reveal it, see
    :func:`workbench.analysis.turntable.between_step_variance`.)

    Correlated noise shorter than ``T/4`` (Gauss-Markov drift, a slow wobble of the fixture),
    which the sample-to-sample differences do not see, is measured directly: the steps'
    autocorrelation, pooled (:func:`workbench.analysis.effective_n.tau_int_records`), gives
    ``tau_int``; on an axis where it exceeds 1 (beyond two white-noise standard errors) the
    white level is the effective one, ``W = s^2 tau_int / fs`` (``s^2`` the pooled within-step
    variance: a mean of ``N`` samples has the variance of ``N / tau_int`` independent ones), and
    ``F`` is the Allan variance's excess over that (``white`` returns the effective level).
    """
    n_min = min(len(x) for x in signals)
    m = n_min // 4
    if m < 2:
        raise AnalysisError(f"steps of {n_min} samples are too short to estimate their noise")
    w = np.mean([np.diff(x, axis=0).var(axis=0) / 2.0 for x in signals], axis=0) / fs
    corr = tau_int_records(signals)
    s2 = np.average([x.var(axis=0, ddof=1) for x in signals], axis=0, weights=[len(x) for x in signals])
    w = np.where(corr > 1.0, np.maximum(w, s2 * corr / fs), w)  # the effective white level
    vals, dof = [], 0
    for x in signals:
        blocks = x[: (len(x) // m) * m].reshape(-1, m, 3).mean(axis=1)
        vals.append(0.5 * np.mean(np.diff(blocks, axis=0) ** 2, axis=0))
        dof += len(blocks) - 1
    tau = m / fs
    a2 = np.mean(vals, axis=0)
    f = a2 - w / tau
    limit = 2 * a2 * np.sqrt(2.0 / dof)
    triad = f.sum() > 2 * np.sqrt(np.sum(a2**2) * 2.0 / dof)  # the same test on the three axes' sum
    f = np.where(triad | (f > limit), np.maximum(f, 0.0), 0.0)
    t = np.array([len(x) / fs for x in signals])
    return MeanNoise(np.sqrt(w), np.sqrt(f), w[None, :] / t[:, None] + f[None, :], np.sqrt(limit), corr)


def static_mean_variance(session: Session, stats: list[StepStats], triad: str, settle_s: float = 0.0) -> MeanNoise:
    """:func:`mean_variance` of the ``triad`` ("gyro" or "accel") samples of static steps."""
    cols = GYRO if triad == "gyro" else ACCEL
    return mean_variance([_frame(session, s.step, settle_s)[cols].to_numpy(float) for s in stats],
                         session.sample_rate_hz)


def motion_in_static(session: Session, step: StepRecord, settle_s: float = 0.0) -> str | None:
    """A one-line reason if the static ``step`` shows motion, else None.

    The step is cut into 1-s blocks; motion = a change between consecutive block means of the
    gyro larger than max(8 sigma of the change, 0.05 °/s), or of the accelerometer direction
    larger than max(8 sigma, 2 mrad). Sigma comes from the sample-to-sample differences
    (white noise). Slow drifts (thermal, bias instability) pass; bumps and turns do not.
    """
    df = _frame(session, step, settle_s)
    m = max(2, int(round(session.sample_rate_hz)))
    k = len(df) // m
    if k < 3:
        return None
    gyro = df[GYRO].to_numpy(float)
    blocks = gyro[: k * m].reshape(k, m, 3).mean(axis=1)
    sig = np.sqrt(np.diff(gyro, axis=0).var(axis=0) / 2.0 / m * 2.0)  # sigma of a difference of block means
    jump = np.abs(np.diff(blocks, axis=0))
    lim = np.maximum(8 * sig, MOTION_GYRO_FLOOR)
    if np.any(jump > lim):
        return (f"{step_name(step)}: not static: gyro 1-s mean jumps by {np.degrees(jump.max()):.3g} °/s "
                f"(limit {np.degrees(lim.max()):.3g} °/s)")
    acc = df[ACCEL].to_numpy(float)
    blocks = acc[: k * m].reshape(k, m, 3).mean(axis=1)
    unit = blocks / np.linalg.norm(blocks, axis=1)[:, None]
    turn = np.linalg.norm(np.cross(unit[1:], unit[:-1]), axis=1)
    sig_dir = np.linalg.norm(np.sqrt(np.diff(acc, axis=0).var(axis=0) / m)) / np.linalg.norm(blocks.mean(axis=0))
    lim = max(8 * sig_dir, MOTION_ACCEL_FLOOR)
    if np.any(turn > lim):
        return (f"{step_name(step)}: not static: accelerometer direction moves by {1e3 * float(turn.max()):.3g} mrad "
                f"between 1-s blocks (limit {1e3 * lim:.3g} mrad)")
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
