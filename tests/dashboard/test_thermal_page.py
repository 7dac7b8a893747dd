"""AppTest of the thermal page (dashboard/pages/60_thermal.py) on a small simulated soak session."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

from streamlit.testing.v1 import AppTest

PAGE = Path(__file__).resolve().parents[2] / "dashboard" / "pages" / "60_thermal.py"


def test_thermal_page_shows_models_and_exports(seeded_db, tmp_path):
    from procedures import thermal as proc
    from workbench.grades import draw_unit, load_spec
    from workbench.jobs import simulate

    spec = load_spec("industrial_mems")
    truth = replace(draw_unit(spec, 5), sample_rate_hz=5.0, thermal_time_constant_s=30.0)
    run = tmp_path / "runs" / "20260101T000000_thermal_industrial_mems"
    run.mkdir(parents=True)
    (run / "job.json").write_text(json.dumps({"procedure": "thermal"}))
    seq = proc.sequence(spec, t_min_c=10.0, t_max_c=40.0, step_c=15.0, dwell_s=5.0)  # three soaks
    simulate(seq, truth, 5, out_dir=run / "output")
    at = AppTest.from_file(str(PAGE), default_timeout=120).run()
    assert not at.exception
    assert "Thermal sweeps" in [t.value for t in at.title]
    models = at.dataframe[0].value
    assert set(models.quantity) >= {"gyro.bias", "accel.bias", "accel.scale"}
    assert models["held-out RMS"].str.contains("°/h").any()  # lab units of workbench.units (gyro bias °/h)
    assert any(c.value.startswith("# PX4 parameters") for c in at.code)
