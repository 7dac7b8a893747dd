"""The strict schema of a rig configuration file (``fixtures/rigs/*.yaml``), in lab units.

Every section is a pydantic model that refuses unknown keys (naming the nearest valid one),
non-finite numbers and values out of range; :func:`parse_rig_file` turns the first problem
into one :class:`~workbench.errors.WorkbenchError` line naming the file and the field.
A real rig (``driver: real``) must state its turntable and chamber limits: the defaults
below are the simulated rig's and are never assumed for hardware.

:func:`schema_markdown` renders every key with its type, range and default for
``docs/rigs.md`` (regenerate with ``python -m workbench.rigschema --write``; a test keeps it current).
"""

from __future__ import annotations

import difflib
import math
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Annotated, Any, Literal, Union, get_args

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from workbench.confine import plain_template
from workbench.errors import WorkbenchError
from workbench.schema_docs import TABLE_HEAD, key_row, sections

Positive = Annotated[float, Field(gt=0)]
NonNegative = Annotated[float, Field(ge=0)]
Count = Annotated[int, Field(ge=0)]
PositiveInt = Annotated[int, Field(gt=0)]


class Section(BaseModel):
    """A configuration section: strict types, finite numbers, no unknown keys."""

    model_config = ConfigDict(extra="forbid", strict=True, allow_inf_nan=False, frozen=True)

    @model_validator(mode="before")
    @classmethod
    def _known_keys(cls, data: Any) -> Any:
        if isinstance(data, Mapping):
            known = list(cls.model_fields)
            for key in data:
                if key not in cls.model_fields:
                    near = difflib.get_close_matches(str(key), known, 1, 0.6)
                    hint = f"; did you mean {near[0]!r}?" if near else f" (known: {', '.join(known)})"
                    raise ValueError(f"unknown key {key!r}{hint}")
        return data


def _regex(value: str | None) -> str | None:
    if value is not None:
        try:
            re.compile(value)
        except re.error as exc:
            raise ValueError(f"not a regular expression ({exc})") from None
    return value


def _template(value: str | None) -> str | None:
    """A command template: plain ``{name}`` / ``{name:spec}`` fields only (no attribute or index access)."""
    return value if value is None else plain_template(value, error=ValueError)


class Site(Section):
    """Where the rig stands."""

    latitude_deg: float = Field(ge=-90, le=90, description="geodetic latitude, °")
    longitude_deg: float = Field(0.0, ge=-180, le=360, description="longitude, ° east")
    height_m: float = Field(0.0, ge=-500, le=10000, description="height above the ellipsoid, m")
    table_zero_azimuth_deg: float | None = Field(None, ge=-360, le=360, description=(
        "azimuth of the table zero clockwise from true north, °; null when not surveyed"))


class MagneticField(Section):
    """The lab's magnetic reference field."""

    intensity_ut: float | None = Field(None, gt=0, le=1000, description=(
        "field magnitude, µT; null when not measured (the simulated lab then uses 48)"))
    dip_deg: float = Field(60.0, ge=-90, le=90, description="inclination, ° (down positive)")
    declination_deg: float = Field(0.0, ge=-180, le=180, description="declination, ° east of true north")


class Turntable(Section):
    """Turntable limits every sequence is checked against."""

    max_rate_dps: Positive = Field(1000.0, description="largest table rate a step may ask for, °/s")
    max_accel_dps2: Positive = Field(500.0, description="table acceleration, °/s²")
    positioning_error_deg: NonNegative = Field(0.01, description="1-sigma fixture/positioning error per step, °")
    settle_s: NonNegative = Field(2.0, description="wait after a move before recording, s")
    encoder_resolution_deg: Positive = Field(1e-4, description="angle read-back resolution, °")


class Chamber(Section):
    """Climatic chamber limits; ``safe_c`` is where an interlock or a stop sends the chamber."""

    min_c: float = Field(-55.0, ge=-273.15, description="lowest air setpoint, °C")
    max_c: float = Field(125.0, ge=-273.15, description="highest air setpoint, °C (> min_c)")
    max_ramp_c_per_min: Positive = Field(5.0, description="largest air ramp rate, °C/min")
    initial_c: float = Field(23.0, description="air temperature at the start, °C (in min_c..max_c)")
    safe_c: float = Field(23.0, description="safe setpoint after a stop or an interlock, °C (in min_c..max_c)")

    @model_validator(mode="after")
    def _ordered(self) -> Chamber:
        if not self.min_c < self.max_c:
            raise ValueError(f"min_c {self.min_c:g} °C must be below max_c {self.max_c:g} °C")
        for key in ("initial_c", "safe_c"):
            v = getattr(self, key)
            if not self.min_c <= v <= self.max_c:
                raise ValueError(f"{key} {v:g} °C outside min_c..max_c ({self.min_c:g}..{self.max_c:g} °C)")
        return self


