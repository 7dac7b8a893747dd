"""The virtual IMU against the truth of the simulation and the IEEE 952 closed forms."""

import dataclasses
import json

import allantools
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from workbench.earth import earth_rate_ned, gravity_ned
from workbench.errors import WorkbenchError
from workbench.grades import Hysteresis, NoiseSpec, UnitTruth, draw_unit, grade_names, load_spec
from workbench.sim.noise import FLICKER_AVAR
from workbench.sim.sensor import VirtualIMU

LAT = np.radians(40.8)
MAG_NED = np.array([27.0, 1.5, 38.0])  # µT, a mid-latitude field


def _white_only(truth: UnitTruth) -> UnitTruth:
    """The unit with bias instability and rate random walk removed (white, quantization and
    LSB kept), so the spread of a mean is the white-noise closed form."""
    changes = {}
    for t in truth.triads:
        changes[f"{t}_noise"] = dataclasses.replace(truth.noise_of(t), bias_instability=np.zeros(3), rrw=np.zeros(3))
    return dataclasses.replace(truth, **changes)


def _static_inputs(rot: Rotation, n: int):
    """True body rate, specific force and field (n, 3) for a static attitude (body->NED)."""
    omega = rot.inv().apply(earth_rate_ned(LAT))
    force = rot.inv().apply(-gravity_ned(LAT))  # specific force at rest: minus gravity
    field = rot.inv().apply(MAG_NED)
    return (np.tile(omega, (n, 1)), np.tile(force, (n, 1)), np.tile(field, (n, 1)))


@pytest.mark.parametrize("grade", grade_names())
def test_static_means_match_model(grade):
    # Six attitudes, 10 s each at the reference temperature: the mean output must equal
    # (I+M) x + n ((I+M) x)^2 + b (+ G f for the gyro), written out here independently of
    # TriadModel.apply. Tolerance per axis: 4.5 sigma of the mean of N white samples,
    # sigma^2 = density^2 / T + LSB^2 / (12 N), plus the quantization carry (<= step / T).
    truth = _white_only(draw_unit(load_spec(grade), seed=7))
    t_ref = load_spec(grade).t_ref_c
    imu = VirtualIMU(truth, seed=8)
    n = int(10 * truth.sample_rate_hz)
    duration = n / truth.sample_rate_hz
    attitudes = Rotation.from_euler("xyz", [[0, 0, 0], [180, 0, 0], [90, 0, 0], [-90, 0, 0], [0, 90, 0],
                                            [0, -90, 30]], degrees=True)
    for rot in attitudes:
        omega, force, field = _static_inputs(rot, n)
        out = imu.measure(omega, force, field if "mag" in truth.triads else None, np.full(n, t_ref))
        true_in = {"gyro": omega[0], "accel": force[0], "mag": field[0]}
        for triad in truth.triads:
            model, noise = truth.model_of(triad), truth.noise_of(triad)
            u = (np.eye(3) + model.scale_misalignment) @ true_in[triad]
            expected = u + model.nonlinearity * u**2 + model.bias
            if model.g_sensitivity is not None:
                expected = expected + model.g_sensitivity @ force[0]
            sigma = np.sqrt(noise.white**2 / duration + noise.resolution**2 / (12 * n))
            tol = 4.5 * sigma + np.sqrt(12) * noise.quantization / duration
            err = out[triad].mean(axis=0) - expected
            assert np.all(np.abs(err) < tol), (grade, triad, rot.as_euler("xyz", degrees=True), err / sigma)


@pytest.fixture(scope="module")
def industrial_avar_ratios():
    """Simulated / predicted AVAR per triad at tau = 0.1 s and 20 s, averaged over 36 channels
    (12 industrial_mems units x 3 axes, 400 s at 100 Hz each, static at t_ref)."""
    spec = load_spec("industrial_mems")
    n, taus = 40000, np.array([0.1, 20.0])
    ratios = {"gyro": [], "accel": []}
    for k in range(12):
        truth = draw_unit(spec, seed=100 + k)
        omega, force, field = _static_inputs(Rotation.identity(), n)
        out = VirtualIMU(truth, seed=200 + k).measure(omega, force, field, np.full(n, spec.t_ref_c))
        for triad, values in ratios.items():
            for ax in range(3):
                tau, ad, _, _ = allantools.oadev(out[triad][:, ax], rate=100.0, data_type="freq", taus=taus)
                values.append(ad**2 / _predicted_avar(truth.noise_of(triad), ax, tau))
    return spec, {t: np.sqrt(np.mean(v, axis=0)) for t, v in ratios.items()}


@pytest.mark.parametrize("triad", ["gyro", "accel"])
def test_adev_matches_grade_terms(industrial_avar_ratios, triad):
    # tau = 0.1 s: white noise is > 95 % of the AVAR; tau = 20 s: bias instability is > 75 %.
    # Predicted AVAR = N^2/tau + (2 ln2/pi) B^2 + K^2 tau/3 + 3 Q^2/tau^2 (IEEE 952). The channel
    # scatter gives a 1-sigma of the mean ADEV of ~2.5 % at 20 s: 10 % is a >= 4-sigma acceptance.
    spec, ratios = industrial_avar_ratios
    noise = spec.specs[triad].noise
    white_share = noise.white[0] ** 2 / 0.1 / _predicted_avar(noise, 0, np.array([0.1]))
    bi_share = FLICKER_AVAR * noise.bias_instability[0] ** 2 / _predicted_avar(noise, 0, np.array([20.0]))
    assert white_share[0] > 0.95 and bi_share[0] > 0.75
    assert np.all(np.abs(ratios[triad] - 1) < 0.10), ratios[triad]


