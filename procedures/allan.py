"""Allan variance: a long static hold at a set temperature; the noise terms of gyros and accels.

Sequence: soak the chamber at ``temperature_c`` (the unit static at ``mount``), then hold
still for ``duration_s`` (label ``allan``). Analysis
(:func:`workbench.analysis.allan_fit.analyze_record`): overlapping Allan deviation of every
axis with 95 % chi-squared intervals (Greenhall EDF), the IEEE Std 952 noise-term fit with
model selection, and the classic read-offs. Product: a calibration set with the ``noise``
block (gyro ``arw`` rad/s/√Hz, ``bias_instability`` rad/s, ``rrw`` rad/s²/√Hz, ``quantization``
rad; accel ``vrw`` m/s²/√Hz, ``bias_instability`` m/s², ``rrw`` m/s³/√Hz; each with ``<name>_ci95``;
null = not observed by the record). A lazily loaded session (``load_session(dir, lazy=True)``,
``session.samples is None``; batch workers do this for this procedure, :data:`LAZY_OK`) is
analysed by :func:`workbench.analysis.allan_fit.analyze_stream` in bounded memory, with the
same result structure (the record must then be gap-free). A record that moves (the stationarity
detector's statistic, :mod:`workbench.analysis.stationarity`, over 10 times its threshold for at
least one window: motion, not noise) is refused (``span=still`` analyses its longest still stretch),
naming the step and the motion; a ``free`` step (an imported hand-held record) is analysed when it
is still. References: thesis (shared/seeds/000_...) tables 1.1, 1.2,
2.1, 4.1 and eq. 3.50-3.53 (process noise from these terms).
"""

from __future__ import annotations

import numpy as np

from workbench.analysis.allan import GAP_POLICIES
from workbench.analysis.allan_fit import TERMS, AllanAnalysis, analyze_record, analyze_stream
from workbench.analysis.stationarity import detect, moving_summary
from workbench.calset import CalibrationSet
from workbench.errors import AnalysisError, RigLimitError
from workbench.options import Option, check_options, defaults
from workbench.plots.allan import plot_triads, term_text
from workbench.procedure import ProcedureResult
from workbench.sequence import Hold, Sequence, Soak, with_options
from workbench.session import ACCEL, GYRO

NAME = "allan"
TITLE = "Allan variance (long static hold): noise terms with confidence intervals"
TRIADS = ("accel", "gyro")
CAMPAIGN_ORDER = 10  # first: its bias instability sets the floor of the static fits that follow
OPTIONS = (
    Option("duration_s", "sequence", "float", 7200.0, "static hold (at least 1000 samples)", unit="s", gt=0),
    Option("temperature_c", "sequence", "float", 25.0, "chamber setpoint of the soak", unit="°C"),
    Option("mount", "sequence", "any", "z-down", "mount name or 3x3 body->table-top matrix"),
    Option("soak", "sequence", "bool", True, "soak the chamber at temperature_c first"),
    Option("taus", "analysis", "any", "octave", "averaging times: octave, decade, '<k>-per-decade' or a list of "
           "taus", unit="s"),
    Option("gap_policy", "analysis", "str", "error", "what a gap in the record does", choices=GAP_POLICIES),
    Option("method", "analysis", "str", "ieee952", "noise terms of the calibration set: IEEE 952 Allan fit or GMWM",
           choices=("ieee952", "gmwm")),
    Option("gmwm_model", "analysis", "str", "wn+fl+rw", "with method gmwm: the processes (wn qn fl rw dr gm, joined "
           "by +; k*gm repeats; fl = flicker bias instability)"),
    Option("gmwm_bootstrap", "analysis", "int", 100, "with method gmwm: simulated records for the weighting matrix "
           "and the intervals", ge=50),
    Option("span", "analysis", "str", "step", "what of the hold to analyse: the whole step, or its longest still "
           "stretch (stationarity detector; e.g. a hand-held record that starts moving)", choices=("step", "still")),
)
DEFAULTS = defaults(OPTIONS)
LABEL = "allan"
LAZY_OK = True  # analyze() streams a lazily loaded session (workbench.fleet.batch loads it lazily)
STREAM_ROWS = 1 << 20  # samples per streamed batch (about 8 * 4 * STREAM_ROWS bytes with the step column)


