"""The import summary: what each stream held, how its instants were found, what was flagged and done.

:func:`import_summary` builds a JSON-ready dict (SI, stored in the session's
``options["import"]``); :func:`summary_lines` turns it into the lines ``workbench import``
prints (lab units: Hz, ms, ppm, %).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from workbench.importers.merge import Merged
from workbench.importers.streams import Stream
from workbench.session import FLAG_REPEATED, FLAG_SATURATED, StepRecord


def _stream_entry(s: Stream) -> dict:
    entry: dict = {"file": s.source, "samples": int(len(s.t)), "rate_hz": float(s.rate_hz),
                   "columns": list(s.values.columns), "time": "arrival" if s.clock is not None else "sample",
                   "repeated": int(s.repeated.sum()) if s.checks_repeats else None,
                   "saturated": int(s.saturated.sum()), "duration_s": float(s.t[-1] - s.t[0]),
                   "trailing_zero_rows_dropped": s.trailing_zero_rows, "damage": s.damage}
    if s.clock is not None:
        c = s.clock
        p50, p99, pmax = c.latency_percentiles_ms()
        entry["clock"] = {"latency_median_s": p50 / 1e3, "latency_p99_s": p99 / 1e3, "latency_max_s": pmax / 1e3,
                          "instant_uncertainty_s": c.envelope_noise_s, "drift_ppm": c.drift_ppm,
                          "drift_resolution_ppm": c.drift_resolution_ppm,
                          "gaps": [{"row": r, "lost_samples": n, "duration_s": d} for r, n, d in c.gaps]}
    return entry


def import_summary(streams: Mapping[str, Stream], base: str, merged: Merged, steps: Sequence[StepRecord],
                   sectioned: bool) -> dict:
    """JSON-ready summary of an import (see the module docstring)."""
    flags = merged.samples["flags"].to_numpy()
    flagged = {}
    for triad in ("gyro", "accel", "mag"):
        flagged[triad] = {"saturated": int(np.count_nonzero(flags & FLAG_SATURATED[triad])),
                          "repeated": int(np.count_nonzero(flags & FLAG_REPEATED[triad]))}
    entries = {n: _stream_entry(s) for n, s in streams.items()}
    names = list(streams)
    for i, n in enumerate(names):  # streams of one read share their stamps: say so once
        same = next((m for m in names[:i] if np.array_equal(streams[m].t, streams[n].t)), None)
        if same is not None:
            entries[n]["same_instants_as"] = same
    return {"time_base": base, "streams": entries,
            "interpolation": "linear, repeats left out, never across a stream gap" if len(streams) > 1 else None,
            "dropped_rows": merged.dropped, "samples": int(len(flags)), "flagged": flagged,
            "steps": "sections" if sectioned else f"{len(steps)} free step(s), split at sampling gaps"}


def summary_lines(summary: Mapping) -> list[str]:
    """Lines for the terminal (lab units), one per stream and one per action."""
    lines = []
    for name, e in summary["streams"].items():
        base = " (time base)" if name == summary["time_base"] else ""
        rep = "" if e["repeated"] is None else f", repeated {e['repeated']} ({100 * e['repeated'] / e['samples']:.1f} %)"
        lines.append(f"{name}{base}: {e['samples']} samples, {e['duration_s']:.1f} s, {e['rate_hz']:.3f} Hz, "
                     f"{', '.join(e['columns'])}{rep}, saturated {e['saturated']} "
                     f"({100 * e['saturated'] / e['samples']:.1f} %)"
                     + (f"; {e['trailing_zero_rows_dropped']} all-zero rows at the end dropped (unfilled buffer)"
                        if e.get("trailing_zero_rows_dropped") else ""))
        if e.get("damage"):
            lines.append(f"  warning: {e['damage']['text']}; the stream's last sample is at "
                         f"{e['damage']['last_time_s']:.6f} s on the log's clock")
        c = e.get("clock")
        if e.get("same_instants_as"):
            lines.append(f"  same instants as {e['same_instants_as']} (one read): copied, not interpolated")
        elif c is not None:
            lost = sum(g["lost_samples"] for g in c["gaps"])
            lines.append(f"  arrival stamps -> sample clock: latency median {1e3 * c['latency_median_s']:.1f} ms, "
                         f"99 % {1e3 * c['latency_p99_s']:.1f} ms, max {1e3 * c['latency_max_s']:.1f} ms; "
                         f"instants ±{1e3 * c['instant_uncertainty_s']:.1f} ms; rate spread over 5-s intervals "
                         f"{c['drift_ppm']:.0f} ppm (resolution {c['drift_resolution_ppm']:.0f}); "
                         f"gaps {len(c['gaps'])} ({lost} samples lost)")
    if summary.get("interpolation"):
        dropped = ", ".join(f"{k} {v}" for k, v in summary["dropped_rows"].items() if v)
        lines.append(f"merged onto {summary['time_base']}'s instants: {summary['interpolation']}; "
                     f"rows dropped (no data of a stream there): {dropped or 'none'}")
    fl = summary["flagged"]
    marks = [f"{t} {k} {v}" for t, d in fl.items() for k, v in d.items() if v]
    lines.append(f"{summary['samples']} samples kept; rows flagged (left out of fits): {', '.join(marks) or 'none'}")
    lines.append(f"steps: {summary['steps']}")
    lines.extend(c["message"] for c in summary.get("axis_check", []))
    return lines