class Commands(Section):
    """Turntable command templates (Python format strings); null = the controller has none."""

    identify: str | None = Field("*IDN?", description="identity query")
    position: str | None = Field("POS:COMM {angle_deg:.5f}", description="absolute position move")
    position_rate: str | None = Field(None, description="position-mode rate limit, e.g. POS:RATE {rate_dps:.5f}")
    position_accel: str | None = Field(None, description="position-mode acceleration limit, {accel_dps2}")
    position_relative: str | None = Field(None, description="signed relative move, {delta_deg}")
    rate: str | None = Field("RATE:COMM {rate_dps:.5f}", description="rate mode")
    stop: str | None = Field("STOP", description="decelerate to rest and hold")
    read_angle: str | None = Field("POS?", description="angle query, reply in °")
    read_rate: str | None = Field("RATE?", description="rate query, reply in °/s")
    status: str | None = Field("STAT?", description="status query")
    interlock: str | None = Field("INTL?", description="interlock query")
    error: str | None = Field("SYST:ERR?", description="error query after each setting command")
    mount: str | None = Field(None, description="motorised fixture, {mount}")

    _templates = field_validator("*")(classmethod(lambda cls, v: _template(v)))


class Replies(Section):
    """Regular expressions matched against the turntable's replies."""

    error_reply: str = Field(r"^(ERR|ERROR|\?|NAK)", description="a reply matching this is a controller error")
    no_error: str = Field(r"^\+?0\b", description="the error query's reply when a command was accepted")
    interlock_clear: str = Field(r"^0$", description="the interlock query's reply when clear")

    _regexes = field_validator("*")(classmethod(lambda cls, v: _regex(v)))


class TableController(Section):
    """Turntable controller behind a VISA resource."""

    driver: Literal["visa"] = Field("visa", description="driver")
    resource: str = Field(description="VISA resource, e.g. TCPIP0::host::5025::SOCKET")
    visa_library: str = Field("@py", description="VISA library (@py = pyvisa-py)")
    timeout_s: Positive = Field(1.0, description="per try, s")
    retries: Count = Field(2, description="further tries after a timeout")
    read_termination: str = Field("\n", description="reply terminator")
    write_termination: str = Field("\n", description="command terminator")
    angle_tolerance_deg: Positive = Field(0.005, description="settled when the angle is within this, °")
    rate_tolerance_dps: Positive = Field(0.01, description="settled when the rate is within this, °/s")
    settle_timeout_s: Positive = Field(120.0, description="of sample time, s")
    poll_s: Positive = Field(0.5, description="read-back and interlock polled once per this much sample time, s")
    positioning_rate_dps: Positive | None = Field(None, description=(
        "rate of the moves between steps, °/s (default min(60, turntable.max_rate_dps))"))
    commands: Commands = Field(default_factory=Commands, description="command templates")
    replies: Replies = Field(default_factory=Replies, description="reply patterns")


class AsciiChamberController(Section):
    """Chamber answering ASCII line commands (Espec style)."""

    driver: Literal["ascii"] = Field(description="driver")
    address: str = Field(description="serial device or socket://host:port")
    baudrate: PositiveInt = Field(9600, description="serial baud rate")
    timeout_s: Positive = Field(1.0, description="per try, s")
    retries: Count = Field(2, description="further tries after a timeout")
    write_termination: str = Field("\r\n", description="command terminator")
    read_termination: str = Field("\r\n", description="reply terminator")
    identify: str = Field("ROM?", description="identity query")
    read: str = Field("TEMP?", description="temperature query")
    read_field: Count | None = Field(0, description="comma-separated field of the reply holding the air temperature")
    set: str = Field("TEMP, S{setpoint_c:.1f}", description="setpoint command, {setpoint_c}")
    ok: str = Field("^OK", description="reply pattern of an accepted command")
    error_reply: str = Field("^(NA|ERR)", description="reply pattern of a refused command")
    air_tolerance_c: Positive = Field(0.5, description="soaked when the air is within this, °C")

    _set = field_validator("set")(classmethod(lambda cls, v: _template(v)))
    _patterns = field_validator("ok", "error_reply")(classmethod(lambda cls, v: _regex(v)))


class Register(Section):
    """One Modbus register."""

    address: Count = Field(description="register address")
    kind: Literal["holding", "input"] = Field("holding", description="register table")
    scale: Positive = Field(1.0, description="°C per count")
    signed: bool = Field(True, description="16-bit two's complement")
    value: int | None = Field(None, description="value written (run register)")