def sequence(spec, **options) -> Sequence:
    """Soak at ``temperature_c`` (when ``soak``), then a static hold of ``duration_s`` s at ``mount``."""
    o = check_options(NAME, OPTIONS, options, "sequence")
    duration_s, temperature_c, mount, soak = o["duration_s"], o["temperature_c"], o["mount"], o["soak"]
    rate = float(getattr(spec, "sample_rate_hz", 100.0) or 100.0)
    if duration_s * rate < 1000:
        raise RigLimitError(f"{NAME}: duration_s {duration_s:g} s gives fewer than 1000 samples at {rate:g} Hz")
    steps = ([Soak(temperature_c, mount, 0.0, label="soak")] if soak else []) + [Hold(mount, 0.0, duration_s, LABEL)]
    return with_options(Sequence(NAME, steps), duration_s=duration_s, temperature_c=temperature_c, soak=soak)


GROSS_MOTION = 10.0  # a window whose test statistic exceeds this many times the detector's threshold is motion, not noise


def _hold_step(session):
    holds = ([s for s in session.steps_of_kind("static") if s.label == LABEL] or session.steps_of_kind("static")
             or session.steps_of_kind("free"))
    if not holds:
        raise AnalysisError(f"{session.name}: no static or free step to analyse (expected a hold labelled {LABEL!r})")
    return max(holds, key=lambda s: s.duration)


def _still_span(session, step, span: str) -> slice:
    """The rows of the step to analyse: all of them, or (``span="still"``) its longest still stretch.

    With ``span="step"`` a record that moves raises AnalysisError naming the step and the motion seen (an Allan
    deviation of a moving record is the motion's, not the noise's)."""
    df = session.step_samples(step.index)
    if len(df) < session.sample_rate_hz:
        return slice(0, len(df))
    gyro, accel = df[GYRO].to_numpy(float), df[ACCEL].to_numpy(float)
    found = detect(gyro, accel, session.sample_rate_hz)
    where = f"{session.name}: step {step.index} ({step.kind}{f', {step.label}' if step.label else ''})"
    if span == "still":
        if not found.stretches:
            raise AnalysisError(f"{where}: no still stretch (the stationarity detector finds none)")
        a, b = max(found.stretches, key=lambda r: r[1] - r[0])
        return slice(a, b)
    # not the detector's still/moving split alone: its false alarms (1e-3 per window) and an axis whose noise is
    # far from Gaussian (coarse quantisation) cut a still record too; a window 10x over the threshold cannot be noise
    if np.count_nonzero(found.statistic > GROSS_MOTION * found.threshold) >= found.window:
        raise AnalysisError(f"{where}: the unit moves: {moving_summary(found, df['t'].to_numpy(float), gyro)}; "
                            "Allan variance needs a still record (-o span=still analyses its longest still stretch)")
    return slice(0, len(df))


