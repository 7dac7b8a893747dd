"""The campaign (workbench/jobs.py run_campaign): order, options handed on, merged set against truth."""

import json
import re

import numpy as np
import pytest

from workbench import jobs
from workbench.calset import CalibrationSet, TriadCalibration, Unit
from workbench.grades import draw_unit, load_spec
from workbench.model import TriadModel
from workbench.rigconfig import load_rig_config
from workbench.units import factor


def test_noise_options_take_observed_terms_and_the_upper_bound_of_the_others():
    import procedures.thermal as thermal

    noise = {"gyro": {"bias_instability": [1e-5, 2e-5, 3e-5], "rrw": [None, 4e-7, None],
                      "rrw_ci95": [[0.0, 1e-6], [3e-7, 5e-7], [0.0, 2e-6]]}}
    s = CalibrationSet(Unit("u1", "m"), {"gyro": TriadCalibration(TriadModel(), {})}, noise=noise)
    opts = jobs.noise_options(thermal, [s])
    assert opts["gyro_bias_instability_deg_h"] == pytest.approx(np.array([1e-5, 2e-5, 3e-5]) / factor("deg/h"))
    assert opts["gyro_rrw_deg_h_sqrt_h"] == pytest.approx(np.array([1e-6, 4e-7, 2e-6]) / factor("deg/h/sqrt(h)"))
    assert "accel_bias_instability_mg" not in opts  # the set has no accelerometer noise


def test_campaign_runs_allan_first_and_hands_its_noise_on(tmp_path):
    spec = load_spec("industrial_mems")
    truth = draw_unit(spec, 3)
    cfg = load_rig_config("sim")
    result = jobs.run_campaign(spec, truth, cfg, 3, tmp_path, only=["allan", "multiposition"],
                               options={"allan": {"duration_s": 1800.0, "soak": False},
                                        "multiposition": {"dwell_s": 20.0}})
    campaign = json.loads((tmp_path / "campaign.json").read_text())
    assert campaign["procedures"] == ["allan", "multiposition"]
    b = result.results["allan"].calibration.noise["gyro"]["bias_instability"]
    handed = campaign["analysis_options"]["multiposition"]["gyro_bias_instability_deg_h"]
    assert handed == pytest.approx(np.array(b) / factor("deg/h"))
    # the merged set against the unit's truth at the ambient (23 °C, no soak): within 4 sigma
    # (issue 5's bound; the sigmas include the bias-instability floor handed on above)
    merged = CalibrationSet.load(tmp_path / "calibration.json")
    for triad in ("accel", "gyro"):
        m = getattr(truth, triad)
        true_bias = m.bias + m.thermal.bias_shift(np.array([cfg.chamber.initial_c]))[0]
        z = (merged.model(triad).bias - true_bias) / merged.triads[triad].sigma_of("bias")
        assert np.all(np.abs(z) < 4.0), (triad, z)


def _outputs(root) -> dict:
    """Every result, set and figure file under ``root`` (sessions left out), ids and times removed."""
    ignored = {"id", "created", "calibration_id", "session_id", "sha256", "path"}
    uuid = re.compile(r"^[0-9a-f]{8}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{12}$")

    def clean(x):
        if isinstance(x, dict):
            return {k: clean(v) for k, v in x.items() if k not in ignored}
        if isinstance(x, str) and uuid.match(x):
            return "<id>"
        return [clean(v) for v in x] if isinstance(x, list) else x
    out = {}
    for f in sorted(root.rglob("*")):
        if f.is_file() and "session" not in f.relative_to(root).parts:
            out[str(f.relative_to(root))] = clean(json.loads(f.read_text())) if f.suffix == ".json" else f.read_bytes()
    return out


def test_campaign_in_two_processes_writes_what_it_writes_in_one(tmp_path):
    # the same seed gives the same numbers (and figure bytes) whichever process ran which step;
    # multiposition waits for the Allan B, the magnetometer does not
    spec = load_spec("industrial_mems")
    truth = draw_unit(spec, 6)
    options = {"allan": {"duration_s": 900.0, "soak": False}, "multiposition": {"dwell_s": 5.0}}
    runs = {}
    for workers in (1, 2):
        res = jobs.run_campaign(spec, truth, load_rig_config("sim"), 6, tmp_path / str(workers),
                                only=["allan", "multiposition", "magnetometer"], options=options, workers=workers)
        assert list(res.results) == ["allan", "multiposition", "magnetometer"]
        assert set(res.usage["multiposition"]) == {"record", "analyse", "figures"}
        runs[workers] = _outputs(tmp_path / str(workers))
    assert any(name.endswith(".png") for name in runs[1])
    assert runs[2].keys() == runs[1].keys()
    for name in runs[1]:
        assert runs[2][name] == runs[1][name], name
