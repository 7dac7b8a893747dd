"""The analysis shared by the north-finding procedures (maytagging, earth-rate, carousel, redundant).

:data:`ANALYSIS_OPTIONS` declares the options of :func:`workbench.analysis.northfinding.find_north`
once for the four procedures; :func:`analyze` runs it and turns the result into a
:class:`~workbench.procedure.ProcedureResult` (a result, not a calibration set).
"""

from __future__ import annotations

import numpy as np

from workbench.analysis.northfinding import find_north, to_result
from workbench.errors import ProcedureError
from workbench.options import Option, check_options
from workbench.procedure import ProcedureResult
from workbench.sequence import Hold
from workbench.session import Session

# sequence options every north-finding procedure has
START_OFFSET = Option("start_offset_deg", "sequence", "float", 0.0, "table angle of the first position", unit="deg")
MOUNT = Option("mount", "sequence", "any", "z-down", "mount name or 3x3 body->table-top matrix")

ANALYSIS_OPTIONS = (
    Option("drift", "analysis", "bool", None, "fit a linear bias drift (default: off for maytagging, on "
           "otherwise)"),
    Option("index_tol_deg", "analysis", "float", 0.05, "largest departure of a pair from 180° apart", unit="deg",
           gt=0),
    Option("max_tilt_deg", "analysis", "float", 1.0, "body x level and the other axes level or vertical within "
           "this", unit="deg", gt=0),
    Option("grade", "analysis", "str", None, "grade (name or fixture) whose noise terms give the theoretical "
           "figures (default: the unit's model if it names one, else the session's own ADEV)"),
    Option("bias", "analysis", "list", None, "known gyro bias (3 values) the redundant method removes "
           "(default: the turn mean)", unit="rad/s"),
    Option("positions_per_turn", "analysis", "int", None, "positions of one turn (default: the distinct "
           "angles)", ge=1),
    Option("bin_deg", "analysis", "float", 5.0, "table-angle bin of the carousel data", unit="deg", gt=0),
    Option("axes", "analysis", "list", None, "the gyro's sensing axes, e.g. [0, 1] (default: the grade's)"),
)


# maytagging and redundant (thesis table 4.2, sequences 8-12: "extracted one hour after the starting")
DISCARD = Option("discard_s", "both", "float", 0.0, "warm-up: the sequence first holds the first position this "
                 "long; the analysis leaves out every step starting earlier", unit="s", ge=0)


def warm_up(first: Hold, discard_s: float) -> list:
    """The warm-up hold (``discard_s`` at the first position, labelled ``warm-up``) before ``first``, or none."""
    return [Hold(first.mount, first.table_angle, float(discard_s), "warm-up")] if discard_s > 0 else []


def settle_option(settle_s: float = 2.0) -> Option:
    """The ``settle_s`` option of a north-finding procedure (both stages: the sequence records it)."""
    return Option("settle_s", "both", "float", settle_s, "dropped at the start of each step (analysis default: "
                  "the value the sequence recorded)", unit="s", ge=0)


def grade_spec(session: Session, grade: str | None):
    """The grade ``grade`` (name or fixture path), else the unit's model if it names a grade, else None."""
    from workbench.errors import WorkbenchError
    from workbench.grades import load_spec

    if grade:
        return load_spec(grade)
    if session.unit.model:
        try:
            return load_spec(session.unit.model)
        except (WorkbenchError, OSError):
            return None
    return None


def analyze(name: str, method: str, declared, session: Session, options: dict) -> ProcedureResult:
    """A north-finding procedure's ``analyze``: :func:`find_north` + :func:`to_result` -> ProcedureResult.

    ``options`` are checked against the procedure's ``declared`` options; ``settle_s``
    defaults to the session's recorded option, else the declared default.
    """
    o = check_options(name, declared, options, "analysis")
    kwargs = {k: o[k] for k in o if o[k] is not None and k != "settle_s"}
    kwargs["settle_s"] = o["settle_s"] if "settle_s" in o.given else \
        float(session.options.get("settle_s", o["settle_s"]))
    if "discard_s" in o:  # the recorded warm-up unless given
        kwargs["discard_s"] = o["discard_s"] if "discard_s" in o.given else \
            float(session.options.get("discard_s", o["discard_s"]))
    if "bias" in kwargs:
        b = kwargs["bias"]
        if len(b) != 3 or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in b):
            raise ProcedureError(f"{name}: bias={b!r}: expected the 3 known gyro biases (x, y, z)")
        kwargs["bias"] = np.asarray(b, float)
    kwargs["grade"] = grade_spec(session, kwargs.get("grade"))
    nf = find_north(session, method, **kwargs)
    result, summary = to_result(nf)
    return ProcedureResult(name, result, None, nf, summary, list(nf.warnings))
