"""Reading sensor-grade fixtures (workbench.grade_fixtures): lab-unit keys to SI, errors naming the field."""

import numpy as np
import pytest

from workbench.grade_fixtures import grade_names, load_spec
from workbench.grade_types import SensorSpec, SpecError
from workbench.units import DEG, G0, HOUR


def test_lab_unit_keys_become_si():
    spec = load_spec("industrial_mems")  # gyro: range 450 °/s, bias 360 °/h, SF 3000 ppm, G 36 °/h/g
    assert isinstance(spec, SensorSpec) and "industrial_mems" in grade_names()
    g = spec.specs["gyro"]
    assert g.range == pytest.approx(450 * DEG)
    assert g.bias == pytest.approx(np.full(3, 360 * DEG / HOUR))
    assert g.scale_factor == pytest.approx(np.full(3, 3000e-6))
    assert g.g_sensitivity == pytest.approx(np.full(3, 36 * DEG / HOUR / G0))


def test_an_unknown_unit_names_the_file_and_key(tmp_path):
    from workbench.grade_types import FIXTURES

    p = tmp_path / "bad.yaml"
    good = (FIXTURES / "industrial_mems.yaml").read_text()
    assert "  bias_deg_per_h: 360\n" in good
    p.write_text(good.replace("  bias_deg_per_h: 360\n", "  bias_furlongs: 360\n", 1))
    with pytest.raises(SpecError, match=r"bad\.yaml.*bias_furlongs"):
        load_spec(p)
