"""The plausibility gate: a physically implausible calibration is never stored or exported.

Between an analysis and the store (and before ``sets export``) every calibration set passes
:func:`check`; the first failed check is one line naming the quantity, its value and its
limit in lab units (:mod:`workbench.units`). ``--force`` stores the set anyway with the failed
checks recorded in its notes (:func:`forced`, key ``plausibility``), where ``sets show`` and a
later export see them.

Checks, each against the unit's grade (its fixture, found by the unit's model name) by a wide
margin (:data:`WIDE` times the grade's 1-sigma spread, plus three of the estimate's own sigmas),
or against :data:`GENERIC` bounds when the grade is unknown (a recording of another lab's board):

- every coefficient finite; bias, scale factor, misalignment, nonlinearity, g-sensitivity and
  the thermal polynomial within the grade's range (a gyro bias may also hold the Earth rate);
- ``I + M`` of every triad: ``|M|`` (largest singular value) < :data:`M_NORM_MAX` and
  condition number <= :data:`COND_MAX` (a soft iron of 289 % is not a calibration);
- magnetometer: field norm within 5 % of the session's reference, else in 20-70 µT (the
  geomagnetic field anywhere on Earth); dip within ±90° and within 5° of a reference dip when
  the result has one (``reference_field`` of the magnetometer analysis); the dip's sign that of the
  site's hemisphere poleward of 25° latitude (a field pointing up in the north: the magnetometer's axes
  are inverted, which no motion can show: the gyro sees ``m`` and ``-m`` turn alike);
- an imported session whose axis check failed (the gyro's rotation fits the accelerometer or
  magnetometer only with another axis mapping: ``options['import']['axis_check']``);
- static steps of the session: ``|ω|`` at most the Earth rate plus the grade's bias range (and,
  for a grade whose bias is below the Earth rate, at least the Earth rate minus it); ``|a|``
  within the grade's bias and scale-factor range of the site's gravity. A value that would
  pass in another unit is named (``gyro in deg/s? values look 57x too large``).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace
from functools import lru_cache
from typing import TYPE_CHECKING

import numpy as np

from workbench import units
from workbench.calset import CalibrationSet, TriadCalibration
from workbench.earth import EARTH_RATE
from workbench.errors import WorkbenchError

if TYPE_CHECKING:
    from workbench.grade_types import SensorSpec

WIDE = 10.0  # a coefficient is implausible beyond WIDE x the grade's 1-sigma spread (p < 1e-20 by chance)
EST_SIGMAS = 3.0  # ... plus this many of the estimate's own sigma (capped at WIDE x the grade's spread)
M_NORM_MAX = 0.5  # largest singular value of M
COND_MAX = 3.0  # condition number of I + M (|M| < 0.5 gives at most 1.5 / 0.5 = 3)
FIELD_RANGE_UT = (20.0, 70.0)  # geomagnetic main field, equator to poles
FIELD_REF_TOL = 0.05  # fitted field norm vs the session's reference, relative
DIP_TOL_DEG = 5.0
# poleward of this latitude the geomagnetic dip has the latitude's sign everywhere (the dip equator stays
# within about 15° of the geographic one): a field that points up in the north is an inverted magnetometer
DIP_HEMISPHERE_LAT_DEG = 25.0
DIP_SIGN_MIN_DEG = 10.0  # a dip this far on the wrong side is not a near-horizontal field's scatter
MOUNT_MISALIGNMENT = 0.05  # rad: a unit on its fixture (or held by hand) may be off by ~3° besides its own M
# bounds per axis when the grade is unknown: a consumer MEMS board (MPU-6050 class: zero-rate
# output ±20 °/s, zero-g offset up to ±150 mg; HMC5883L full scale ±8.1 gauss = 810 µT)
GENERIC = {"gyro": units.from_unit(30.0, "deg/s"), "accel": units.from_unit(250.0, "mg"), "mag": 1000.0}
GENERIC_SCALE = 0.05  # accelerometer scale-factor error of such a board, for the static |a| check
# other units a triad's samples are often written in by mistake: (name, SI value of one of them)
_MIXUPS = {"gyro": (("deg/s", units.DEG), ("rad/s but declared deg/s", 1.0 / units.DEG)),
           "accel": (("g", units.G0), ("mg", units.G0 * 1e-3)),
           "mag": (("gauss", 100.0), ("nT", 1e-3), ("mgauss", 0.1))}


class ImplausibleCalibration(WorkbenchError):
    """A calibration failed a physical check; the message names quantity, value and limit."""


@dataclass(frozen=True)
class Failure:
    """One failed check: ``text`` is the one-line message (lab units, labelled)."""

    quantity: str
    text: str


def grade_of(model: str) -> SensorSpec | None:
    """The :class:`SensorSpec` of a unit model that names a grade fixture, else None."""
    return _grade(str(model or ""))


@lru_cache(maxsize=32)
def _grade(model: str) -> SensorSpec | None:
    from workbench.grade_fixtures import grade_names, load_spec

    return load_spec(model) if model in grade_names() else None


def check(cal: CalibrationSet, session=None, result: Mapping | None = None, spec=None) -> list[Failure]:
    """Every failed check of ``cal`` (empty: plausible); session checks first (they name the cause).

    ``session``: the :class:`workbench.session.Session` the set came from (static steps checked,
    its site's gravity, Earth rate and reference field used), or None (export: the set only).
    ``result``: the analysis result dict (a reference dip under ``reference_field``).
    ``spec``: the unit's grade; default the grade named by the set's unit model, if any.
    """
    spec = spec if spec is not None else grade_of(cal.unit.model)
    failures: list[Failure] = []
    if session is not None:
        failures += _axis_checks(session) + _static_checks(session, spec)
    for triad, tc in cal.triads.items():
        failures += _coefficient_checks(triad, tc, spec)
        failures += _matrix_checks(triad, tc)
        if triad == "mag":
            failures += _field_checks(tc, session, result or {})
    failures += _noise_checks(cal)
    return failures


def gate(cal: CalibrationSet, session=None, result: Mapping | None = None, force: bool = False,
         what: str = "calibration") -> CalibrationSet:
    """``cal`` if plausible; with ``force`` the set with its failures in its notes; else raise.

    Raises :class:`ImplausibleCalibration` (exit 2 at the command line) with the first failure.
    A set already carrying forced failures (``notes['plausibility']``) is refused again unless
    forced, so that an export sees what the store was told.
    """
    failures = check(cal, session, result)
    texts = list(dict.fromkeys([*forced_failures(cal), *(f.text for f in failures)]))
    if not texts:
        return cal
    if not force:
        more = f" (+{len(texts) - 1} more)" if len(texts) > 1 else ""
        raise ImplausibleCalibration(f"{what} refused: {texts[0]}{more}; nothing stored or written "
                                     "(--force keeps it, with the failed check in the set's notes)")
    return forced(cal, texts)


def forced(cal: CalibrationSet, texts: list[str]) -> CalibrationSet:
    """``cal`` with ``notes['plausibility'] = {'forced': True, 'failed': texts}``."""
    return replace(cal, notes={**dict(cal.notes), "plausibility": {"forced": True, "failed": list(texts)}})


def forced_failures(cal: CalibrationSet) -> list[str]:
    """The failed checks a set was forced past (empty when it passed)."""
    note = cal.notes.get("plausibility")
    return [str(x) for x in note.get("failed", [])] if isinstance(note, Mapping) else []


# -- coefficients ---------------------------------------------------------------------------
def _show(triad: str, quantity: str, value_si: float) -> str:
    """``value_si`` in the lab unit of ``quantity``; in SI when the lab value would overflow (1e308)."""
    unit = units.unit_of(triad, quantity)
    with np.errstate(over="ignore"):
        lab = units.to_unit(float(value_si), unit)
    if np.isfinite(lab):
        return f"{lab:.3g} {units.label(unit)}".rstrip()
    si = {"gyro": "rad/s", "accel": "m/s^2", "mag": "uT"}[triad] if quantity == "bias" else "1"
    return f"{float(value_si):.3g} {units.label(si)} (SI)".rstrip()


def _limit(grade_sigma: np.ndarray, est_sigma: np.ndarray) -> np.ndarray:
    wide = WIDE * np.asarray(grade_sigma, float)
    est = np.nan_to_num(np.asarray(est_sigma, float), nan=0.0, posinf=0.0)
    return wide + EST_SIGMAS * np.minimum(est, wide)


def _coefficient_checks(triad: str, tc: TriadCalibration, spec) -> list[Failure]:
    m = tc.model
    out: list[Failure] = []
    arrays = {"bias": m.bias, "scale_misalignment": m.scale_misalignment, "nonlinearity": m.nonlinearity,
              "g_sensitivity": m.g_sensitivity}
    if m.thermal is not None:
        arrays.update({"thermal.bias_poly": m.thermal.bias_poly, "thermal.scale_poly": m.thermal.scale_poly})
    for name, arr in arrays.items():
        if arr is not None and not np.all(np.isfinite(arr)):
            return [Failure(f"{triad}.{name}", f"{triad} {name}: NaN or infinite coefficient")]
    ts = None if spec is None else spec.specs.get(triad)
    for axis, b in enumerate(m.bias):
        if ts is None:
            limit = GENERIC[triad]
            src = "a consumer MEMS board's bound; grade unknown"
        else:
            limit = float(_limit(ts.bias, tc.sigma_of("bias"))[axis]) + (EARTH_RATE if triad == "gyro" else 0.0)
            src = f"{WIDE:g}x the {spec.name} grade's 1σ"
        if abs(b) > limit:
            hint = _mixup_hint(triad, abs(b), 0.0, limit) if triad == "gyro" else ""
            out.append(Failure(f"{triad}.bias", f"{triad} bias {'xyz'[axis]} = {_show(triad, 'bias', b)} exceeds "
                                                  f"±{_show(triad, 'bias', limit)} ({src}){hint}"))
    if ts is None:
        return out
    sm, sm_sig = m.scale_misalignment, tc.sigma_of("scale_misalignment")
    for i in range(3):
        for j in range(3):
            if i == j:
                q, lim = "scale_factor", _limit(ts.scale_factor[i], sm_sig[i, j])
            else:
                q, lim = "misalignment", _limit(ts.misalignment[i], sm_sig[i, j]) + MOUNT_MISALIGNMENT
            if abs(sm[i, j]) > lim:
                out.append(Failure(f"{triad}.{q}", f"{triad} {q.replace('_', ' ')} M[{i},{j}] = "
                                                    f"{_show(triad, q, sm[i, j])} exceeds ±{_show(triad, q, lim)} "
                                                    f"({WIDE:g}x the {spec.name} grade's 1σ)"))
    out += _plain(triad, "nonlinearity", m.nonlinearity, ts.nonlinearity, tc.sigma_of("nonlinearity"), spec)
    if m.g_sensitivity is not None and ts.g_sensitivity is not None:
        gs = np.broadcast_to(np.asarray(ts.g_sensitivity, float)[:, None], (3, 3))
        out += _plain(triad, "g_sensitivity", m.g_sensitivity, gs, tc.sigma_of("g_sensitivity"), spec)
    if m.thermal is not None:
        out += _thermal(triad, tc, ts, spec)
    return out


def _plain(triad: str, q: str, values, grade_sigma, est_sigma, spec) -> list[Failure]:
    values = np.asarray(values, float)
    lim = _limit(np.broadcast_to(grade_sigma, values.shape), np.broadcast_to(est_sigma, values.shape))
    bad = np.argwhere(np.abs(values) > lim)
    if not len(bad):
        return []
    idx = tuple(int(k) for k in bad[0])
    unit = units.unit_of(triad, q)
    return [Failure(f"{triad}.{q}", f"{triad} {q.replace('_', ' ')} {list(idx)} = {units.fmt(values[idx], unit, 3)} "
                                    f"exceeds ±{units.fmt(lim[idx], unit, 3)} "
                                    f"({WIDE:g}x the {spec.name} grade's 1σ)")]


def _thermal(triad: str, tc: TriadCalibration, ts, spec) -> list[Failure]:
    """Thermal polynomial column k (k >= 1) vs the grade's spread of the (T - t_ref)^k coefficient."""
    out: list[Failure] = []
    th = tc.model.thermal
    for field, grade, base in (("bias_poly", ts.bias_temp_poly, ts.bias), ("scale_poly", ts.scale_temp_poly,
                                                                            ts.scale_factor)):
        coeffs = getattr(th, field)
        sig = tc.sigma_of(f"thermal.{field}")
        for k in range(coeffs.shape[1]):
            g = base if k == 0 else (grade[:, k - 1] if k - 1 < grade.shape[1] else None)
            if g is None:
                continue
            lim = _limit(g, sig[:, k] if sig.shape == coeffs.shape else np.zeros(3))
            if triad == "gyro" and field == "bias_poly" and k == 0:
                lim = lim + EARTH_RATE
            bad = np.flatnonzero(np.abs(coeffs[:, k]) > lim)
            if len(bad):
                a = int(bad[0])
                unit = units.unit_of(triad, f"thermal.{field}")
                lab = units.thermal_label(triad, field, k)
                out.append(Failure(f"{triad}.thermal.{field}",
                                   f"{triad} thermal {field} {'xyz'[a]} (T-t_ref)^{k} = "
                                   f"{units.to_unit(coeffs[a, k], unit):.3g} {lab} exceeds "
                                   f"±{units.to_unit(lim[a], unit):.3g} {lab} "
                                   f"({WIDE:g}x the {spec.name} grade's 1σ)"))
    return out


def _matrix_checks(triad: str, tc: TriadCalibration) -> list[Failure]:
    sm = np.asarray(tc.model.scale_misalignment, float)
    sv = np.linalg.svd(sm, compute_uv=False)
    what = "soft iron" if triad == "mag" else "scale factor/misalignment"
    if sv[0] >= M_NORM_MAX:
        return [Failure(f"{triad}.M", f"{triad} {what} |M| = {sv[0] * 100:.3g} % (largest singular value of "
                                      f"I+M - I) exceeds {M_NORM_MAX * 100:.0f} %")]
    s = np.linalg.svd(np.eye(3) + sm, compute_uv=False)
    cond = float(s[0] / s[-1]) if s[-1] > 0 else float("inf")
    if cond > COND_MAX:
        return [Failure(f"{triad}.cond", f"{triad} condition number of I+M = {cond:.3g} exceeds {COND_MAX:g}")]
    return []


def _field_checks(tc: TriadCalibration, session, result: Mapping) -> list[Failure]:
    out: list[Failure] = []
    norm = tc.field_norm_ut
    ref = None if session is None else session.site.field_norm_ut
    ref_field = result.get("reference_field") if isinstance(result.get("reference_field"), Mapping) else None
    if ref is None and ref_field is not None:
        ref = ref_field.get("norm_ut")
    if norm is not None:
        if not np.isfinite(norm):
            out.append(Failure("mag.field_norm", "mag field norm: NaN or infinite"))
        elif ref is not None and abs(norm / ref - 1.0) > FIELD_REF_TOL:
            out.append(Failure("mag.field_norm", f"mag field norm {norm:.4g} µT is not within "
                                                 f"{FIELD_REF_TOL:.0%} of the reference {ref:.4g} µT"))
        elif ref is None and not FIELD_RANGE_UT[0] <= norm <= FIELD_RANGE_UT[1]:
            out.append(Failure("mag.field_norm", f"mag field norm {norm:.4g} µT is outside "
                                                 f"{FIELD_RANGE_UT[0]:g}-{FIELD_RANGE_UT[1]:g} µT (the Earth's field)"
                                                 + _mixup_hint("mag", norm, *FIELD_RANGE_UT)))
    fit = result.get("fit") if isinstance(result.get("fit"), Mapping) else {}
    dip = fit.get("dip_rad")
    if dip is None:  # a hand-held fit without the dip model: the dip its calibrated field shows against gravity
        free = result.get("free_quality") if isinstance(result.get("free_quality"), Mapping) else {}
        shown = (free.get("fit") or {}).get("dip_deg") if isinstance(free.get("fit"), Mapping) else None
        dip = None if shown is None else float(np.radians(shown))
    if dip is not None:
        dip_deg = float(np.degrees(dip))
        ref_dip = None if ref_field is None else ref_field.get("dip_deg")
        if not np.isfinite(dip_deg) or abs(dip_deg) > 90.0:
            out.append(Failure("mag.dip", f"mag dip {dip_deg:.3g}° is outside ±90°"))
        elif ref_dip is not None and abs(dip_deg - ref_dip) > DIP_TOL_DEG:
            out.append(Failure("mag.dip", f"mag dip {dip_deg:.4g}° is not within {DIP_TOL_DEG:g}° of the "
                                          f"reference {ref_dip:.4g}°"))
        elif session is not None:
            out += _dip_sign_check(dip_deg, session.site.latitude_deg)
    return out


def _dip_sign_check(dip_deg: float, latitude_deg: float) -> list[Failure]:
    """A dip (°) on the wrong side of the horizontal for the site's latitude (°), poleward of
    :data:`DIP_HEMISPHERE_LAT_DEG`: the magnetometer's overall sign is inverted."""
    if abs(latitude_deg) < DIP_HEMISPHERE_LAT_DEG or dip_deg * np.sign(latitude_deg) > -DIP_SIGN_MIN_DEG:
        return []
    return [Failure("mag.dip", f"mag dip {dip_deg:+.1f}° at latitude {latitude_deg:+.1f}°: the field points "
                               f"{'up' if dip_deg < 0 else 'down'}, where it points "
                               f"{'down' if latitude_deg > 0 else 'up'} (magnetometer axes inverted? negate all "
                               "three in the import profile)")]


def _noise_checks(cal: CalibrationSet) -> list[Failure]:
    for triad, terms in cal.noise.items():
        for term, values in terms.items():
            if term.endswith("_ci95") or values is None:
                continue
            vals = np.array([np.nan if v is None else v for v in values], float)
            if np.any(np.isinf(vals)) or np.any(vals[np.isfinite(vals)] < 0):
                return [Failure(f"{triad}.{term}", f"{triad} noise {term}: negative or infinite value")]
    return []


# -- the session ---------------------------------------------------------------------------------
def _axis_checks(session) -> list[Failure]:
    """The import's axis check (``options['import']['axis_check']``): a gyro whose rotation fits the
    accelerometer or magnetometer only with another axis mapping means the profile's axes are wrong."""
    imp = (session.options or {}).get("import") if isinstance(session.options, Mapping) else None
    checks = imp.get("axis_check") if isinstance(imp, Mapping) else None
    out = []
    for c in checks if isinstance(checks, list) else []:
        if isinstance(c, Mapping) and c.get("agrees") is False:
            out.append(Failure("import.axes", f"import axis check against the {c.get('reference', '?')}: "
                                              f"{c.get('message') or 'the axes disagree'}"))
    return out[:1]


# -- static steps of the session --------------------------------------------------------------
def _static_means(session) -> list[tuple[int, float | None, np.ndarray, np.ndarray, float]]:
    """(step, temperature, mean gyro (3,) rad/s, mean accel (3,) m/s², duration s) of each static step."""
    from workbench.session import ACCEL, GYRO

    out = []
    for st in session.steps:
        if st.kind != "static" or st.table_rate != 0.0:
            continue
        block = next(session.stream([*GYRO, *ACCEL], st.index, batch_rows=1 << 17), None)
        if block is None or not len(block):
            continue
        mean = block.mean(axis=0)
        out.append((st.index, st.temperature_c, mean[:3], mean[3:], len(block) / session.sample_rate_hz))
    return out


def _thermal_allowance(ts, dt: float) -> np.ndarray:
    """WIDE x the grade's bias change over ``dt`` °C from t_ref (per axis, SI)."""
    poly = np.asarray(ts.bias_temp_poly, float)
    return WIDE * np.abs(poly * np.abs(dt) ** np.arange(1, poly.shape[1] + 1)).sum(axis=1) if poly.size else 0.0


def _mixup_hint(triad: str, value: float, lo: float, hi: float) -> str:
    """``'; gyro in deg/s? values look 57.3x too large'`` when ``value`` read in another unit lies in [lo, hi]."""
    for name, f in _MIXUPS[triad]:
        if lo <= float(value) * f <= hi:  # (a Python float: 1e308 x 57 is inf, not a warning)
            ratio = 1.0 / f if f < 1 else f
            size = "large" if f < 1 else "small"
            return f"; {triad} in {name}? values look {ratio:.3g}x too {size}"
    return ""


def _static_checks(session, spec) -> list[Failure]:
    from workbench.session import ACCEL, GYRO

    if session.samples is not None and not all(c in session.samples.columns for c in GYRO + ACCEL):
        return []
    out: list[Failure] = []
    g_site = session.site.gravity
    for step, temp, w, a, dur in _static_means(session):
        dt = 0.0 if temp is None or spec is None else temp - spec.t_ref_c
        gs, as_ = (None, None) if spec is None else (spec.specs.get("gyro"), spec.specs.get("accel"))
        if gs is None:
            w_hi, w_lo = np.sqrt(3) * GENERIC["gyro"] + EARTH_RATE, 0.0
        else:
            brange = np.linalg.norm(WIDE * gs.bias + _thermal_allowance(gs, dt))
            noise = 5 * np.linalg.norm(gs.noise.white) / np.sqrt(max(dur, 1e-3))
            sens = WIDE * np.linalg.norm(gs.g_sensitivity) * g_site if gs.g_sensitivity is not None else 0.0
            w_hi, w_lo = EARTH_RATE + brange + noise + sens, EARTH_RATE - brange - noise - sens
        wn = float(np.linalg.norm(w))
        if wn > w_hi or wn < w_lo:
            bound = f"at most {units.fmt(w_hi, 'deg/s', 3)}" if wn > w_hi else f"at least {units.fmt(w_lo, 'deg/h', 3)}"
            unit = "deg/s" if wn > w_hi else "deg/h"
            out.append(Failure("gyro.static_rate",
                               f"step {step}: static gyro |ω| = {units.fmt(wn, unit, 3)}, {bound} (Earth rate "
                               f"+ {'the ' + spec.name + ' grade' if spec else 'a consumer board'}'s bias range)"
                               + _mixup_hint("gyro", wn, max(w_lo, 0.0), w_hi)))
        if as_ is None:
            tol = np.sqrt(3) * GENERIC["accel"] + GENERIC_SCALE * g_site
        else:
            tol = (np.linalg.norm(WIDE * as_.bias + _thermal_allowance(as_, dt))
                   + WIDE * as_.scale_factor.max() * g_site
                   + 5 * np.linalg.norm(as_.noise.white) / np.sqrt(max(dur, 1e-3)))
        an = float(np.linalg.norm(a))
        if abs(an - g_site) > tol:
            out.append(Failure("accel.static_norm",
                               f"step {step}: static accelerometer |a| = {an:.4g} {units.label('m/s^2')}, local "
                               f"gravity {g_site:.4g} ± {tol:.2g} {units.label('m/s^2')}"
                               + _mixup_hint("accel", an, g_site - tol, g_site + tol)))
    return out[:1] + [f for f in out[1:] if f.quantity != out[0].quantity][:1]