class Registers(Section):
    """The chamber's Modbus register map."""

    temperature: Register = Field(description="process value")
    setpoint: Register = Field(description="static setpoint")
    run: Register | None = Field(None, description="written after a setpoint, if the chamber needs it")


class ModbusChamberController(Section):
    """Chamber over Modbus TCP (Watlow F4 style)."""

    driver: Literal["modbus"] = Field(description="driver")
    host: str = Field(description="host name or address")
    port: Annotated[int, Field(gt=0, lt=65536)] = Field(502, description="TCP port")
    device_id: Count = Field(1, description="Modbus unit id")
    timeout_s: Positive = Field(1.0, description="per try, s")
    retries: Count = Field(2, description="further tries after a timeout")
    registers: Registers = Field(description="register map")
    air_tolerance_c: Positive = Field(0.5, description="soaked when the air is within this, °C")


ChamberController = Annotated[Union[AsciiChamberController, ModbusChamberController],  # noqa: UP007
                              Field(discriminator="driver")]


class ImuStream(Section):
    """The unit's sample stream."""

    address: str = Field(description="serial device, socket://host:port or udp://host:port")
    sample_rate_hz: Positive = Field(description="sample rate, Hz")
    baudrate: PositiveInt = Field(115200, description="serial baud rate")
    format: Literal["text", "binary"] = Field("text", description="frame format")
    separator: str = Field(",", description="text field separator")
    sync: str = Field("", description="binary frame sync bytes, hex")
    struct: str = Field("", description="binary frame layout (Python struct)")
    fields: list[str] = Field(description="frame fields: counter, time, gx..gz, ax..az, mx..mz, temp, _")
    scale: dict[str, Annotated[float, Field(allow_inf_nan=False)]] = Field(
        default_factory=dict, description="field -> SI factor")
    checksum: Literal["none", "xor8"] = Field("none", description="frame checksum")
    counter_modulo: PositiveInt = Field(2 ** 32, description="counter wrap-around")
    time_source: Literal["counter", "time", "host"] | None = Field(None, description=(
        "sample times from the counter, the device time or the host clock (default counter if a field)"))
    max_corrupt_frames: Count = Field(3, description="corrupt frames in a row before the run stops")
    timeout_s: Positive = Field(1.0, description="no frame for this long stops the run, s")

    @field_validator("sync")
    @classmethod
    def _hex(cls, v: str) -> str:
        try:
            bytes.fromhex(v)
        except ValueError:
            raise ValueError(f"sync {v!r} is not hex bytes") from None
        return v


class Fixture(Section):
    """How the unit is remounted between mounts."""

    mode: Literal["prompt", "command", "fixed"] = Field("prompt", description=(
        "prompt = the operator remounts when asked; command = motorised fixture; fixed = one mount only"))


class Hil(Section):
    """The loopback simulator of ``workbench rig hil``."""

    unit: str = Field("industrial_mems", description="unit grade fixture")
    seed: Count = Field(1, description="seed of the simulated unit")
    speed: Positive = Field(1.0, description="simulated seconds per wall-clock second")


class ReferenceInstrument(Section):
    """A piece of reference equipment of the rig and its traceability, as a certificate states it."""

    name: str = Field(description="what it is, e.g. 'rate table', 'chamber thermometer'")
    model: str = Field("", description="maker and model")
    serial: str = Field("", description="its serial number")
    certificate: str = Field("", description="its own calibration certificate number")
    calibrated: str = Field("", description="date of its last calibration (ISO 8601)")
    due: str = Field("", description="date its next calibration is due")
    traceability: str = Field(description="chain to the SI, e.g. 'INRIM via accredited lab 123'; "
                                          "or why there is none (a simulation)")


DRIVER_SECTIONS = ("table_controller", "chamber_controller", "imu_stream", "fixture", "hil")


