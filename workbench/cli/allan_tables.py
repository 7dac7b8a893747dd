"""The IEEE 952 terms table of ``workbench allan``: one row per term in its lab unit, folded to the console width.

Values through :data:`workbench.analysis.allan_terms.TERM_UNITS` (SI for an unknown quantity),
the 95 % interval in brackets, ``n/o < bound`` for a term not observed.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from rich.table import Table

from workbench.cli import out

if TYPE_CHECKING:
    from workbench.analysis.allan_fit import AllanAnalysis

TERM_NAMES = {"quantization": "Q quantization", "white": "N white noise", "bias_instability": "B bias instability",
              "rrw": "K rate random walk", "rate_ramp": "R rate ramp"}
# rows of the terms table: (row label, term, source); read-offs are the plain-ADEV values
TERM_ROWS = (("Q", "quantization", "fit"), ("N", "white", "fit"), ("B", "bias_instability", "fit"),
             ("K", "rrw", "fit"), ("R", "rate_ramp", "fit"), ("N 1 s", "white", "read_off"),
             ("B min", "bias_instability", "read_off"))


def _term_unit(quantity: str | None, term: str) -> str | None:
    from workbench.analysis.allan_terms import TERM_UNITS

    return TERM_UNITS.get(quantity or "", {}).get(term)


def _value(quantity: str | None, term: str, value_si: float) -> str:
    from workbench import units

    unit = _term_unit(quantity, term)
    return f"{value_si if unit is None else units.to_unit(value_si, unit):.3g}"


def _cell(an: AllanAnalysis, fit, term: str, source: str) -> str:
    if source == "read_off":
        return _value(an.quantity, term, fit.read_off[term])
    est = fit.terms[term]
    if not est.observed:
        return f"n/o < {_value(an.quantity, term, est.ci95[1])}"
    lo, hi = (_value(an.quantity, term, v) for v in est.ci95)
    return f"{_value(an.quantity, term, est.value)} [{lo}, {hi}]"


def terms_tables(an: AllanAnalysis, width: int) -> list[Table]:
    """The IEEE 952 terms as tables at most ``width`` characters wide: one row per term with its lab
    unit in a column of its own, one column per data column (as many per table as fit), the term
    names in the caption; values in the unit of the row, 95 % interval in brackets."""
    from rich import box

    from workbench import units

    unit_text = {term: "SI" if _term_unit(an.quantity, term) is None else units.label(_term_unit(an.quantity, term))
                 for _, term, _ in TERM_ROWS}
    cells = {f.column: [_cell(an, f, term, source) for _, term, source in TERM_ROWS] for f in an.fits}
    label_w = max(len(r[0]) for r in TERM_ROWS)
    cell_w = max([len(c) for col in cells.values() for c in col] + [len(c) for c in cells])
    fixed = label_w + max(len(u) for u in unit_text.values()) + 4  # two columns and their padding
    per_table = max(1, (width - fixed) // (cell_w + 2))
    what = {"gyro": "gyro", "accel": "accel"}.get(an.quantity, "SI input")
    caption = (", ".join(TERM_NAMES.values()) + "; read-offs: N at τ = 1 s, B = min ADEV / 0.664; [95 % interval]; "
               "n/o = not observed, < its 95 % upper bound")
    tables = []
    for start in range(0, len(an.fits), per_table):
        fits = an.fits[start:start + per_table]
        t = Table("term", "unit", *(f.column for f in fits), box=box.SIMPLE_HEAD, pad_edge=False,
                  title=f"IEEE 952 terms ({what})", title_justify="left",
                  caption=caption if start + per_table >= len(an.fits) else None, caption_justify="left")
        for k, (label, term, _) in enumerate(TERM_ROWS):
            t.add_row(label, unit_text[term], *(cells[f.column][k] for f in fits))
        tables.append(t)
    return tables


def print_terms(an: AllanAnalysis) -> None:
    """Print :func:`terms_tables` at the console's width."""
    for t in terms_tables(an, out.width):
        out.print(t)
