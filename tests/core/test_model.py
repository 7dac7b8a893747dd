import numpy as np
import pytest

from workbench.errors import CalibrationFormatError
from workbench.model import ThermalModel, TriadModel


def random_model(rng: np.random.Generator) -> TriadModel:
    return TriadModel(
        bias=rng.normal(0, 0.05, 3),
        scale_misalignment=rng.normal(0, 0.01, (3, 3)),
        nonlinearity=rng.normal(0, 1e-3, 3),
        g_sensitivity=rng.normal(0, 1e-4, (3, 3)),
        thermal=ThermalModel(25.0, rng.normal(0, 1e-3, (3, 4)), rng.normal(0, 1e-5, (3, 3))),
    )


@pytest.mark.parametrize("seed", range(5))
def test_round_trip_measured_compensated_measured(seed):
    rng = np.random.default_rng(seed)
    m = random_model(rng)
    true = rng.normal(0, 3.0, (1000, 3))
    f = rng.normal(0, 9.8, (1000, 3))
    temp = rng.uniform(-40, 85, 1000)
    measured = m.apply(true, f, temp)
    back = m.compensate(measured, f, temp)
    assert np.max(np.abs(back - true) / np.maximum(np.abs(true), 1.0)) < 1e-12
    again = m.apply(back, f, temp)
    assert np.max(np.abs(again - measured) / np.maximum(np.abs(measured), 1.0)) < 1e-12


def test_definition_of_terms():
    # bias and M as documented: measured = (I + M) true + b
    m = TriadModel(bias=[1, 2, 3], scale_misalignment=np.diag([0.1, 0, 0]))
    assert np.allclose(m.apply(np.array([[1.0, 0, 0]])), [[2.1, 2, 3]])
    th = ThermalModel(20.0, bias_poly=np.array([[0, 1.0], [0, 0], [0, 0]]))
    mt = TriadModel(thermal=th)
    assert np.allclose(mt.apply(np.zeros((1, 3)), temperature_c=30.0), [[10.0, 0, 0]])


@pytest.mark.parametrize("kwargs,field", [
    ({"bias": [1, 2]}, "bias"),
    ({"scale_misalignment": np.zeros((2, 3))}, "scale_misalignment"),
    ({"bias": [np.nan, 0, 0]}, "bias"),
    ({"scale_misalignment": -np.eye(3)}, "singular"),
])
def test_bad_models_are_refused(kwargs, field):
    with pytest.raises(CalibrationFormatError, match=field):
        TriadModel(**kwargs)
