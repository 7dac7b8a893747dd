"""Thermal estimators on synthetic arrays and small simulated sessions (workbench/analysis/thermal.py)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from workbench.analysis import thermal as th
from workbench.errors import AnalysisError, SessionError
from workbench.grades import draw_unit, load_spec

DEG = np.pi / 180
MG = 9.80665e-3
SPEC = load_spec("industrial_mems")
# soak profile of the issue: -40..+85 °C in 15 °C steps (85 added as the end point), up then down
UP = [*np.arange(-40.0, 85.0, 15.0), 85.0]
TEMPS = np.array(UP + UP[-2::-1])
DIRECTION = np.array([1] * len(UP) + [-1] * (len(UP) - 1))
GAP = np.radians(0.05)  # simulated up-minus-down gyro bias hysteresis, rad/s


def soak_means(seed: int, triad: str, what: str, sigma: float) -> np.ndarray:
    """Per-soak values of a drawn unit (truth + the branch term + seeded noise of ``sigma``)."""
    truth = draw_unit(SPEC, seed)
    m = getattr(truth, triad)
    if what == "bias":
        clean = m.bias + m.thermal.bias_shift(TEMPS)
        if triad == "gyro":
            clean = clean + 0.5 * DIRECTION[:, None] * GAP
    else:
        clean = np.diag(m.scale_misalignment) + m.thermal.scale_shift(TEMPS)
    return clean + np.random.default_rng(1000 + seed).normal(0.0, sigma, clean.shape)


# Noise of one soak mean, taken from the simulated sweep (tests/analysis/test_thermal_sim.py):
# gyro bias 0.003 °/s (bias instability 8 °/h and rate random walk over the sweep dominate the
# 10 s static means), accel bias 0.15 mg, scale factors 40 ppm (six 10 s positions at 10 Hz).
SIGMAS = {("gyro", "bias"): 0.003 * DEG, ("accel", "bias"): 0.15 * MG, ("accel", "scale"): 40e-6}
TRUE_ORDER = {"bias": 3, "scale": 2}  # industrial_mems: cubic bias, quadratic scale factor


@pytest.mark.parametrize("triad,what", list(SIGMAS))
def test_order_chosen_correctly_in_nine_of_ten_seeds(triad, what):
    sigma = SIGMAS[(triad, what)]
    chosen = []
    for seed in range(10):
        y = soak_means(seed, triad, what, sigma)
        fit = th.fit_thermal_poly(TEMPS, y, np.full(y.shape, sigma), DIRECTION, t_ref_c=25.0,
                                  quantity=f"{triad}.{what}", per_axis=False)  # one order for the triad
        chosen.append(fit.order)
        assert fit.cv_rms.shape == (6, 3)  # held-out residual reported for every order 0..5
    assert sum(k == TRUE_ORDER[what] for k in chosen) >= 9, chosen


def test_coefficients_and_hysteresis_within_their_sigma():
    sigma = SIGMAS[("gyro", "bias")]
    truth = draw_unit(SPEC, 3).gyro
    y = soak_means(3, "gyro", "bias", sigma)
    fit = th.fit_thermal_poly(TEMPS, y, np.full(y.shape, sigma), DIRECTION, order=3, hysteresis="on")
    true = np.column_stack([truth.bias, truth.thermal.bias_poly[:, 1:]])
    # 4-sigma bound per coefficient (12 coefficients: false alarm ~1e-3)
    assert np.all(np.abs(fit.coeffs - true) < 4 * fit.coeffs_sigma)
    assert np.all(np.abs(fit.hysteresis - GAP) < 4 * fit.hysteresis_sigma)
    # hysteresis sigma ~ sigma * sqrt(4 / N) for N points split over two branches
    assert np.all(fit.hysteresis_sigma < 2 * sigma * np.sqrt(4 / len(TEMPS)))
    # held-out residual at the chosen order is the noise: sigma, within a factor 2 either way
    assert np.all((fit.cv_rms_chosen > sigma / 2) & (fit.cv_rms_chosen < 2 * sigma))


def test_hysteresis_term_only_kept_when_it_lowers_the_held_out_residual():
    sigma = SIGMAS[("accel", "bias")]
    y = soak_means(4, "accel", "bias", sigma)  # no hysteresis in the accel truth
    fit = th.fit_thermal_poly(TEMPS, y, np.full(y.shape, sigma), DIRECTION)
    modelled = fit.hysteresis_modelled
    assert np.all(np.where(modelled, fit.cv_rms_hysteresis[fit.order] < fit.cv_rms[fit.order], True))
    assert np.all(np.abs(fit.hysteresis) < 4 * fit.hysteresis_sigma)  # reported, consistent with zero
    g = th.fit_thermal_poly(TEMPS, soak_means(4, "gyro", "bias", SIGMAS[("gyro", "bias")]),
                            np.full((len(TEMPS), 3), SIGMAS[("gyro", "bias")]), DIRECTION)
    assert g.hysteresis_modelled.all()  # a 0.05 °/s gap is 17 sigma: the term must be kept
    assert np.all(np.abs(g.hysteresis - GAP) < 0.2 * GAP)


def test_too_few_temperatures_for_the_order():
    t = np.array([-10.0, 20.0, 50.0])
    with pytest.raises(AnalysisError, match="3 distinct temperature.*order 3 needs at least 4"):
        th.fit_thermal_poly(t, np.zeros((3, 3)), order=3, quantity="gyro.bias")
    fit = th.fit_thermal_poly(t, np.outer(t, [1e-4, 2e-4, 3e-4]), quantity="gyro.bias")
    assert fit.order <= 1 and any("cannot be cross-validated" in w for w in fit.warnings)
    point = th.SoakPoint("gyro", 0, (1,), 20.0, 20.0, 0.0, 100.0, 1, np.zeros(3), np.ones(3), np.zeros(3),
                         np.full(3, np.nan), True)
    with pytest.raises(AnalysisError, match=r"soak steps 0, 7.*order 2 needs at least 3"):
        th.fit_soaks({"gyro": [point, replace(point, soak_step=7, setpoint_c=40.0, temperature_c=40.0)]}, order=2)


def test_settling_time_of_a_first_order_lag():
    # unit temperature after a 15 °C step with time constant tau: rate 15/tau e^(-t/tau);
    # it falls below tol at t* = tau ln(15 * 60 / (tau * tol)); the detector reports t* plus at
    # most one window (trailing slope) and the 1/10-window bins
    tau, tol, window = 300.0, 0.05, 120.0
    t = np.arange(0.0, 3000.0, 0.5)
    temp = 20.0 + 15.0 * (1 - np.exp(-t / tau))
    st = th.settling(t, temp, tol, window)
    t_star = tau * np.log(15 * 60 / (tau * tol))
    assert st.settled and t_star - window / 10 <= st.t_settled <= t_star + window
    ramp = th.settling(t, 20.0 + 0.2 / 60 * t, tol, window)  # 0.2 °C/min: never settles
    assert not ramp.settled and ramp.t_settled is None and abs(ramp.final_rate_c_per_min - 0.2) < 1e-6


# -- small simulated sessions for the bad-input paths (10 Hz, thermal time constant 30 s) ---------
@pytest.fixture(scope="module")
def small_soak_session():
    from procedures import thermal as proc
    from workbench.jobs import simulate

    truth = replace(draw_unit(SPEC, 5), sample_rate_hz=10.0, thermal_time_constant_s=30.0)
    seq = proc.sequence(SPEC, t_min_c=-10.0, t_max_c=50.0, step_c=15.0, dwell_s=5.0)
    session, _ = simulate(seq, truth, 5)
    return session


def test_missing_temperature_column_names_the_steps(small_soak_session):
    s = replace(small_soak_session, samples=small_soak_session.samples.drop(columns=["temp"]))
    with pytest.raises(SessionError, match=r"column temp .*step\(s\) 0, 7"):
        th.analyze_thermal(s)


def test_unsettled_soak_is_named_and_left_out(small_soak_session):
    s = small_soak_session
    groups = th.soak_groups(s)
    g = groups[2]
    samples = s.samples.copy()
    sel = np.isin(samples["step"].to_numpy(), [g.soak_step, *g.steps])
    t = samples.loc[sel, "t"].to_numpy()
    samples.loc[sel, "temp"] += 0.5 / 60 * (t - t[0])  # still drifting at 0.5 °C/min
    res = th.analyze_thermal(replace(s, samples=samples))
    assert any(f"step {g.soak_step} (soak" in w and "did not settle" in w for w in res.warnings)
    assert not res.soak_points["gyro"][2].settled
    assert len(res.fits["gyro.bias"].temperature_c) == len(groups) - 1


def test_ramp_too_fast_for_the_thermal_lag_is_named():
    from procedures import thermal as proc
    from workbench.jobs import simulate

    # unit time constant 600 s; a 5 °C/min ramp over 20 °C lasts 4 min: the unit moves ~6 °C
    truth = replace(draw_unit(SPEC, 6), sample_rate_hz=5.0, thermal_time_constant_s=600.0)
    seq = proc.sequence(SPEC, profile="ramp", t_min_c=23.0, t_max_c=43.0, ramp_c_per_min=5.0)
    session, _ = simulate(seq, truth, 6)
    _, warnings = th.ramp_series(session, "gyro", window_s=30.0)
    assert any(w.startswith("step 1 (ramp") and "too fast for the unit's thermal lag" in w for w in warnings)


def test_ramp_fit_carries_the_random_walk():
    from procedures import thermal as proc
    from workbench.jobs import simulate

    truth = replace(draw_unit(SPEC, 6), sample_rate_hz=5.0, thermal_time_constant_s=60.0)
    seq = proc.sequence(SPEC, profile="ramp", t_min_c=20.0, t_max_c=40.0, ramp_c_per_min=1.0)
    session, _ = simulate(seq, truth, 6)
    k = np.full(3, 1e-6)  # rad/s/√s
    plain = th.analyze_thermal(session, ("gyro",), t_ref_c=30.0, order=1)
    walked = th.analyze_thermal(session, ("gyro",), t_ref_c=30.0, order=1, bias_rrw={"gyro": k})
    p, w = plain.fits["gyro.bias"].coeffs_sigma, walked.fits["gyro.bias"].coeffs_sigma
    assert np.all(w >= p)  # never narrower than the fit's own sigma
    # The ramp passes 30 °C about 10 min after it starts (1 °C/min from 20 °C, the unit lagging
    # 1 min): the straight line through the windows takes the walk since power-on there, K sqrt(t)
    # with t between the ramp's start and 720 s after it (measured: t = 830 s, 466 s into the ramp).
    # On x the fit's own sigma is below it, on y and z the held-out floor is above it.
    t0 = session.steps_of_kind("ramp")[0].t_start - session.samples["t"].iloc[0]
    assert k[0] * np.sqrt(t0) < w[0, 0] < k[0] * np.sqrt(t0 + 720.0)
    assert p[0, 0] < k[0] * np.sqrt(t0) and np.all(w[1:, 0] == p[1:, 0])


def test_coefficients_carry_the_random_walk_since_power_on():
    # Seven soaks 35 min apart, a gyro bias random walk K = 1e-5 rad/s/√s (124 °/h/√h: only its
    # ratio to the soak noise matters) and white soak noise 2e-5 rad/s. The cubic absorbs the
    # walk: its value at t_ref is off by the walk since power-on, and the climbing sweep turns
    # the walk into slope and curvature (the walk at the last soak, sigma K sqrt(14600 s) =
    # 1.2e-3 rad/s, is 60x the soak noise).
    k, sigma_soak = 1e-5, 2e-5
    temps = np.arange(-10.0, 51.0, 10.0)
    elapsed = 2000.0 + 2100.0 * np.arange(len(temps))
    true = np.array([1e-3, 2e-5, 1e-6, 0.0])  # rad/s, per °C, per °C², per °C³ about 23 °C
    z_plain, z_walk = [], []
    for seed in range(400):
        rng = np.random.default_rng(seed)
        walk = np.cumsum(rng.normal(0.0, k * np.sqrt(np.diff(np.r_[0.0, elapsed]))))
        values = np.polyval(true[::-1], temps - 23.0) + walk + rng.normal(0.0, sigma_soak, len(temps))
        points = [th.SoakPoint("gyro", i, (i,), t, t, 0.0, 100.0, 1, np.full(3, v), np.full(3, sigma_soak),
                               np.full(3, np.nan), np.full(3, np.nan), True, e)
                  for i, (t, v, e) in enumerate(zip(temps, values, elapsed))]
        fit = th.fit_soaks({"gyro": points}, 23.0, order=3)["gyro.bias"]
        walked = th.with_bias_random_walk(fit, temps, elapsed, k)
        z_plain.append((fit.coeffs[0] - true) / fit.coeffs_sigma[0])
        z_walk.append((walked.coeffs[0] - true) / walked.coeffs_sigma[0])
    # an honest sigma gives sum(z^2) ~ chi2(400) per coefficient: rms z within
    # sqrt(chi2_0.001..0.999(400) / 400) = 0.89..1.11. Without the walk the sigmas are the
    # fit's alone (measured rms 2.3, 3.6, 2.7, 2.2); with it 1.00, 0.97, 1.05, 0.97.
    rms_plain = np.sqrt(np.mean(np.square(z_plain), axis=0))
    rms_walk = np.sqrt(np.mean(np.square(z_walk), axis=0))
    assert np.all(rms_plain > 1.11), rms_plain
    assert np.all((0.89 < rms_walk) & (rms_walk < 1.11)), rms_walk


def test_hidden_bias_instability_is_one_warning_per_triad(small_soak_session):
    # 5-s dwells at 10 Hz cannot show the grade's bias instability (8 °/h, 2 m/s/h): each soak's
    # fit could hide it, and the sweep says so once per triad, naming the soaks; given B, not at all
    points, warnings = th.soak_points(small_soak_session)
    hidden = [w for w in warnings if "would not show" in w]
    assert 1 <= len(hidden) <= 2 and all(w.startswith("soak steps ") for w in hidden)
    b = {"gyro": 8 * DEG / 3600, "accel": 2 / 3600}
    _, warnings = th.soak_points(small_soak_session, bias_instability=b)
    assert not [w for w in warnings if "would not show" in w]


def test_order_per_axis_lowest_the_noise_explains():
    """Campaign-like sweep (7 soaks, -10..50 °C): x truly cubic, y and z quadratic (the grade's scale-factor
    law). Per axis, x gets order 3 and y, z order 2; a common order would impose x's order on y and z.

    Truth: the drawn unit's quadratic scale law plus 2e-7 /°C³ on x (30³ * 2e-7 = 5400 ppm at the ends,
    far above the 40 ppm soak noise: always detectable). The one-standard-error rule alone, with 7
    folds, picked a higher order than the truth on about 1 quadratic axis in 5 (4 of 20 with these
    seeds); capped at the lowest order the soak sigmas explain (chi-squared 95 %) it does so on about
    1 in 30 (19 of 600 in a 300-unit run), so at most 2 of these 20 (binomial tail 3 %). A quadratic
    term smaller than the noise (under 40 ppm at the sweep's ends: seeds 7 z and 9 y) is rightly left
    out: order 1 there.
    """
    from workbench.model import ThermalModel

    temps, sigma = np.arange(-10.0, 51.0, 10.0), 40e-6
    per_axis, common = [], []
    for seed in range(10):
        m = draw_unit(SPEC, seed).accel
        poly = np.column_stack([m.thermal.scale_poly, np.zeros((3, 2))])
        poly[0, 3] = 2e-7
        clean = np.diag(m.scale_misalignment) + ThermalModel(m.thermal.t_ref_c, m.thermal.bias_poly, poly).scale_shift(temps)
        y = clean + np.random.default_rng(2000 + seed).normal(0.0, sigma, clean.shape)
        s = np.full(y.shape, sigma)
        per_axis.append(th.fit_thermal_poly(temps, y, s, t_ref_c=23.0, quantity="accel.scale").orders)
        common.append(th.fit_thermal_poly(temps, y, s, t_ref_c=23.0, quantity="accel.scale", per_axis=False).orders)
    per_axis, common = np.array(per_axis), np.array(common)
    assert np.all(per_axis[:, 0] == 3)
    assert np.sum(per_axis[:, 1:] > 2) <= 2, per_axis
    m = np.array([draw_unit(SPEC, seed).accel.thermal.scale_poly[:, 2] for seed in range(10)])
    below_noise = np.abs(m[:, 1:]) * 30.0**2 < sigma  # quadratic shift at the ends under the soak noise
    assert np.all((per_axis[:, 1:] == 2) | ((per_axis[:, 1:] == 1) & below_noise)), per_axis
    assert np.all(common[:, 1:] >= 3)  # the shared order is x's, too high for y and z
