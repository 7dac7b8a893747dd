"""Declared procedure options: each option declared once, one validator for every caller.

A procedure module lists its options in ``OPTIONS``, a tuple of :class:`Option` (name, stage
``sequence`` | ``analysis`` | ``both`` | ``rig``, type, default, help, lab unit, allowed range or
choices). :func:`check_options` is the one validator: it refuses an unknown name (naming the
nearest declared one), checks type, range and choices with a one-line :class:`ProcedureError`
naming the option and its unit, fills in the defaults and keeps the options of one stage.
:func:`validate` and :func:`split` apply it to a procedure module (``run``, ``analyze``,
``campaign``, ``batch`` and the dashboard widgets all go through them), :func:`option_rows`
gives the table ``workbench procedures PROC`` prints.

Every turntable procedure also takes the :data:`RIG_OPTIONS` (stage ``rig``: the simulated rig's
imperfections, neither the sequence's nor the analysis's; :func:`rig_options` picks them).

Values stay in the option's declared lab unit (``table_angle_deg`` in degrees, as given);
:meth:`Options.si` converts one to SI through :mod:`workbench.units`.
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

from workbench.errors import ProcedureError

STAGES = ("sequence", "analysis", "both", "rig")
# float, int, bool, str: one value; list: a JSON list (its items checked by the procedure);
# magnitude: a number >= 0 or one per axis (3); any: any JSON value (e.g. a mount name or matrix)
TYPES = ("float", "int", "bool", "str", "list", "magnitude", "any")


@dataclass(frozen=True)
class Option:
    """One declared option of a procedure.

    ``unit`` is the lab unit the value is given in (a :mod:`workbench.units` name such as
    ``deg``, ``deg/h``, ``mg``, or a plain label such as ``s``, ``°C``); ``ge`` / ``gt`` / ``le``
    bound a number (in that unit); ``choices`` lists the allowed values; ``words`` are special
    strings a numeric option also takes (e.g. ``("auto",)``). A default of None means "unset"
    and None is then an allowed value.
    """

    name: str
    stage: str
    type: str
    default: Any
    help: str
    unit: str | None = None
    choices: tuple | None = None
    ge: float | None = None
    gt: float | None = None
    le: float | None = None
    words: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if self.stage not in STAGES:
            raise ValueError(f"option {self.name}: stage {self.stage!r} is not one of {', '.join(STAGES)}")
        if self.type not in TYPES:
            raise ValueError(f"option {self.name}: type {self.type!r} is not one of {', '.join(TYPES)}")

    def in_stage(self, stage: str | None) -> bool:
        """Whether the option belongs to ``stage`` (None: every stage; ``both`` is sequence and analysis)."""
        return stage is None or self.stage == stage or (self.stage == "both" and stage in ("sequence", "analysis"))

    def allowed(self) -> str:
        """The allowed values in words, e.g. ``> 0 s``, ``one of ABAB, ABBA``, ``>= 0 deg or 'auto'``."""
        unit = f" {self.unit}" if self.unit else ""
        if self.choices is not None:
            text = "one of " + ", ".join(str(c) for c in self.choices)
        elif self.type == "magnitude":
            text = f"a number >= 0 or a list of 3{unit}"
        else:
            bounds = [f"{op} {v:g}" for op, v in ((">=", self.ge), (">", self.gt), ("<=", self.le)) if v is not None]
            text = " and ".join(bounds) + (unit if bounds else "")
        extras = [repr(w) for w in self.words] + (["null"] if self.default is None else [])
        return " or ".join(([text] if text else []) + extras)

    def check(self, value: Any, where: str) -> Any:
        """The value checked and converted to the declared type; ProcedureError naming option and unit."""
        if value is None and self.default is None:
            return None
        if isinstance(value, str) and value in self.words:
            return value
        unit = f" ({self.unit})" if self.unit else ""
        bad = f"{where}: {self.name}={value!r}{unit}"
        out = self._convert(value, bad)
        if self.choices is not None and out not in self.choices:
            raise ProcedureError(f"{bad} is not one of {', '.join(str(c) for c in self.choices)}")
        if self.type in ("float", "int"):
            for op, bound, ok in ((">=", self.ge, lambda v, b: v >= b), (">", self.gt, lambda v, b: v > b),
                                  ("<=", self.le, lambda v, b: v <= b)):
                if bound is not None and not ok(out, bound):
                    raise ProcedureError(f"{bad} must be {op} {bound:g}{(' ' + self.unit) if self.unit else ''}")
        return out

    def _convert(self, value: Any, bad: str) -> Any:
        t = self.type
        number = isinstance(value, (int, float)) and not isinstance(value, bool)
        if t == "float":
            if not number or not math.isfinite(value):
                raise ProcedureError(f"{bad} is not a number")
            return float(value)
        if t == "int":
            if not number or not math.isfinite(value) or float(value) != int(value):
                raise ProcedureError(f"{bad} is not a whole number")
            return int(value)
        if t == "bool":
            if not isinstance(value, bool):
                raise ProcedureError(f"{bad} is not true or false")
            return value
        if t == "str":
            if not isinstance(value, str):
                raise ProcedureError(f"{bad} is not a word")
            return value
        if t == "list":
            if not isinstance(value, (list, tuple)):
                raise ProcedureError(f"{bad} is not a list")
            return list(value)
        if t == "magnitude":
            vals = list(value) if isinstance(value, (list, tuple)) else [value]
            if len(vals) not in (1, 3) or not all(isinstance(v, (int, float)) and not isinstance(v, bool)
                                                  and math.isfinite(v) and v >= 0 for v in vals):
                raise ProcedureError(f"{bad} is not a number >= 0 or a list of 3")
            return float(vals[0]) if not isinstance(value, (list, tuple)) else [float(v) for v in vals]
        return value


class Options(dict):
    """Validated options of one stage: name -> value in the option's declared (lab) unit.

    ``given`` holds the names the caller set (the others carry their declared default).
    """

    def __init__(self, values: Mapping, declared: Mapping[str, Option], given: Iterable[str]) -> None:
        super().__init__(values)
        self.declared = dict(declared)
        self.given = frozenset(given)

    def si(self, name: str):
        """Option ``name`` in SI: a number or list times the SI value of its unit; None and words unchanged.

        E.g. ``o.si("table_angle_deg")`` -> rad, ``o.si("gyro_bias_instability_deg_h")`` -> (3,) rad/s
        or a float.
        """
        import numpy as np

        from workbench import units

        value, opt = self[name], self.declared[name]
        if value is None or isinstance(value, str) or opt.unit is None:
            return value
        if opt.type == "magnitude" or isinstance(value, list):
            return np.asarray(value, float) * units.factor(opt.unit)
        return float(value) * units.factor(opt.unit)


# options of the simulated rig, declared once for every turntable procedure (workbench.jobs reads them)
RIG_OPTIONS = (
    Option("imperfections", "rig", "str", "off", "virtual lab only: the unit's imperfections from its grade's "
           "imperfections block: off, all, or groups joined by commas (warm_up, turn_on, scale_drift, noise_temp)"),
    Option("table_indexing_error_deg", "rig", "float", 0.0, "virtual lab only: systematic table angle error "
           "a sin(angle)", unit="deg", ge=-1.0, le=1.0),
    Option("table_wobble_deg", "rig", "float", 0.0, "virtual lab only: once-per-revolution axis wobble",
           unit="deg", ge=-1.0, le=1.0),
    Option("table_axis_tilt_deg", "rig", "float", 0.0, "virtual lab only: table axis tilt from the vertical",
           unit="deg", ge=-1.0, le=1.0),
)


def defaults(declared: Iterable[Option]) -> dict:
    """``{name: default}`` of declarations (a procedure's ``DEFAULTS``)."""
    return {o.name: o.default for o in declared}


def check_options(name: str, declared: Iterable[Option], options: Mapping | None,
                  stage: str | None = None) -> Options:
    """Options of procedure ``name`` checked against its declarations, defaults filled, kept for ``stage``.

    An option of another stage is accepted and left out (``sequence()`` may receive the
    analysis options and the reverse); an undeclared name raises ProcedureError naming the
    nearest declared one; a bad value raises ProcedureError naming the option, the value, the
    allowed range and the unit.
    """
    table = {o.name: o for o in declared}
    options = dict(options or {})
    unknown = [k for k in options if k not in table]
    if unknown:
        k = unknown[0]
        near = difflib.get_close_matches(k, list(table), n=1, cutoff=0.6)
        hint = f"did you mean {near[0]}?" if near else f"known: {', '.join(table) or 'none'}"
        more = f" (and {', '.join(unknown[1:])})" if len(unknown) > 1 else ""
        raise ProcedureError(f"{name}: unknown option {k!r}{more} ({hint})")
    keep = {n: o for n, o in table.items() if o.in_stage(stage)}
    values = {n: (o.check(options[n], name) if n in options else o.default) for n, o in keep.items()}
    for n in options:  # the other stage's options are checked too
        if n not in keep:
            table[n].check(options[n], name)
    return Options(values, keep, [n for n in options if n in keep])


def declarations(proc) -> tuple[Option, ...]:
    """A procedure module's ``OPTIONS`` and, for a turntable procedure (not a ``DRIVE``), the
    :data:`RIG_OPTIONS`; a module with ``DEFAULTS`` only declares each as ``any`` of both stages."""
    declared = getattr(proc, "OPTIONS", None)
    if declared is None:
        declared = tuple(Option(k, "both", "any", v, "") for k, v in dict(getattr(proc, "DEFAULTS", {})).items())
    own = {o.name for o in declared}
    rig = () if getattr(proc, "DRIVE", False) else tuple(o for o in RIG_OPTIONS if o.name not in own)
    return tuple(declared) + rig


def rig_options(proc, options: Mapping | None) -> Options:
    """The rig-stage options of ``options`` (validated, defaults filled) for procedure ``proc``."""
    return validate(proc, options, "rig")


def validate(proc, options: Mapping | None, stage: str | None = None) -> Options:
    """:func:`check_options` for a procedure module (its ``NAME`` and declarations)."""
    return check_options(proc.NAME, declarations(proc), options, stage)


def split(proc, options: Mapping | None) -> tuple[dict, dict]:
    """The options given (validated, no defaults added) split into (sequence, analysis) options.

    An option of stage ``both`` goes to both. Raises ProcedureError as :func:`validate`.
    """
    validate(proc, options)
    table = {o.name: o for o in declarations(proc)}
    given = dict(options or {})
    seq = {k: table[k].check(v, proc.NAME) for k, v in given.items() if table[k].in_stage("sequence")}
    ana = {k: table[k].check(v, proc.NAME) for k, v in given.items() if table[k].in_stage("analysis")}
    return seq, ana


def option_rows(proc) -> list[dict]:
    """Rows (name, stage, type, unit, default, allowed, help) of a procedure's options, for tables."""
    import json

    return [{"name": o.name, "stage": o.stage, "type": o.type, "unit": o.unit or "",
             "default": json.dumps(o.default), "allowed": o.allowed(), "help": o.help} for o in declarations(proc)]
