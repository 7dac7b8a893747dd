"""Rig configuration: a strict schema, checked before anything moves (issue 16, rig safety)."""

import copy
import math
from pathlib import Path

import pytest
import yaml

from workbench.cli import main
from workbench.errors import WorkbenchError
from workbench.rigconfig import RIGS_DIR, load_rig_config, rig_config_from_dict
from workbench.rigschema import schema_markdown

HIL = yaml.safe_load((RIGS_DIR / "hil.yaml").read_text())
DOC = Path(__file__).resolve().parents[2] / "docs" / "rigs.md"


def _refused(change, match: str) -> None:
    d = copy.deepcopy(HIL)
    change(d)
    with pytest.raises(WorkbenchError, match=match) as info:
        rig_config_from_dict(d, "lab.yaml")
    assert "\n" not in str(info.value) and str(info.value).startswith("lab.yaml: ")


@pytest.mark.parametrize("path", sorted(RIGS_DIR.glob("*.yaml")), ids=lambda p: p.name)
def test_every_shipped_configuration_is_accepted_with_every_key(path):
    cfg = load_rig_config(path)
    raw = yaml.safe_load(path.read_text())
    assert math.isclose(cfg.turntable.max_rate, math.radians(raw["turntable"]["max_rate_dps"]))
    assert cfg.chamber.safe_c == raw["chamber"]["safe_c"] and cfg.site.latitude_deg == raw["site"]["latitude_deg"]
    for section in ("table_controller", "chamber_controller", "imu_stream", "fixture", "hil"):
        assert cfg.options.get(section) == raw.get(section)  # device sections as written, every key kept


def test_a_misspelt_limit_is_refused_with_the_nearest_name():
    # seen: max_rate_dsp ignored, and the table commanded to 405 °/s
    _refused(lambda d: d["turntable"].update(max_rate_dsp=405.0),
             r"turntable: unknown key 'max_rate_dsp'; did you mean 'max_rate_dps'\?")
    _refused(lambda d: d.update(chamber_contoller={}), r"did you mean 'chamber_controller'")
    _refused(lambda d: d["imu_stream"].update(max_corupt_frames=1), r"imu_stream: .*did you mean 'max_corrupt_frames'")


@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf])
def test_a_non_finite_rate_limit_is_refused(value):
    # seen: max_rate_dps: .nan let 810 °/s run
    _refused(lambda d: d["turntable"].update(max_rate_dps=value), r"turntable.max_rate_dps: .* is not a finite number")


def test_nan_from_yaml_text(tmp_path):
    text = (RIGS_DIR / "hil.yaml").read_text().replace("max_rate_dps: 1000.0", "max_rate_dps: .nan")
    (tmp_path / "nan.yaml").write_text(text)
    with pytest.raises(WorkbenchError, match="max_rate_dps: nan is not a finite number"):
        load_rig_config(tmp_path / "nan.yaml")


def test_a_safe_setpoint_outside_the_chamber_range_is_refused():
    # seen: safe_c 120 with max_c 85: on an interlock the runner sent 120 °C and called it safe
    _refused(lambda d: d["chamber"].update(safe_c=120.0, max_c=85.0), r"chamber: safe_c 120 °C outside min_c..max_c")
    _refused(lambda d: d["chamber"].update(initial_c=-60.0), r"chamber: initial_c -60 °C outside")
    _refused(lambda d: d["chamber"].update(min_c=85.0, max_c=85.0), r"min_c 85 °C must be below max_c 85 °C")


def test_latitude_out_of_range_is_refused_before_anything_runs():
    # seen: latitude 200 found only after the whole sequence was recorded
    _refused(lambda d: d["site"].update(latitude_deg=200.0), r"site.latitude_deg: 200.0 must be <= 90")
    _refused(lambda d: d["site"].update(latitude_deg=-90.5), r"site.latitude_deg: -90.5 must be >= -90")


@pytest.mark.parametrize("section,key,value,match", [
    ("turntable", "encoder_resolution_deg", 0.0, "must be > 0"),
    ("turntable", "settle_s", -0.1, "must be >= 0"),
    ("turntable", "max_accel_dps2", -5.0, "must be > 0"),
    ("chamber", "max_ramp_c_per_min", 0.0, "must be > 0"),
    ("turntable", "max_rate_dps", "fast", "valid number"),
    ("turntable", "max_rate_dps", True, "valid number"),
])
def test_limits_positive_and_numbers(section, key, value, match):
    _refused(lambda d: d[section].update({key: value}), rf"{section}.{key}: .*{match}")


@pytest.mark.parametrize("section,key", [("turntable", None), ("chamber", None), ("turntable", "max_rate_dps"),
                                         ("chamber", "safe_c"), ("chamber", "max_c")])
def test_a_real_rig_states_its_limits(section, key):
    def drop(d):
        d.pop(section) if key is None else d[section].pop(key)
    _refused(drop, rf"a real rig must state {section}\.")


def test_the_simulated_rig_keeps_its_defaults():
    cfg = rig_config_from_dict({"driver": "sim", "site": {"latitude_deg": 45.0}})
    assert cfg.chamber.safe_c == 23.0 and math.isclose(cfg.turntable.max_rate, math.radians(1000.0))


def test_device_sections_checked_too():
    _refused(lambda d: d["chamber_controller"].update(driver="telnet"), "unknown driver 'telnet'")
    _refused(lambda d: d["table_controller"]["commands"].update(position="POS {angle_deg.__class__}"),
             r"commands.position: .*not a plain name")
    _refused(lambda d: d["table_controller"].update(replies={"no_error": "(("}), "not a regular expression")
    _refused(lambda d: d["imu_stream"].update(sync="zz"), "not hex")


def test_dry_run_checks_the_configuration_and_the_plan(tmp_path, capsys):
    bad = copy.deepcopy(HIL)
    bad["turntable"]["max_rate_dsp"] = 405.0
    (tmp_path / "bad.yaml").write_text(yaml.safe_dump(bad))
    assert main(["run", "multiposition", "--rig", str(tmp_path / "bad.yaml"), "--dry-run"]) == 2
    assert "did you mean 'max_rate_dps'" in capsys.readouterr().err
    slow = {"driver": "sim", "site": {"latitude_deg": 40.0}, "turntable": {"max_rate_dps": 10.0}}
    (tmp_path / "slow.yaml").write_text(yaml.safe_dump(slow))
    assert main(["run", "rate", "--rig", str(tmp_path / "slow.yaml"), "--dry-run"]) == 2
    assert "exceeds the limit 10.0 °/s" in capsys.readouterr().err


def test_rig_check_refuses_a_bad_configuration(tmp_path, capsys):
    bad = copy.deepcopy(HIL)
    bad["site"]["latitude_deg"] = 200
    (tmp_path / "bad.yaml").write_text(yaml.safe_dump(bad))
    for cmd in (["rig", "check"], ["rig", "hil"]):
        assert main([*cmd, str(tmp_path / "bad.yaml")]) == 2
        assert "site.latitude_deg: 200 must be <= 90" in capsys.readouterr().err


def test_docs_list_every_key_generated_from_the_schema():
    text = DOC.read_text()
    begin, end = "<!-- rig keys: begin -->\n", "<!-- rig keys: end -->"
    assert text[text.index(begin) + len(begin):text.index(end)] == schema_markdown(), \
        "docs/rigs.md is out of date: python -m workbench.rigschema --write"
