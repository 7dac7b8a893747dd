"""CSV output of ``workbench allan --out``: the curves (IEEE 952 path), a statistic (``--stat``), GMWM parameters.

Values in the SI unit of the input (rad/s, m/s^2; tau in s), floats as Python's shortest
round-trip repr; the file is written atomically.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from workbench.analysis.allan_fit import AllanAnalysis

CURVE_COLUMNS = ("column", "tau_s", "m", "n", "adev", "adev_lo95", "adev_hi95", "edf", "alpha")


def curve_rows(an: AllanAnalysis) -> list[tuple]:
    """One row per column and tau (:data:`CURVE_COLUMNS`): tau_s, adev and its 95 % interval
    (input SI unit), edf, alpha."""
    c = an.ci.curve
    return [(col, float(c.tau[k]), int(c.m[k]), int(c.n[k]), float(c.dev[k, j]), float(an.ci.lo[k, j]),
             float(an.ci.hi[k, j]), float(an.ci.edf[k, j]), int(an.ci.alpha[k, j]))
            for j, col in enumerate(c.columns) for k in range(len(c.tau))]


def write_csv(path: Path, header: tuple[str, ...] | list[str], rows: list[tuple]) -> None:
    """A CSV file of ``rows`` (floats as Python's shortest round-trip repr, as pandas writes them),
    written atomically."""
    import csv
    import io

    from workbench.files import atomic_write_text

    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(header)
    writer.writerows(rows)
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_text(path, buf.getvalue())


FAMILY_COLUMNS = ("column", "tau", "dev", "dev_lo", "dev_hi", "n", "alpha", "edf")


def family_rows(results: list) -> list[tuple]:
    """One row per column and tau (:data:`FAMILY_COLUMNS`, SI of the input; NaN written as empty)."""
    def num(v: float) -> float | str:
        return "" if v != v else float(v)

    return [(col, float(c.curve.tau[k]), float(c.curve.dev[k]), num(c.lo[k]), num(c.hi[k]), int(c.curve.n[k]),
             num(c.alpha[k]), num(c.edf[k]))
            for col, c in results for k in range(len(c.curve.tau))]


GMWM_COLUMNS = ("column", "parameter", "value", "lo95", "hi95")
