"""Import profiles (workbench/importers/profile.py): the shipped profiles load; every malformed key
is refused before any data is read, in one line naming the profile file and the key path."""

import copy
from pathlib import Path

import pytest
import yaml

from workbench.errors import ImportProfileError
from workbench.importers.profile import SINGLE, load_profile, stream_specs, time_base

FIXTURES = Path(__file__).resolve().parents[2] / "fixtures" / "import_profiles"
SINGLE_FILE = FIXTURES / "imucal_ferraris.yaml"
STREAMS = FIXTURES / "marg_mpu6050_hmc5883l.yaml"


def _raw(path: Path) -> dict:
    return yaml.safe_load(path.read_text())


def test_shipped_profiles_load_with_their_streams():
    single = load_profile(SINGLE_FILE)
    assert list(stream_specs(single)) == [SINGLE] and time_base(single) == SINGLE
    assert stream_specs(single)[SINGLE]["rate_hz"] == 102.4
    streams = load_profile(STREAMS)
    assert time_base(streams) == "accel"
    assert set(stream_specs(streams)) == {"accel", "gyro", "temperature", "mag"}


def _set(path: str, value):
    def edit(d):
        keys = path.split(".")
        for k in keys[:-1]:
            d = d[k]
        if value is KeyError:
            del d[keys[-1]]
        else:
            d[keys[-1]] = value
    return edit


