"""Streamlit glue every dashboard page needs: the store, errors, lab units, links.

- :func:`store` — the store named by ``WORKBENCH_DB`` (cached per URL);
- :func:`show_error` / :func:`guarded` — a :class:`WorkbenchError` as a readable ``st.error``;
- :func:`lab` / :func:`lab_array` — an SI value (± sigma) in a lab unit, through ``workbench.units``;
- :func:`lab_label` — a snake-case name with a unit suffix for people (``dwell_s`` -> ``dwell (s)``);
- :func:`plain_field` — a labelled value typed by a user (a serial), shown whole and never as markup;
- :func:`md_escape` — user text (a path, a model, an error naming them) made literal inside Markdown;
- :func:`format_duration`, :func:`page_link`.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import re

import numpy as np
import streamlit as st

from workbench import units
from workbench.errors import WorkbenchError
from workbench.store import Store, default_url


@st.cache_resource(show_spinner=False)
def _store(url: str) -> Store:
    return Store(url)


def store() -> Store:
    """The store named by ``WORKBENCH_DB`` (default ``sqlite:///workbench.db``); raises StoreError."""
    return _store(default_url())


def in_store(set_id: str) -> bool:
    """Whether the store holds calibration set ``set_id``."""
    try:
        store().get_set(set_id)
    except WorkbenchError:
        return False
    return True


MARKUP = re.compile(r"([\\`*\[\]<>$~])")  # what starts emphasis, code, a link, HTML, LaTeX, a colour directive


def md_escape(text: str) -> str:
    """``text`` with every character that starts Markdown markup backslash-escaped, so ``st.error``,
    ``st.caption`` and their kind show it as typed (a file ``[x](http://...)**b**`` is no link, no bold)."""
    return MARKUP.sub(r"\\\1", str(text))


def show_error(exc: BaseException, context: str = "") -> None:
    """Show ``exc`` as a one-line ``st.error`` (a WorkbenchError's message names the place at fault;
    it holds user text, shown literally)."""
    kind = type(exc).__name__
    prefix = f"{md_escape(context)}: " if context else ""
    if isinstance(exc, WorkbenchError):
        st.error(f"{prefix}{md_escape(str(exc))}  \n({kind})", icon="⚠️")
    else:  # a bug in a procedure: say so, but keep the page usable
        st.error(f"{prefix}unexpected {kind}: {md_escape(str(exc)[:300])}", icon="🐞")


@contextmanager
def guarded(context: str = "", catch_all: bool = False) -> Iterator[None]:
    """Run a block; a WorkbenchError (or any error with ``catch_all``) becomes :func:`show_error`.

    The page continues after the block, so callers must not rely on values the block would set.
    """
    try:
        yield
    except WorkbenchError as exc:
        show_error(exc, context)
    except Exception as exc:  # noqa: BLE001 - only with catch_all, for third-party procedure code
        if not catch_all:
            raise
        show_error(exc, context)


def lab(value_si: Any, unit: str, sigma_si: Any = None, digits: int = 4) -> str:
    """``value_si`` (± ``sigma_si``) in lab ``unit`` with its label, e.g. ``'0.21 ± 0.01 °/h'``: the
    dashboard's spelling of ``units.pm`` (NaN / None value: "not observed"; NaN sigma: "(σ not observed)").

    Units are those of ``workbench.units`` (``deg/h``, ``deg/sqrt(h)``, ``mg``, ``ug/sqrt(Hz)``, ``ppm``, ...).
    """
    return units.pm(value_si, sigma_si, unit, digits)


def lab_array(values_si: Any, unit: str) -> np.ndarray:
    """An SI array converted to lab ``unit`` (NaN kept), for tables and plots."""
    return np.asarray(units.to_unit(np.asarray(values_si, float), unit), float)


# unit suffixes of names (longest first) -> the lab unit shown in labels and column headers
OPTION_UNITS = (("_deg_h_sqrt_h", "°/h/√h"), ("_m_s_h_sqrt_h", "m/s/h/√h"), ("_c_per_min", "°C/min"),
                ("_deg_h", "°/h"), ("_deg_s", "°/s"), ("_dps2", "°/s²"), ("_dps", "°/s"), ("_deg", "°"),
                ("_mrad", "mrad"), ("_mg", "mg"), ("_ppm", "ppm"), ("_ut", "µT"), ("_hz", "Hz"), ("_s", "s"),
                ("_c", "°C"))


def lab_label(name: str) -> str:
    """A snake-case name with a unit suffix (an option, a table column) for people:
    ``'gyro_bias_instability_deg_h'`` -> ``'gyro bias instability (°/h)'``."""
    for suffix, unit in OPTION_UNITS:
        if name.endswith(suffix) and len(name) > len(suffix):
            return f"{name[:-len(suffix)].replace('_', ' ')} ({unit})"
    return name.replace("_", " ")


def plain_field(container: Any, label: str, value: str) -> None:
    """``label`` over ``value`` in ``container`` (a column or ``st``), for values a user typed (a unit's serial,
    a procedure name from a manifest): the whole value, wrapped, never truncated as ``st.metric`` does and
    never parsed as Markdown or HTML (``st.metric`` parses its value)."""
    container.caption(label)
    container.text(value, wrap=True, width="stretch")


def format_duration(seconds: float) -> str:
    """``3725`` -> ``'1 h 02 min 05 s'``."""
    s = int(round(seconds))
    h, rem = divmod(s, 3600)
    m, sec = divmod(rem, 60)
    return f"{h} h {m:02d} min {sec:02d} s" if h else (f"{m} min {sec:02d} s" if m else f"{sec} s")


def page_link(page: str, label: str) -> None:
    """A link to another dashboard page (``NN_name.py``, with or without its folder); plain text outside app.py."""
    from streamlit.errors import StreamlitAPIException

    try:
        st.page_link(f"dashboard/pages/{Path(page).name}", label=label)
    except StreamlitAPIException:  # the page was run on its own (no st.navigation)
        st.caption(f"{label} ({page})")
