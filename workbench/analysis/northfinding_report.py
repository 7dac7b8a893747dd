"""North-finding results for people and files: ``result.json`` content, summary lines, tables.

:func:`to_result` (the result dict in labelled units and the summary lines),
:func:`sequence_table` (thesis table 4.3 over sessions), :func:`pairing_table` (table 4.4).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from workbench.analysis.northfinding_fit import RedundantResult, repeatability
from workbench.angles import wrap_2pi
from workbench.errors import AnalysisError
from workbench.json_values import json_value as _json_num

if TYPE_CHECKING:
    from workbench.analysis.northfinding import NorthFinding


def to_result(nf: NorthFinding) -> tuple[dict, list[str]]:
    """The ``result.json`` dict (keys name their lab unit; rad/s otherwise) and summary lines.

    Keys: ``azimuth_deg`` [0, 360), ``azimuth_sigma_mrad``, ``pair_azimuths_deg``,
    ``pair_times_s``, ``pair_std_mrad``, ``units``, ``gyro_bias`` (3,) rad/s and its sigma,
    ``earth_rate_amplitude`` rad/s with ``earth_rate_expected`` = Omega_e cos lat,
    ``theory`` {``arw_pair_sigma_mrad``, ``allan_pair_sigma_mrad``, ``source``,
    ``averaging_time_s``, ``pair_spacing_s``, ``adev_at_dwell``}, ``azimuth_error_mrad`` when the
    table's zero azimuth is known, ``redundant`` (per pairing, with ``theory_std_mrad`` and
    ``theory_mean_sigma_mrad`` from the grade's noise, bias wander included) for that method.
    """
    from workbench.units import fmt

    th = nf.theory
    res = {
        "method": nf.method,
        "azimuth_deg": float(np.degrees(wrap_2pi(nf.azimuth))),
        "azimuth_sigma_mrad": _json_num(nf.azimuth_sigma * 1e3),
        "units": nf.units,
        "pair_azimuths_deg": _json_num(np.degrees(wrap_2pi(nf.unit_azimuth))),
        "pair_times_s": _json_num(nf.unit_time),
        "pair_std_mrad": _json_num(nf.unit_std * 1e3),
        "gyro_bias": _json_num(nf.gyro_bias),
        "gyro_bias_sigma": _json_num(nf.gyro_bias_sigma),
        "earth_rate_amplitude": _json_num(nf.earth_rate_amplitude),
        "earth_rate_amplitude_sigma": _json_num(nf.earth_rate_amplitude_sigma),
        "earth_rate_expected": nf.expected_amplitude,
        "latitude_deg": float(np.degrees(nf.latitude)),
        "one_axis_ambiguous": nf.ambiguous,
        "theory": {"arw_pair_sigma_mrad": _json_num(th["arw_unit_sigma"] * 1e3),
                   "allan_pair_sigma_mrad": _json_num(th["allan_unit_sigma"] * 1e3),
                   "source": th["source"], "averaging_time_s": th["tau"], "pair_spacing_s": th["spacing"],
                   "adev_at_dwell": _json_num(th["adev_at_dwell"])},
    }
    if nf.azimuth_error is not None:
        res["azimuth_error_mrad"] = nf.azimuth_error * 1e3
    spread = th.get("pairing_spread")
    if isinstance(nf.detail, RedundantResult):
        d = nf.detail
        res["redundant"] = {"bias_source": d.bias_source, "pairings": [
            {"pairing_deg": lab, "mean_deg": float(np.degrees(wrap_2pi(m))), "std_mrad": _json_num(s * 1e3),
             "n": int(d.azimuth.shape[0]),
             "theory_std_mrad": None if spread is None else _json_num(spread.turn_std[k] * 1e3),
             "theory_mean_sigma_mrad": None if spread is None else _json_num(spread.mean_sigma[k] * 1e3)}
            for k, (lab, m, s) in enumerate(zip(d.pairings, d.mean, d.std))]}
    summary = [
        f"azimuth of body x at table zero: {res['azimuth_deg']:.4f} ± {np.degrees(nf.azimuth_sigma):.2g}° (1σ = "
        f"{nf.azimuth_sigma * 1e3:.3g} mrad, {len(nf.unit_azimuth)} {nf.units}s)",
        f"per-{nf.units} std: {nf.unit_std * 1e3:.3g} mrad; theory {th['arw_unit_sigma'] * 1e3:.3g} mrad (ARW only), "
        f"{th['allan_unit_sigma'] * 1e3:.3g} mrad (ADEV at {th['tau']:.0f} s"
        + (f", the averages {th['spacing']:.1f} s apart" if th["spacing"] > th["tau"] * 1.001 else "")
        + f"; {th['source']})",
        f"horizontal Earth rate: {fmt(nf.earth_rate_amplitude, 'deg/h')} "
        f"(Ω_e cos lat = {fmt(nf.expected_amplitude, 'deg/h')})",
        "gyro bias: " + ", ".join(f"{a} {fmt(b, 'deg/h')}" for a, b in zip("xyz", nf.gyro_bias)),
    ]
    if nf.azimuth_error is not None:
        summary.append(f"error against the table's known zero azimuth: {nf.azimuth_error * 1e3:+.3g} mrad")
    if isinstance(nf.detail, RedundantResult):
        summary.append(f"redundant: bias {nf.detail.bias_source}; the theory above is the noise floor with the bias "
                       "known" + ("" if spread is None or not np.isfinite(nf.detail.std).any() else
                                  f"; std over turns {np.nanmedian(nf.detail.std) * 1e3:.3g} mrad (median of the "
                                  f"pairings), {np.median(spread.turn_std) * 1e3:.3g} mrad expected from the noise "
                                  "model with the bias wander over the session"))
    if nf.ambiguous:
        summary.append("one level axis (eq. 4.3): the azimuth may be mirrored (psi or -psi about the pair's home)")
    return res, summary


def sequence_table(results: Sequence[NorthFinding], labels: Sequence[str] | None = None) -> list[dict]:
    """Rows of thesis table 4.3 over sessions: mean azimuth (°), per-unit std (mrad), distance of
    the mean from the mean of all (mrad, Fig. 4.14-4.15) and the session's 1-sigma (mrad)."""
    means = np.array([r.azimuth for r in results])
    _, dist = repeatability(means)
    labels = labels or [str(i + 1) for i in range(len(results))]
    return [{"sequence": lab, "mean_deg": float(np.degrees(r.azimuth)), "std_mrad": r.unit_std * 1e3,
             "distance_mrad": float(d * 1e3), "sigma_mrad": r.azimuth_sigma * 1e3}
            for lab, r, d in zip(labels, results, dist)]


def pairing_table(results: Sequence[NorthFinding]) -> list[dict]:
    """Rows of thesis table 4.4 over redundant sessions: per pairing, the repeatability (max
    distance of each session's pairing mean from the mean over sessions), mrad and degrees."""
    details = [r.detail for r in results]
    if not details or not all(isinstance(d, RedundantResult) for d in details):
        raise AnalysisError("pairing_table: needs redundant-configuration results")
    rows = []
    for k, lab in enumerate(details[0].pairings):
        rep, _ = repeatability(np.array([d.mean[k] for d in details]))
        rows.append({"pairing_deg": lab, "repeatability_mrad": rep * 1e3, "repeatability_deg": float(np.degrees(rep)),
                     "std_over_turns_mrad": float(np.sqrt(np.mean([d.std[k] ** 2 for d in details])) * 1e3)})
    return rows
