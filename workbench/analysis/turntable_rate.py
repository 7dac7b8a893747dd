"""Rate-table fit of the gyro: scale factor, misalignment, nonlinearity and asymmetry.

:func:`rate_reference` (the true mean body rate of a rate step over whole revolutions) and
:func:`fit_gyro_rate` (against the encoder rate plus the vertical Earth rate). Part of
:mod:`workbench.analysis.turntable`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from workbench import units
from workbench.analysis.position_check import (
    StepStats, mean_variance, step_name, whole_revolution_samples, whole_revolutions,
)
from workbench.analysis.turntable_fit import (
    TriadFit, _AxisFit, _NAN3, _NAN33, _drop_unobservable, _fit_with_misfits, _gauss_newton, _mount_key,
    _residual_frame, _sigma_matrix, check_site,
)
from workbench.analysis.turntable_noise import _noise_notes, _position_sigma, between_step_variance, bias_wander
from workbench.earth import earth_rate_ned
from workbench.errors import AnalysisError
from workbench.model import TriadModel
from workbench.session import Session, StepRecord


# -- gyro, rate table --------------------------------------------------------------------------

def rate_reference(session: Session, s: StepStats) -> np.ndarray:
    """True mean angular rate (3,) rad/s, body frame, of a rate step over whole revolutions.

    The encoder rate (mean of ``table_rate``; the commanded rate if the column is absent)
    plus the vertical Earth-rate component, about the table's down axis, rotated into the body
    by the mount. The horizontal Earth rate averages out over whole revolutions.
    """
    rate = s.table_rate if np.isfinite(s.table_rate) else s.step.table_rate
    down = rate + earth_rate_ned(session.site.latitude)[2]
    return np.asarray(s.step.mount).T @ np.array([0.0, 0.0, down])


def fit_gyro_rate(session: Session, steps: Sequence[int] | None = None,
                  position_sigma: float | str = 0.0) -> TriadFit:
    """Gyro ``M``, nonlinearity and asymmetry from rate steps (rad/s, body frame).

    Each rate step is reduced to its mean over whole revolutions and compared with
    :func:`rate_reference`. Per axis ``j``: ``y_j = (e_j + M_j) w + asym_j |w_j| + n_j u_j^2 +
    c_j(mount)``, with one offset per mount (bias + G f). Nonlinearity and asymmetry need the
    pair sums ``c + asym r + n r^2`` at three or more rates; with fewer they are dropped and a
    warning says so. Bias and ``G`` are solved from the offsets when the mounts observe them.

    ``position_sigma`` (rad): 1-sigma tilt of the table axis in the body at each step (fixture
    repeatability); it adds ``|w|^2 s^2 (1 - u_j^2)`` to the variance of row ``j`` (the
    off-axis rate it leaks), ``"auto"`` estimates it as :func:`fit_accel` does.
    """
    check_site(session)
    context = f"{session.name}: gyro rate fit"
    recs = session.steps_of_kind("rate") if steps is None else [session.step(i) for i in steps]
    bad = [r for r in recs if r.kind != "rate"]
    if bad:
        raise AnalysisError(f"{context}: {step_name(bad[0])} is a {bad[0].kind} step, not a rate step")
    if not recs:
        raise AnalysisError(f"{context}: the session has no rate steps")
    stats = [whole_revolutions(session, r) for r in recs]
    warnings = []
    if not all(np.isfinite(s.table_rate) for s in stats):
        warnings.append(f"{context}: samples have no table_rate column: the commanded rate is the reference")
    w = np.array([rate_reference(session, s) for s in stats])
    w_nominal = np.array([np.asarray(s.step.mount).T @ np.array([0.0, 0.0, s.step.table_rate]) for s in stats])
    y = np.array([s.gyro for s in stats])
    noise = mean_variance([_rate_error_signal(session, s.step) for s in stats], session.sample_rate_hz)
    var = noise.variance
    mounts = list(dict.fromkeys(_mount_key(s.step.mount) for s in stats))
    onehot = np.array([[float(_mount_key(s.step.mount) == m) for m in mounts] for s in stats])

    speed2 = np.sum(w**2, axis=1)[:, None]
    u2 = w**2 / speed2

    def position_var(sig: float) -> np.ndarray:
        return var + speed2 * sig**2 * (1 - u2) + speed2 * sig**4 * u2

    def build(rows: np.ndarray, sig: float | None = None) -> _AxisFit:
        wr, oh = w[rows], onehot[rows]
        vr = position_var(tilt if sig is None else sig)[rows]
        base = [[f"m{k}" for k in range(3)] + ["asym", "n"] + [f"c{m}" for m in range(len(mounts))]
                for _ in range(3)]
        # observability from the commanded rates (the Earth rate and encoder noise would make a
        # structurally unobservable column look observable at a condition number of ~1e4)
        wn = w_nominal[rows]
        designs = [np.column_stack([wn, np.abs(wn[:, j]), wn[:, j] ** 2, oh]) for j in range(3)]
        keep, dropped = _drop_unobservable(designs, base, vr, droppable=("n", "asym"), context=context)
        names = [[base[j][k] for k in keep[j]] for j in range(3)]

        def model(j, beta):
            p = dict(zip(names[j], beta))
            a = np.eye(3)[j] + np.array([p.get(f"m{k}", 0.0) for k in range(3)])
            u = wr @ a
            nl = p.get("n", 0.0)
            cols = {f"m{k}": wr[:, k] * (1 + 2 * nl * u) for k in range(3)}
            cols.update({"asym": np.abs(wr[:, j]), "n": u**2})
            cols.update({f"c{m}": oh[:, m] for m in range(len(mounts))})
            h = u + nl * u**2 + p.get("asym", 0.0) * np.abs(wr[:, j]) + oh @ np.array(
                [p.get(f"c{m}", 0.0) for m in range(len(mounts))])
            return h, np.column_stack([cols[nm] for nm in names[j]])

        fit = _gauss_newton(model, [np.zeros(len(n)) for n in names], names, y[rows], vr)
        fit.dropped = dropped
        return fit

    def residual_of(fit):
        return lambda i: f"{units.fmt(np.abs(y[i] - w[i]).max(), 'deg/s', 3)} before compensation"

    tilt = _position_sigma(build, position_sigma, len(stats), context)
    fit, used, outliers, w2 = _fit_with_misfits(build, stats, y, position_var(tilt), context, residual_of)
    warnings += w2
    unobserved = sorted({d for d in fit.dropped if not d.startswith("c")})
    if unobserved:
        warnings.append(f"{context}: not observable from these rates (need 3 or more distinct rates): "
                        f"{', '.join('nonlinearity' if d == 'n' else 'asymmetry' for d in unobserved)}")
    m, m_s = _sigma_matrix(fit, "m", 3)
    n, n_s = _sigma_matrix(fit, "n", 1)
    asym, asym_s = _sigma_matrix(fit, "asym", 1)
    offsets, off_cov = _offsets(fit, len(mounts))
    f_m = np.array([np.reshape(k, (3, 3)).T @ np.array([0.0, 0.0, -session.site.gravity]) for k in mounts])
    bias, bias_s, g, g_s = _bias_from_offsets(offsets, off_cov, f_m)
    bias_s = np.sqrt(bias_s**2 + bias_wander(noise, between_step_variance(fit, position_var(tilt)[used])))
    result = TriadFit("gyro", bias, m, n[:, 0], g, bias_s, m_s, n_s[:, 0], g_s, asym[:, 0], asym_s[:, 0])
    off_rows = onehot @ offsets
    comp = TriadModel(np.zeros(3), m, n[:, 0]).compensate(y - off_rows - asym[:, 0] * np.abs(w))
    notes = {"rates_rad_s": sorted({round(float(abs(np.linalg.norm(x))), 9) for x in w}),
             "mount_offsets": offsets.tolist(), "step_offsets": off_rows.tolist(),
             "revolutions": [s.revolutions for s in stats]}
    if np.isnan(bias_s).all():
        notes["bias"] = "not observed: the rate steps' mounts cannot separate bias from g-sensitivity"
    notes.update({"position_sigma_rad": tilt, **_noise_notes(noise)})
    return replace(result, residuals=_residual_frame(stats, w, y, comp, position_var(tilt) * fit.scale, used),
                        outliers=tuple(stats[i].step.index for i in outliers), warnings=tuple(warnings),
                        chi2_reduced=fit.chi2 / fit.dof if fit.dof else float("nan"), dof=fit.dof, notes=notes)


def _rate_error_signal(session: Session, step: StepRecord) -> np.ndarray:
    """Gyro minus the true rate (N, 3), rad/s, over a rate step's whole revolutions (for its noise).

    True rate: encoder rate about the table axis plus the Earth rate (the horizontal part
    rotating with the table when the azimuth is known; else only its vertical part).
    """
    df, _ = whole_revolution_samples(session, step)
    mount = np.asarray(step.mount)
    rate = df["table_rate"].to_numpy(float) if "table_rate" in df.columns else np.full(len(df), step.table_rate)
    w = rate[:, None] * mount.T[:, 2][None, :]
    w_ie = earth_rate_ned(session.site.latitude)
    if session.site.table_zero_azimuth is not None and "table_angle" in df.columns:
        angle = df["table_angle"].to_numpy(float)
        w = w + session.attitude(step, angle[:, None]).inv().apply(w_ie)
    else:
        w = w + w_ie[2] * mount.T[:, 2][None, :]
    return df[["gx", "gy", "gz"]].to_numpy(float) - w


def _offsets(fit: _AxisFit, n_mounts: int) -> tuple[np.ndarray, list[np.ndarray]]:
    """Mount offsets (n_mounts, 3) and, per axis, their covariance (n_mounts, n_mounts)."""
    off = np.zeros((n_mounts, 3))
    covs = []
    for j in range(3):
        idx = [fit.names[j].index(f"c{m}") for m in range(n_mounts)]
        off[:, j] = fit.beta[j][idx]
        covs.append(fit.cov[j][np.ix_(idx, idx)])
    return off, covs


def _bias_from_offsets(off: np.ndarray, covs: list[np.ndarray], f_m: np.ndarray):
    """Bias and G (with sigmas) from per-mount offsets ``c = b + G f``; NaN sigmas if not observable."""
    x = np.column_stack([np.ones(len(f_m)), f_m])
    if len(f_m) < 4 or np.linalg.matrix_rank(x / np.linalg.norm(x, axis=0)) < 4:
        return np.zeros(3), _NAN3.copy(), np.zeros((3, 3)), _NAN33.copy()
    pinv = np.linalg.pinv(x)
    bias, bias_s, g, g_s = np.zeros(3), np.zeros(3), np.zeros((3, 3)), np.zeros((3, 3))
    for j in range(3):
        beta = pinv @ off[:, j]
        cov = pinv @ covs[j] @ pinv.T
        bias[j], bias_s[j] = beta[0], np.sqrt(cov[0, 0])
        g[j], g_s[j] = beta[1:], np.sqrt(np.diag(cov)[1:])
    return bias, bias_s, g, g_s