def _predicted_avar(noise: NoiseSpec, ax: int, tau: np.ndarray) -> np.ndarray:
    return (noise.white[ax] ** 2 / tau + FLICKER_AVAR * noise.bias_instability[ax] ** 2
            + noise.rrw[ax] ** 2 * tau / 3 + 3 * noise.quantization[ax] ** 2 / tau**2)


def _hysteresis_unit() -> UnitTruth:
    truth = draw_unit(load_spec("hg1700"), seed=3)
    return dataclasses.replace(truth, gyro_hysteresis=Hysteresis(np.radians([0.05, 0.05, 0.05]), 2.0))


def test_same_seed_identical_and_chunked_equals_single_call():
    truth = _hysteresis_unit()  # exercises quantization and the hysteresis state too
    n = 3000
    omega, force, _ = _static_inputs(Rotation.from_euler("x", 30, degrees=True), n)
    temp = 25.0 + 5.0 * np.sin(np.linspace(0, 6, n))
    whole = VirtualIMU(truth, seed=1).measure(omega, force, None, temp)
    again = VirtualIMU(truth, seed=1).measure(omega, force, None, temp)
    chunked_imu = VirtualIMU(truth, seed=1)
    edges = [0, 1, 1000, 1001, 2500, n]
    parts = [chunked_imu.measure(omega[a:b], force[a:b], None, temp[a:b]) for a, b in zip(edges[:-1], edges[1:])]
    other = VirtualIMU(truth, seed=2).measure(omega, force, None, temp)
    for key in ("gyro", "accel", "temp"):
        assert np.array_equal(whole[key], again[key])
        assert np.array_equal(whole[key], np.concatenate([p[key] for p in parts]))
        assert not np.array_equal(whole[key], other[key])
    assert whole["mag"] is None


def test_hysteresis_gap_between_warming_and_cooling():
    # Noise-free unit on a 20 -> 40 -> 20 °C ramp: at 30 °C the gyro bias on the warming branch
    # exceeds the cooling branch by the gap (0.05 °/s), the thermal polynomial cancelling.
    truth = _hysteresis_unit()
    quiet = {f"{t}_noise": NoiseSpec() for t in truth.triads}
    truth = dataclasses.replace(truth, **quiet)
    temp = np.concatenate([np.linspace(20, 40, 2001), np.linspace(40, 20, 2001)[1:]])
    n = temp.size
    omega, force, _ = _static_inputs(Rotation.identity(), n)
    gyro = VirtualIMU(truth, seed=0).measure(omega, force, None, temp)["gyro"]
    up, down = gyro[1000], gyro[3000]  # both at 30 °C
    assert np.allclose(up - down, np.radians(0.05), rtol=1e-9, atol=1e-15)


def test_saturation_and_temperature_sensor():
    truth = draw_unit(load_spec("consumer_9axis"), seed=4)
    n = 20000
    omega = np.tile([0.0, 0.0, 3 * truth.gyro_range], (n, 1))
    _, force, field = _static_inputs(Rotation.identity(), n)
    out = VirtualIMU(truth, seed=5).measure(omega, force, field, np.full(n, 30.0))
    assert np.all(out["gyro"][:, 2] == truth.gyro_range)
    assert np.all(np.abs(out["gyro"]) <= truth.gyro_range)
    # thermometer: N(T, s^2); the sample std of n values has relative sigma 1/sqrt(2n) = 0.5 %
    assert abs(out["temp"].mean() - 30.0) < 4.5 * truth.temp_sensor_noise_c / np.sqrt(n)
    assert abs(out["temp"].std() / truth.temp_sensor_noise_c - 1) < 4.5 / np.sqrt(2 * n)


def test_missing_or_misshapen_input_is_an_error():
    truth = draw_unit(load_spec("consumer_9axis"), seed=4)
    imu = VirtualIMU(truth, seed=5)
    omega, force, field = _static_inputs(Rotation.identity(), 10)
    with pytest.raises(WorkbenchError, match="mag"):
        imu.measure(omega, force, None, np.full(10, 25.0))
    with pytest.raises(WorkbenchError, match="accel"):
        imu.measure(omega, force[:5], field, np.full(10, 25.0))


def test_state_restore_continues_exactly():
    # A recording interrupted after 1200 samples and resumed from the saved (JSON) state in a
    # new VirtualIMU equals the uninterrupted recording.
    truth = _hysteresis_unit()
    n = 2000
    omega, force, _ = _static_inputs(Rotation.identity(), n)
    temp = np.linspace(20, 30, n)
    whole = VirtualIMU(truth, seed=3).measure(omega, force, None, temp)
    first = VirtualIMU(truth, seed=3)
    head = first.measure(omega[:1200], force[:1200], None, temp[:1200])
    resumed = VirtualIMU(truth, seed=99)
    resumed.restore(json.loads(json.dumps(first.state())))
    tail = resumed.measure(omega[1200:], force[1200:], None, temp[1200:])
    for key in ("gyro", "accel", "temp"):
        assert np.array_equal(whole[key], np.concatenate([head[key], tail[key]]))
