"""North-finding estimators: maytag pairs, the Earth-rate harmonic, the redundant configuration.

:func:`maytag_azimuth` (thesis eq. 4.6), :func:`maytag_azimuth_one_axis` (eq. 4.3),
:class:`HarmonicFit` / :func:`fit_harmonic` / :func:`group_fits` (``b + A cos a + B sin a``
shared through the azimuth), :class:`MaytagResult` / :func:`maytag`, :class:`RedundantResult`
/ :func:`redundant` (sec. 4.4.3), :func:`repeatability` (tables 4.3-4.4). Frames and
references: :mod:`workbench.analysis.northfinding`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from workbench.analysis.northfinding_data import AxisGeometry, Observations, angle_diff, circular_mean
from workbench.analysis.northfinding_theory import check_latitude
from workbench.angles import wrap_2pi
from workbench.earth import EARTH_RATE
from workbench.errors import AnalysisError

MIN_REWEIGHT_DOF = 3  # residual degrees of freedom per level axis below which fit_harmonic stays unweighted

# -- closed forms (eq. 4.3, 4.6) ----------------------------------------------------------

def maytag_azimuth(rate_home: np.ndarray, rate_flipped: np.ndarray, y_clockwise: bool = True) -> float:
    """Azimuth of the body x axis at the home position from one maytag pair (thesis eq. 4.6).

    ``psi = atan2(m4 - m3, m1 - m2)`` with ``m1, m2`` the x outputs and ``m3, m4`` the y
    outputs (rad/s) at home and after the 180° index. Needs no latitude and no scale factor
    when both axes share it. ``y_clockwise``: y points 90° clockwise of x seen from above
    (z-down mount); False for z-up, where the sign of the y difference flips.

    Parameters
    ----------
    rate_home, rate_flipped : (2,) array, rad/s
        Mean x and y gyro outputs (horizontal projections) at home and after the index.

    Returns
    -------
    float, rad in (-pi, pi]
    """
    d = (np.asarray(rate_home, float) - np.asarray(rate_flipped, float)) / 2.0
    sign = 1.0 if y_clockwise else -1.0
    return float(np.arctan2(-sign * d[1], d[0]))


def maytag_azimuth_one_axis(m1: float, m2: float, latitude: float) -> tuple[float, float]:
    """The two azimuth candidates (rad) of a single horizontal gyro from one maytag pair (eq. 4.3).

    ``psi = arccos((m1 - m2) / (2 Omega_e cos lat))`` lies in [0, pi]; ``-psi`` gives the same
    outputs, so the azimuth is ambiguous: the pair (psi, -psi) is returned. A difference beyond
    the Earth rate (noise, scale-factor or latitude error) is clipped to ±1 before the arccos.
    ``m1, m2`` rad/s; ``latitude`` rad.
    """
    check_latitude(latitude)
    psi = float(np.arccos(np.clip((m1 - m2) / (2.0 * EARTH_RATE * np.cos(latitude)), -1.0, 1.0)))
    return psi, -psi


# -- least squares ------------------------------------------------------------------------

@dataclass(frozen=True)
class HarmonicFit:
    """Least-squares fit of the Earth-rate sinusoid to gyro outputs vs table angle.

    ``azimuth`` rad of the body x axis at the table's zero, clockwise from true north, in
    (-pi, pi], and ``azimuth_sigma`` (formal 1-sigma, rad, from the residual scatter of each
    axis; it assumes independent rows). ``amplitude`` rad/s, the horizontal Earth rate seen
    (``Omega_e cos lat`` for a perfect gyro). ``bias`` (3,) rad/s per body axis with
    ``bias_sigma``; ``drift`` (3,) rad/s/s (NaN when not fitted), ``t_ref`` s the time the bias
    refers to. ``residual`` (N, 3) rad/s; ``residual_std`` (3,) rad/s per axis.
    """

    azimuth: float
    azimuth_sigma: float
    amplitude: float
    amplitude_sigma: float
    bias: np.ndarray
    bias_sigma: np.ndarray
    drift: np.ndarray
    drift_sigma: np.ndarray
    t_ref: float
    residual: np.ndarray
    residual_std: np.ndarray
    n_rows: int

    def model(self, angle: np.ndarray, geometry: AxisGeometry, latitude: float) -> np.ndarray:
        """Fitted gyro output (K, 3) rad/s at static table angles ``angle`` (K,) rad, drift omitted."""
        a = np.asarray(angle, float)[:, None]
        earth = geometry.gain * self.amplitude * np.cos(self.azimuth + geometry.axis_angle + a)
        return self.bias + earth - geometry.down * EARTH_RATE * np.sin(latitude)


def harmonic_design(obs: Observations, geom: AxisGeometry, axis: int) -> np.ndarray:
    """Columns (c, s) = (Omega_N cos psi, Omega_N sin psi) for one axis: g (cos(al+a), -sin(al+a))."""
    ca, sa = np.cos(geom.axis_angle[axis]), np.sin(geom.axis_angle[axis])
    cos_t = ca * obs.cos_angle - sa * obs.sin_angle  # mean cos(alpha + a)
    sin_t = sa * obs.cos_angle + ca * obs.sin_angle  # mean sin(alpha + a)
    return geom.gain[axis] * np.column_stack([cos_t, -sin_t])


def fit_harmonic(obs: Observations, geom: AxisGeometry, latitude: float, drift: bool = False,
                 bias: np.ndarray | None = None, where: str = "fit") -> HarmonicFit:
    """Fit ``rate_i = b_i [+ d_i (t - t_ref)] + g_i Omega_N cos(psi + alpha_i + a)`` (see module doc).

    Horizontal axes share ``(Omega_N cos psi, Omega_N sin psi)``; each axis has its own bias
    (and drift with ``drift=True``). Vertical axes only give their bias (the known vertical
    Earth rate and the table rate are removed). With ``bias`` (3,) rad/s given, biases are
    not fitted but subtracted (the redundant configuration). Rows are weighted per axis by
    the inverse residual variance of a first unweighted pass when each axis leaves at least
    :data:`MIN_REWEIGHT_DOF` residual degrees of freedom (else unweighted: a variance from one or
    two residuals makes the weights, and the estimate, noisier). Angles rad, rates rad/s.
    """
    check_latitude(latitude, where)
    n = len(obs)
    hz = np.flatnonzero(geom.horizontal)
    t_ref = float(np.mean(obs.t))
    dt = obs.t - t_ref
    # remove the known parts: vertical Earth rate and table rate along each axis
    y = obs.rate - geom.down * (-EARTH_RATE * np.sin(latitude) + obs.table_rate[:, None])
    if bias is not None:
        y = y - np.asarray(bias, float)
    fit_bias = bias is None
    n_per = (1 + int(drift)) if fit_bias else 0
    n_par = 2 + n_per * len(hz)
    if n * len(hz) < n_par:
        raise AnalysisError(f"{where}: {n} rows x {len(hz)} level axes cannot fit {n_par} parameters")
    exact = n * len(hz) == n_par  # e.g. one maytag pair: no residual, no formal uncertainty
    if abs(np.mean(obs.cos_angle + 1j * obs.sin_angle)) > 1 - 1e-9 and fit_bias:
        raise AnalysisError(f"{where}: all rows at one table angle; bias and Earth rate are not separable")
    blocks, rhs, axis_of = [], [], []
    for k, i in enumerate(hz):
        cols = np.zeros((n, n_par))
        cols[:, :2] = harmonic_design(obs, geom, i)
        if fit_bias:
            cols[:, 2 + n_per * k] = 1.0
            if drift:
                cols[:, 3 + n_per * k] = dt
        blocks.append(cols)
        rhs.append(y[:, i])
        axis_of.append(np.full(n, i))
    a_mat, b_vec, ax = np.vstack(blocks), np.concatenate(rhs), np.concatenate(axis_of)
    w = np.ones_like(b_vec)
    # unweighted, then weighted by per-axis residual variance when each axis leaves enough residual
    # degrees of freedom to estimate it (with one or two, the weights are noise and the estimate worse)
    reweight = not exact and (len(b_vec) - n_par) / len(hz) >= MIN_REWEIGHT_DOF
    for _ in range(2 if reweight else 1):
        sol, *_ = np.linalg.lstsq(a_mat * w[:, None], b_vec * w, rcond=None)
        res = b_vec - a_mat @ sol
        dof = max(len(b_vec) - n_par, 1)
        var_axis = {i: max(float(np.sum(res[ax == i] ** 2)) / max(dof * np.sum(ax == i) / len(ax), 1e-12), 1e-40)
                    for i in hz}
        w = 1.0 / np.sqrt(np.array([var_axis[i] for i in ax]))
    cov = np.linalg.pinv((a_mat * w[:, None]).T @ (a_mat * w[:, None]))
    if exact:
        cov[:] = np.nan
    c, s = sol[:2]
    amp = float(np.hypot(c, s))
    if amp == 0.0:
        raise AnalysisError(f"{where}: no Earth-rate signal fitted")
    jac_az = np.array([-s, c]) / amp**2
    jac_amp = np.array([c, s]) / amp
    az_sigma = float(np.sqrt(jac_az @ cov[:2, :2] @ jac_az))
    amp_sigma = float(np.sqrt(jac_amp @ cov[:2, :2] @ jac_amp))

    residual = np.full((n, 3), np.nan)
    est_bias = np.full(3, np.nan) if fit_bias else np.asarray(bias, float).copy()
    bias_sigma = np.full(3, np.nan)
    est_drift, drift_sigma = np.full(3, np.nan), np.full(3, np.nan)
    for k, i in enumerate(hz):
        residual[:, i] = res[ax == i]
        if fit_bias:
            j = 2 + n_per * k
            est_bias[i], bias_sigma[i] = sol[j], np.sqrt(cov[j, j])
            if drift:
                est_drift[i], drift_sigma[i] = sol[j + 1], np.sqrt(cov[j + 1, j + 1])
    for i in np.flatnonzero(~geom.horizontal):  # vertical axes: mean (and drift) after the known parts
        cols = np.column_stack([np.ones(n), dt]) if drift else np.ones((n, 1))
        p, *_ = np.linalg.lstsq(cols, y[:, i], rcond=None)
        r = y[:, i] - cols @ p
        var = float(r @ r) / max(n - cols.shape[1], 1)
        pc = var * np.linalg.pinv(cols.T @ cols)
        residual[:, i] = r
        if fit_bias:
            est_bias[i], bias_sigma[i] = p[0], np.sqrt(pc[0, 0])
        if drift:
            est_drift[i], drift_sigma[i] = p[1], np.sqrt(pc[1, 1])
    return HarmonicFit(float(np.arctan2(s, c)), az_sigma, amp, amp_sigma, est_bias, bias_sigma, est_drift,
                       drift_sigma, t_ref, residual, np.sqrt(np.nanmean(residual**2, axis=0)), n)


def group_fits(obs: Observations, groups: np.ndarray, geom: AxisGeometry, latitude: float,
               where: str = "fit") -> np.ndarray:
    """Azimuth (rad) of a separate fit (bias + sinusoid, no drift) per group label, in sorted order.

    Used per lap of a carousel and per turn of a multi-position sweep.
    """
    return np.array([fit_harmonic(obs.subset(groups == g), geom, latitude, where=f"{where} group {g}").azimuth
                     for g in np.unique(groups)])


# -- maytagging ---------------------------------------------------------------------------

@dataclass(frozen=True)
class MaytagResult:
    """Maytag pairs and their azimuths (thesis sec. 4.4.2).

    ``pair_azimuth`` (P,) rad, azimuth of body x at the table's zero from each pair (eq. 4.6
    with two level axes, else eq. 4.3 with the candidate nearest the pairs' mean, see
    ``ambiguous``); ``pair_time`` (P,) s; ``pair_steps`` (P, 2) step indices;
    ``pair_amplitude`` (P,) rad/s horizontal Earth rate seen by the pair;
    ``azimuth`` rad, circular mean of the pairs; ``azimuth_sigma`` rad, their std / sqrt(independent
    pairs) (P disjoint, rows // 2 sliding);
    ``pair_std`` rad, the std of the pairs about their mean; ``fit`` the harmonic fit of all
    positions (bias, amplitude, drift); ``ambiguous``: True for a one-axis result (eq. 4.3),
    whose azimuth may be mirrored (``-psi``).
    """

    pair_azimuth: np.ndarray
    pair_time: np.ndarray
    pair_steps: np.ndarray
    pair_amplitude: np.ndarray
    azimuth: float
    azimuth_sigma: float
    pair_std: float
    fit: HarmonicFit
    ambiguous: bool
    warnings: tuple[str, ...] = field(default=())


PAIRINGS = ("disjoint", "sliding")


def maytag(obs: Observations, geom: AxisGeometry, latitude: float, index_tol: float, drift: bool = False,
           where: str = "maytagging", pairs: str = "disjoint") -> MaytagResult:
    """Azimuth from consecutive position pairs 180° apart (eq. 4.6, or eq. 4.3 with one level axis).

    Rows are paired in time order: ``pairs="disjoint"`` (0, 1), (2, 3), ... (independent pairs);
    ``"sliding"`` (0, 1), (1, 2), ... (an azimuth every dwell, as thesis sec. 4.4.2 takes 80 from
    40 ABAB pairs; adjacent azimuths share a dwell, so the 1-sigma of the mean counts only the
    ``rows // 2`` independent pairs). Each pair must be 180° apart by its recorded angles within
    ``index_tol`` (rad), else AnalysisError naming the steps. The pair's first angle is removed so
    every pair estimates the azimuth at the table's zero.
    """
    check_latitude(latitude, where)
    if pairs not in PAIRINGS:
        raise AnalysisError(f"{where}: pairs {pairs!r} is not one of {', '.join(PAIRINGS)}")
    order = np.argsort(obs.t)
    obs = obs.subset(order)
    n_indep = len(obs) // 2
    if n_indep < 1:
        raise AnalysisError(f"{where}: {len(obs)} static position(s); maytagging needs at least one pair")
    warnings = []
    if len(obs) % 2 and pairs == "disjoint":
        warnings.append(f"{where}: odd number of positions; the last (step {obs.step[-1]}) is not paired")
    firsts = np.arange(n_indep) * 2 if pairs == "disjoint" else np.arange(len(obs) - 1)
    n_pairs = len(firsts)
    hz = np.flatnonzero(geom.horizontal)
    two_axis = len(hz) >= 2
    ang = obs.angle
    pair_az, pair_amp, pair_t, pair_steps = [], [], [], []
    for i in firsts:
        j = i + 1
        sep = abs(angle_diff(ang[j] - ang[i], np.pi))
        if sep > index_tol:
            raise AnalysisError(f"{where}: steps {obs.step[i]} -> {obs.step[j]}: the index is "
                                f"{np.degrees(wrap_2pi(ang[j] - ang[i])):.4f}° by the encoder, not 180° "
                                f"(tolerance {np.degrees(index_tol):.3g}°)")
        d = (obs.rate[i] - obs.rate[j]) / 2.0 / np.where(geom.gain > 0, geom.gain, 1.0)
        if two_axis:
            iy = hz[1]
            psi = maytag_azimuth(np.array([d[0], d[iy]]), np.zeros(2), bool(np.sin(geom.axis_angle[iy]) > 0))
            amp = float(np.hypot(d[0], d[iy]))
        else:
            psi = maytag_azimuth_one_axis(2 * d[0], 0.0, latitude)[0]
            amp = np.nan  # one axis sees Omega_N cos(psi): the amplitude is not observed
        pair_az.append(float(angle_diff(psi, ang[i])))
        pair_amp.append(amp)
        pair_t.append(0.5 * (obs.t[i] + obs.t[j]))
        pair_steps.append((int(obs.step[i]), int(obs.step[j])))
    pair_az = np.array(pair_az)
    if not two_axis:
        warnings.append(f"{where}: one level gyro axis: eq. 4.3 leaves a ±180° ambiguity (psi or -psi); "
                        "every pair is put on the first pair's branch")
        # each pair gives +-psi about its home angle; align all to the first pair's branch
        home = ang[firsts]
        cand = np.stack([pair_az, angle_diff(-(pair_az + home), home)])
        ref = cand[0, 0]
        pick = np.argmin(np.abs(angle_diff(cand, ref)), axis=0)
        pair_az = cand[pick, np.arange(n_pairs)]
    mean = circular_mean(pair_az)
    dev = angle_diff(pair_az, mean)
    std = float(np.std(dev, ddof=1)) if n_pairs > 1 else np.nan
    used = np.arange(firsts[-1] + 2)
    fit = fit_harmonic(obs.subset(used), geom, latitude, drift=drift and n_indep > 1, where=where)
    sigma = std / np.sqrt(n_indep) if n_indep >= 3 else fit.azimuth_sigma
    return MaytagResult(pair_az, np.array(pair_t), np.array(pair_steps), np.array(pair_amp), mean, float(sigma), std,
                        fit, not two_axis, tuple(warnings))


# -- redundant configuration (sec. 4.4.3) -------------------------------------------------

@dataclass(frozen=True)
class RedundantResult:
    """Simulated skewed four-axis configurations from consecutive 45° positions (sec. 4.4.3).

    ``pairings`` (K,) labels like ``"0-45"``; ``azimuth`` (T, K) rad, azimuth of body x at the
    table's zero from pairing k of turn t; ``turn_time`` (T,) s; ``bias`` (3,) rad/s the bias
    removed and ``bias_source``; ``mean`` (K,) rad per pairing; ``std`` (K,) rad over turns.
    """

    pairings: tuple[str, ...]
    azimuth: np.ndarray
    turn_time: np.ndarray
    bias: np.ndarray
    bias_source: str
    mean: np.ndarray
    std: np.ndarray


def redundant(obs: Observations, geom: AxisGeometry, latitude: float, positions_per_turn: int = 8,
              bias: np.ndarray | None = None, angle_tol: float = np.radians(0.5),
              where: str = "redundant") -> RedundantResult:
    """Azimuths of the eight pairings (0°-45°, ..., 315°-0°) of every turn (thesis sec. 4.4.3).

    Rows in time order form turns of ``positions_per_turn`` equally spaced angles. Each
    pairing combines the x and y outputs of positions k and k+1 of the same turn (315° pairs
    with that turn's 0°) into four readings on axes psi, psi+45°, psi+90°, psi+135° and solves
    (Omega_N cos psi, Omega_N sin psi) by least squares after removing the bias: ``bias``
    (3,) rad/s if given (a calibration), else the per-axis mean over all complete turns
    (the Earth rate averages out over equally spaced positions). Angles rad.
    """
    check_latitude(latitude, where)
    obs = obs.subset(np.argsort(obs.t))
    n_turns = len(obs) // positions_per_turn
    if n_turns < 1:
        raise AnalysisError(f"{where}: {len(obs)} positions; a turn needs {positions_per_turn}")
    obs = obs.subset(np.arange(n_turns * positions_per_turn))
    ang = obs.angle.reshape(n_turns, positions_per_turn)
    step = 2 * np.pi / positions_per_turn
    for t in range(n_turns):
        gaps = angle_diff(ang[t, 1:], ang[t, :-1])
        bad = np.abs(np.abs(gaps) - step) > angle_tol
        if bad.any():
            k = int(np.argmax(bad))
            s0, s1 = obs.step[t * positions_per_turn + k], obs.step[t * positions_per_turn + k + 1]
            raise AnalysisError(f"{where}: steps {s0} -> {s1}: index {np.degrees(gaps[k]):.3f}° is not "
                                f"{np.degrees(step):.1f}°")
    if bias is None:
        est = obs.rate.mean(axis=0) + geom.down * EARTH_RATE * np.sin(latitude)
        source = f"mean over {n_turns} complete turn(s)"
    else:
        est, source = np.asarray(bias, float), "given"
    labels = []
    az = np.zeros((n_turns, positions_per_turn))
    for k in range(positions_per_turn):
        k2 = (k + 1) % positions_per_turn
        a0 = round(float(np.degrees(wrap_2pi(ang[0, k])))) % 360  # the encoder's degree: 314.996° is 315°
        labels.append(f"{a0}-{(a0 + round(np.degrees(step))) % 360}")
        for t in range(n_turns):
            rows = np.array([t * positions_per_turn + k, t * positions_per_turn + k2])
            az[t, k] = fit_harmonic(obs.subset(rows), geom, latitude, bias=est, where=f"{where} turn {t}").azimuth
    mean = np.array([circular_mean(az[:, k]) for k in range(positions_per_turn)])
    std = np.array([np.std(angle_diff(az[:, k], mean[k]), ddof=1) if n_turns > 1 else np.nan
                    for k in range(positions_per_turn)])
    turn_time = obs.t.reshape(n_turns, positions_per_turn).mean(axis=1)
    return RedundantResult(tuple(labels), az, turn_time, est, source, mean, std)


# -- repeatability ------------------------------------------

def repeatability(means: np.ndarray) -> tuple[float, np.ndarray]:
    """Thesis repeatability of sequence means (rad): max |mean_j - grand mean| and each distance.

    ``means`` (J,) rad, the mean azimuth of each sequence (tables 4.3, 4.4; Fig. 4.14-4.23).
    """
    means = np.asarray(means, float)
    dist = angle_diff(means, circular_mean(means))
    return float(np.max(np.abs(dist))), dist