# (profile, edit, key path the message names)
CASES = [
    (SINGLE_FILE, _set("format", "workbench-import/9"), "'format'"),
    (SINGLE_FILE, _set("site", KeyError), "missing key 'site'"),
    (SINGLE_FILE, _set("sample_rate_hz", KeyError), "missing key 'sample_rate_hz'"),
    (SINGLE_FILE, _set("sample_rate_hz", "fast"), "sample_rate_hz: expected a finite number"),
    (SINGLE_FILE, _set("sample_rate_hz", True), "sample_rate_hz: expected a finite number"),
    (SINGLE_FILE, _set("site.latitude_deg", 95.0), "site.latitude_deg"),
    (SINGLE_FILE, _set("site.field_norm_ut", 0.0), "site.field_norm_ut"),
    (SINGLE_FILE, _set("columns.gx.unit", "m/s^2"), "columns.gx.unit 'm/s^2' is not a unit of rad/s"),
    (SINGLE_FILE, _set("columns.gx.column", KeyError), "columns.gx: missing key 'column'"),
    (SINGLE_FILE, _set("columns.gq", {"column": "x"}), "columns.gq: unknown target"),
    (SINGLE_FILE, _set("columns.gz", KeyError), "columns: no mapping for gz"),
    (SINGLE_FILE, _set("columns.ax.scale", "x2"), "columns.ax.scale"),
    (SINGLE_FILE, _set("reader.type", "xlsx"), "reader.type 'xlsx'"),
    (SINGLE_FILE, _set("reader.topic", "/imu"), "reader.topic: not a key of a csv reader"),
    (SINGLE_FILE, _set("time.unit", "min"), "time.unit 'min'"),
    (SINGLE_FILE, _set("time.offset", 3), "time.offset: unknown key"),
    (SINGLE_FILE, _set("time.stamps", "arrival"), "time.stamps: needs time.column"),
    (SINGLE_FILE, _set("streams", {}), "columns: give the columns under each stream"),
    (STREAMS, _set("time_base", "imu"), "time_base 'imu'"),
    (STREAMS, _set("streams.mag.file", KeyError), "streams.mag.file: missing"),
    (STREAMS, _set("streams.gyro.rate_hz", -100), "streams.gyro.rate_hz: expected a finite number"),
    (STREAMS, lambda d: (_set("streams.gyro.time", {"unit": "s"})(d), _set("streams.gyro.rate_hz", KeyError)(d)),
     "streams.gyro.rate_hz: expected a finite number"),  # neither a time column nor a rate
    (STREAMS, _set("streams.gyro.range.unit", "g"), "streams.gyro.range.unit 'g' is not a unit of rad/s"),
    (STREAMS, _set("streams.gyro.repeats", "drop"), "streams.gyro.repeats 'drop'"),
    (STREAMS, _set("streams.accel.reader", {"type": "rosbag"}), "streams.accel.reader.topic: missing"),
    (STREAMS, _set("streams.temperature.columns.gx", {"column": "gx_dps", "unit": "deg/s"}),
     "streams.temperature.columns.gx: already given by stream gyro"),
    (STREAMS, _set("streams.accel.columns.gx", {"column": "gx_dps", "unit": "deg/s"}),
     "streams.accel.range: the stream must hold the columns of one triad kind"),
    (STREAMS, _set("reader.trailing_zero_rows", "trim"), "trailing_zero_rows 'trim'"),
    (STREAMS, _set("streams", {}), "streams: no stream"),
    # a misspelt key is refused, never ignored
    (SINGLE_FILE, _set("sampel_rate_hz", 100), "sampel_rate_hz: unknown key"),
    (SINGLE_FILE, _set("columns.gx.scael", -1), "columns.gx.scael: unknown key"),
    (SINGLE_FILE, _set("site.latitude", 40.0), "site.latitude: unknown key"),
    (SINGLE_FILE, _set("unit.serail", "x"), "unit.serail: unknown key"),
    (SINGLE_FILE, _set("sections.flie", "x.json"), "sections.flie: unknown key"),
    (STREAMS, _set("streams.mag.rate", 75), "streams.mag.rate: unknown key"),
    (STREAMS, _set("streams.gyro.range.value_dps", 250), "streams.gyro.range.value_dps: unknown key"),
    # the serial names folders and goes into exports; the model into their comment lines
    (SINGLE_FILE, _set("unit.serial", "../../x"), "unit.serial '../../x': use 1-64 letters"),
    (SINGLE_FILE, _set("unit.serial", [1, 2]), "unit.serial [1, 2]"),
    (SINGLE_FILE, _set("unit.model", "a\n#define X 1"), "unit.model"),
    # a section's step: its turn and mount are checked before any data is read (were tracebacks or NaN rates)
    (SINGLE_FILE, _set("sections.steps.x_rot.turn_deg", "lots"), "sections.steps.x_rot.turn_deg: expected a finite"),
    (SINGLE_FILE, _set("sections.steps.x_rot.turn_deg", float("nan")), "sections.steps.x_rot.turn_deg"),
    (SINGLE_FILE, _set("sections.steps.x_rot.axis", "w"), "sections.steps.x_rot.axis 'w'"),
    (SINGLE_FILE, _set("sections.steps.x_p.mount", "sideways"), "sections.steps.x_p.mount: unknown mount"),
    (SINGLE_FILE, _set("sections.steps.x_p.mount", [["a"]]), "sections.steps.x_p.mount"),
    (SINGLE_FILE, _set("sections.steps.x_p.kind", "wobble"), "sections.steps.x_p.kind 'wobble' is unknown"),
    # pandas takes a longer delimiter as a regular expression (and warns on stderr)
    (SINGLE_FILE, _set("reader.delimiter", ";;"), "reader.delimiter ';;': expected one character"),
    (SINGLE_FILE, _set("reader.skip_rows", -3), "reader.skip_rows: expected a finite number"),
    # the procedure the session is for: a misspelt one was recorded and only failed at analysis
    (SINGLE_FILE, _set("procedure", "feraris"), "procedure 'feraris': unknown procedure (known: "),
    (SINGLE_FILE, _set("procedure", "feraris"), "; did you mean 'ferraris'?"),
    (SINGLE_FILE, _set("procedure", "spin-test"), "procedure 'spin-test': unknown procedure"),
    # YAML 1.1 reads 1e7 (no point, unsigned exponent) as text: 'got '1e7'' alone was a puzzle
    (SINGLE_FILE, _set("sample_rate_hz", "1e2"), "got '1e2' (YAML reads 1e2 as text: write it with a point"),
    (SINGLE_FILE, _set("unit.model", "imu\u202eevil"), "unit.model"),
]


@pytest.mark.parametrize("source,edit,key", CASES, ids=[c[2][:40] for c in CASES])
def test_malformed_key_is_one_line_naming_file_and_key(tmp_path, source, edit, key):
    prof = copy.deepcopy(_raw(source))
    edit(prof)
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(prof))
    with pytest.raises(ImportProfileError) as exc:
        load_profile(path)
    msg = str(exc.value)
    assert "\n" not in msg
    assert str(path) in msg and key in msg, msg


def test_a_registered_procedure_passes_and_none_is_needed(tmp_path):
    for value in ("magnetometer", "zupt-alignment", None):
        prof = _raw(SINGLE_FILE)
        if value is None:
            del prof["procedure"]
        else:
            prof["procedure"] = value
        (tmp_path / "p.yaml").write_text(yaml.safe_dump(prof))
        assert load_profile(tmp_path / "p.yaml").get("procedure") == value