class RigFile(Section):
    """A rig configuration file."""

    name: str | None = Field(None, description="rig name (default: the driver)")
    driver: Literal["sim", "real"] = Field(description="sim = the virtual lab; real = the drivers below")
    site: Site = Field(description="where the rig stands")
    magnetic_field: MagneticField = Field(default_factory=MagneticField, description="reference field")
    turntable: Turntable = Field(default_factory=Turntable, description="turntable limits (required for real)")
    chamber: Chamber = Field(default_factory=Chamber, description="chamber limits (required for real)")
    table_controller: TableController | None = Field(None, description="real: the turntable controller")
    chamber_controller: ChamberController | None = Field(None, description="real: the chamber; omit for none")
    imu_stream: ImuStream | None = Field(None, description="real: the unit's sample stream")
    fixture: Fixture | None = Field(None, description="real: remounting")
    hil: Hil | None = Field(None, description="loopback simulator settings")
    reference_equipment: list[ReferenceInstrument] = Field(
        default_factory=list, description="reference instruments and their traceability (shown on certificates)")

    @model_validator(mode="after")
    def _real_limits(self) -> RigFile:
        if self.driver == "real":
            for section in ("table_controller", "imu_stream"):
                if getattr(self, section) is None:
                    raise ValueError(f"a real rig needs a {section} section")
            for section, keys in REAL_REQUIRED.items():
                given = getattr(self, section).model_fields_set if section in self.model_fields_set else set()
                missing = [k for k in keys if k not in given]
                if missing:
                    raise ValueError(f"a real rig must state {section}.{missing[0]} (no default is assumed "
                                     f"for hardware)")
        return self

    def driver_options(self) -> dict:
        """The device sections as written (the drivers apply their own defaults)."""
        return {k: getattr(self, k).model_dump(exclude_unset=True) for k in DRIVER_SECTIONS
                if getattr(self, k) is not None}


REAL_REQUIRED = {"turntable": ("max_rate_dps", "max_accel_dps2"),
                 "chamber": ("min_c", "max_c", "max_ramp_c_per_min", "safe_c")}


_BOUNDS = {"greater_than": ">", "greater_than_equal": ">=", "less_than": "<", "less_than_equal": "<="}


def _message(e: dict) -> str:
    kind, value = e["type"], e.get("input")
    if kind == "missing":
        return "missing"
    if kind == "union_tag_invalid":
        return f"unknown driver {value.get('driver')!r} (known: ascii, modbus)"
    if kind == "finite_number" or (isinstance(value, float) and not math.isfinite(value)):
        return f"{value!r} is not a finite number"
    if kind == "literal_error":
        known = re.findall(r"'([^']*)'", e["ctx"]["expected"])
        return f"unknown {e['loc'][-1]} {value!r} (known: {', '.join(known)})"
    if kind in _BOUNDS:
        limit = next(iter(e["ctx"].values()))
        return f"{value!r} must be {_BOUNDS[kind]} {limit:g}"
    msg = e["msg"].removeprefix("Value error, ")
    if kind != "value_error" and not isinstance(value, (Mapping, list)):
        msg = f"{msg[0].lower()}{msg[1:]} (got {value!r})"
    return msg


def parse_rig_file(d: Any, source: str = "<rig>") -> RigFile:
    """Validate a rig configuration mapping; WorkbenchError ``<source>: <field>: <problem>``."""
    if not isinstance(d, Mapping):
        raise WorkbenchError(f"{source}: a rig configuration must be a YAML mapping")
    try:
        return RigFile.model_validate(dict(d))
    except ValidationError as exc:
        e = exc.errors()[0]
        loc = tuple(p for p in e["loc"] if p not in ("ascii", "modbus"))
        where = ".".join(str(p) for p in loc)
        raise WorkbenchError(f"{source}: {where + ': ' if where else ''}{_message(e)}") from None


# -- documentation ---------------------------------------------------------------------------
def schema_markdown() -> str:
    """Every rig-configuration key with its type, range, default and meaning, as Markdown tables."""
    lines = ["<!-- generated by `python -m workbench.rigschema` from workbench/rigschema.py; do not edit -->", ""]
    for prefix, model in sections(RigFile):
        title = f"`{prefix}`" if prefix else "top level"
        driver = model.model_fields.get("driver")
        if prefix == "chamber_controller" and driver is not None:
            title += f" (`driver: {get_args(driver.annotation)[0]}`)"
        lines += [f"#### {title}", "", model.__doc__.strip().splitlines()[0], "", *TABLE_HEAD]
        lines += [key_row(key, f) for key, f in model.model_fields.items()]
        lines.append("")
    req = "; ".join(f"`{s}.{k}`" for s, keys in REAL_REQUIRED.items() for k in keys)
    lines += [f"A real rig (`driver: real`) must state {req}.", ""]
    return "\n".join(lines)


DOC_BEGIN, DOC_END = "<!-- rig keys: begin -->\n", "<!-- rig keys: end -->"


def write_docs(doc: Path) -> None:
    """Replace the generated key tables between the markers of ``doc`` (docs/rigs.md)."""
    text = doc.read_text()
    head, rest = text.split(DOC_BEGIN, 1)
    doc.write_text(head + DOC_BEGIN + schema_markdown() + DOC_END + rest.split(DOC_END, 1)[1])


if __name__ == "__main__":
    import sys

    if sys.argv[1:] == ["--write"]:
        write_docs(Path(__file__).resolve().parents[1] / "docs" / "rigs.md")
    else:
        print(schema_markdown(), end="")