def analyze(session, **options) -> ProcedureResult:
    """Allan analysis of the longest static hold; gyro always, accel when present.

    A lazily loaded session is streamed (``gap_policy`` is then moot: lazy loading already
    refuses non-finite samples)."""
    o = check_options(NAME, OPTIONS, options, "analysis")
    taus, gap_policy = o["taus"], o["gap_policy"]
    step = _hold_step(session)
    if session.samples is None and o["span"] == "still":
        raise AnalysisError(f"{session.name}: span=still needs the record in memory (it is loaded lazily)")
    rows = _still_span(session, step, o["span"]) if session.samples is not None else None
    rate = float(session.sample_rate_hz)
    analyses: dict[str, AllanAnalysis] = {}
    for triad, cols, data in (("gyro", GYRO, session.gyro), ("accel", ACCEL, session.accel)):
        src = f"{session.name}: step {step.index} ({triad})"
        if session.samples is None:  # lazily loaded long record: bounded memory
            analyses[triad] = analyze_stream(lambda c=cols: session.stream(c, step.index, STREAM_ROWS), rate, cols,
                                             triad, taus, src)
        else:
            analyses[triad] = analyze_record(data(step.index)[rows], rate, cols, triad, taus, gap_policy, src)
    blocks = {t: a.noise_block() for t, a in analyses.items()}
    gmwm = _gmwm(session, step, o, analyses, rows) if o["method"] == "gmwm" else {}
    blocks.update({t: g.noise_block() for t, g in gmwm.items()})
    duration, lines = step.duration, []
    if rows is not None and o["span"] == "still":
        t = session.step_samples(step.index)["t"].to_numpy(float)[rows]
        duration = float(t[-1] - t[0])
        lines.append(f"analysed: the longest still stretch of step {step.index}, t = {t[0]:.2f}..{t[-1]:.2f} s "
                     f"({duration:.1f} s)")
    cal = CalibrationSet(unit=session.unit, noise=blocks,
                         notes={NAME: {"sample_rate_hz": rate, "duration_s": duration,
                                       "temperature_c": step.temperature_c, "span": o["span"]}})
    result = {**_result_dict(analyses, step), "duration_s": duration, "span": o["span"]}
    if gmwm:  # the noise block above is GMWM's; the IEEE 952 terms stay in result[triad]["terms"]
        result["gmwm"] = {t: g.to_dict() for t, g in gmwm.items()}
    return ProcedureResult(NAME, result=result, calibration=cal, payload=analyses,
                           summary=lines + [line for a in analyses.values() for line in a.summary()]
                           + [line for g in gmwm.values() for line in g.summary()],
                           warnings=[w for a in analyses.values() for w in a.warnings])


def _gmwm(session, step, o, analyses, rows: slice | None) -> dict:
    """``method=gmwm``: the GMWM fit of every triad analysed (in memory only)."""
    from workbench.analysis.gmwm_record import analyze_gmwm

    if session.samples is None:
        raise AnalysisError(f"{session.name}: method gmwm needs the record in memory (not a lazily loaded session)")
    data = {"gyro": (GYRO, session.gyro), "accel": (ACCEL, session.accel)}
    return {t: analyze_gmwm(data[t][1](step.index)[rows], float(session.sample_rate_hz), data[t][0], t, o["gmwm_model"],
                            o["gmwm_bootstrap"], o["gap_policy"], f"{session.name}: step {step.index} ({t})")
            for t in analyses}


def _result_dict(analyses: dict[str, AllanAnalysis], step) -> dict:
    """The step's facts and each triad's :meth:`AllanAnalysis.to_dict`."""
    return {"step": step.index, "duration_s": step.duration, "temperature_c": step.temperature_c,
            **{triad: an.to_dict() for triad, an in analyses.items()}}


def figures(result: ProcedureResult) -> dict:
    """Log-log ADEV with 95 % bands and the fitted terms, one panel per triad."""
    return {"adev": plot_triads(result.payload)}


def noise_terms_lab(result: ProcedureResult) -> list[dict]:
    """Rows (triad, axis, term, value, 95 % interval) in lab units, for tables (dashboard, reports)."""
    rows = []
    for triad, an in result.payload.items():
        for f in an.fits:
            for t in TERMS:
                term = f.terms[t]
                rows.append({"triad": triad, "axis": f.column, "term": t, "observed": term.observed,
                             "value": term_text(triad, t, term.value) if term.observed else "not observed",
                             "ci95": f"{term_text(triad, t, term.ci95[0])} .. {term_text(triad, t, term.ci95[1])}",
                             "tau_range_s": "" if term.tau_range is None else
                             f"{term.tau_range[0]:.3g} .. {term.tau_range[1]:.3g}"})
    return rows
