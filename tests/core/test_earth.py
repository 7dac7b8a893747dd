import numpy as np

from workbench.earth import EARTH_RATE, earth_rate_ned, horizontal_earth_rate, normal_gravity, rz


def test_normal_gravity_matches_wgs84_equator_and_pole():
    # WGS-84 (NIMA TR8350.2 table 3.4): gamma_e = 9.7803253359, gamma_p = 9.8321849378 m/s^2
    assert abs(normal_gravity(0.0) - 9.7803253) < 1e-6
    assert abs(normal_gravity(np.pi / 2) - 9.8321849) < 1e-6


def test_normal_gravity_height_gradient_is_free_air():
    # free-air gradient ~ -3.086e-6 s^-2 near the surface
    grad = (normal_gravity(0.7, 100.0) - normal_gravity(0.7, 0.0)) / 100.0
    assert abs(grad + 3.086e-6) < 0.01e-6


def test_earth_rate_components():
    lat = np.radians(40.8)
    w = earth_rate_ned(lat)
    assert np.isclose(np.linalg.norm(w), EARTH_RATE, rtol=1e-12)
    assert np.isclose(w[0], horizontal_earth_rate(lat)) and w[1] == 0.0 and w[2] < 0  # up component is -down


def test_rz_positive_is_clockwise_from_above():
    # table-zero (x) turned by +90 deg about down points east in NED
    assert np.allclose(rz(np.pi / 2).apply([1.0, 0.0, 0.0]), [0.0, 1.0, 0.0], atol=1e-12)
