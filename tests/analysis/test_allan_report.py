"""AllanAnalysis follows the result protocol: to_dict (SI) and summary (lab units) of one record."""

import json
import math

import numpy as np

from workbench import units
from workbench.analysis.allan_fit import AllanAnalysis as Reexported
from workbench.analysis.allan_fit import analyze_record
from workbench.analysis.allan_report import AllanAnalysis
from workbench.analysis.allan_terms import TERMS
from workbench.result import AnalysisResult

N_TRUE = 1e-3  # rad/s/sqrt(Hz) white rate noise, 3.44 °/√h


def _analysis():
    rng = np.random.default_rng(11)
    y = N_TRUE * math.sqrt(100.0) * rng.standard_normal((60_000, 3))
    return analyze_record(y, 100.0, ["gx", "gy", "gz"], "gyro", "octave")


def test_protocol_and_reexport():
    an = _analysis()
    assert Reexported is AllanAnalysis and isinstance(an, AnalysisResult)
    assert an.warnings == ()


def test_to_dict_is_json_and_si():
    an = _analysis()
    d = json.loads(json.dumps(an.to_dict()))
    assert list(d) == ["tau_s", "adev", "adev_lo", "adev_hi", "edf", "alpha", "terms", "tau_range_s", "read_off",
                       "chi2_red"]
    k = len(d["tau_s"])
    assert np.shape(d["adev"]) == (3, k) and np.shape(d["adev_lo"]) == (3, k) and list(d["tau_range_s"]) == list(TERMS)
    assert np.all(np.array(d["adev_lo"]) <= np.array(d["adev"])) and np.all(np.array(d["adev"]) <= d["adev_hi"])
    # 60 000 samples: the white-noise fit's relative sigma is about 1/sqrt(2 * 0.5 * 60000 / CORRELATION) < 1 %;
    # 4 % is > 4 sigma for each of the three axes (SI: rad/s/sqrt(Hz), not °/√h)
    assert np.allclose(d["terms"]["arw"], N_TRUE, rtol=0.04)
    assert d["terms"] == an.noise_block()


def test_summary_one_labelled_line_per_axis_in_lab_units():
    an = _analysis()
    lines = an.summary()
    assert [line.split(":")[0] for line in lines] == ["gyro gx", "gyro gy", "gyro gz"]
    for line, f in zip(lines, an.fits):
        value = units.to_unit(f.terms["white"].value, units.unit_of("gyro", "white"))
        assert f"N {value:.3g} °/√h [" in line  # lab unit, with its interval
        assert abs(value - 3.44) < 0.15  # 4 % of 3.44 °/√h, as above
