"""Calibration certificates: one HTML page (and PDF where Chromium is available) per calibrated unit.

Everything on the page comes from the store: the set (coefficients, uncertainties,
provenance), the stored results of its sessions, and the figures, re-drawn by the procedures
from the recorded sessions (whose SHA-256 must match the provenance). Nothing is typed in.
"""

from __future__ import annotations

import base64
import io
import shutil
import subprocess
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
from jinja2 import Environment, FileSystemLoader, select_autoescape

from workbench import __version__
from workbench.calset import TRIADS, CalibrationSet, atomic_write_text
from workbench.errors import WorkbenchError
from workbench.units import DISPLAY, fmt, to_unit

TEMPLATES = Path(__file__).resolve().parents[1] / "templates"


def _png(fig) -> str:
    import matplotlib.pyplot as plt

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, bbox_inches="tight")
    plt.close(fig)
    return base64.b64encode(buf.getvalue()).decode()


def _triad_rows(cal: CalibrationSet, triad: str) -> list[dict]:
    tc = cal.triads[triad]
    unit = DISPLAY[triad]["bias"]
    rows = []
    b, bs = tc.model.bias, tc.sigma_of("bias")
    for i in range(3):
        rows.append({"name": f"bias {'xyz'[i]}", "value": f"{to_unit(b[i], unit):.5g}", "unit": unit,
                     "sigma": "not observed" if not np.isfinite(bs[i]) else f"{to_unit(bs[i], unit):.2g}"})
    m, ms = tc.model.scale_misalignment, tc.sigma_of("scale_misalignment")
    for i in range(3):
        for j in range(3):
            scale, u = (1e-6, "ppm") if i == j else (1e-3, "mrad")
            name = f"scale factor {'xyz'[i]}" if i == j else f"misalignment M[{'xyz'[i]},{'xyz'[j]}]"
            rows.append({"name": name, "value": f"{m[i, j] / scale:.4g}", "unit": u,
                         "sigma": "not observed" if not np.isfinite(ms[i, j]) else f"{ms[i, j] / scale:.2g}"})
    if triad == "mag" and tc.field_norm_ut is not None:
        rows.append({"name": "field norm", "value": f"{tc.field_norm_ut:.4g}", "unit": "µT",
                     "sigma": "not observed" if tc.field_norm_ut_sigma is None else f"{tc.field_norm_ut_sigma:.2g}"})
    return rows


def _noise_rows(cal: CalibrationSet) -> list[dict]:
    rows = []
    for triad, terms in cal.noise.items():
        for term, values in terms.items():
            if term.endswith("_ci95"):
                continue
            unit = DISPLAY[triad].get("noise_white" if term in ("arw", "vrw") else term)
            ci = terms.get(term + "_ci95") or [None] * 3
            for i, v in enumerate(values):
                interval = ci[i]
                rows.append({"name": f"{triad} {term} {'xyz'[i]}",
                             "value": fmt(v, unit) if unit else ("not observed" if v is None else f"{v:.3g}"),
                             "ci95": "" if interval is None or unit is None else
                             f"{to_unit(interval[0], unit):.3g} .. {to_unit(interval[1], unit):.3g}"})
    return rows


def _figures(cal: CalibrationSet, store) -> tuple[list[dict], list[str]]:
    """Figures re-drawn from the set's sessions; notes for sessions that cannot be found or changed."""
    from workbench.calset import file_sha256
    from workbench.registry import procedure
    from workbench.session import load_session, samples_file

    paths = {s.id: s.path for s in store.list_sessions(cal.unit.serial)}
    figs, notes = [], []
    for prov in cal.provenance.sessions:
        path = paths.get(prov["id"])
        if not path or not Path(path).exists():
            notes.append(f"session {prov['id'][:8]} ({prov['procedure']}): recording not found; figures omitted")
            continue
        sfile = samples_file(Path(path))
        if sfile is None or file_sha256(sfile) != prov["sha256"]:
            notes.append(f"session {prov['id'][:8]}: samples do not match the recorded SHA-256; figures omitted")
            continue
        proc = procedure(prov["procedure"])
        result = proc.analyze(load_session(path))
        for name, fig in proc.figures(result).items():
            figs.append({"title": f"{prov['procedure']}: {name.replace('_', ' ')}", "png": _png(fig)})
    return figs, notes


def render_certificate(cal: CalibrationSet, store, with_figures: bool = True) -> str:
    """The certificate HTML of a stored set (absent triads are shown as absent, not omitted)."""
    results = [r for r in store.list_results(serial=cal.unit.serial)
               if r["session_id"] in {s["id"] for s in cal.provenance.sessions}]
    figs, notes = _figures(cal, store) if with_figures else ([], [])
    approvals = [i for i in store.list_sets(cal.unit.serial) if i.id == cal.id]
    env = Environment(loader=FileSystemLoader(TEMPLATES), autoescape=select_autoescape(["html"]))
    return env.get_template("certificate.html.j2").render(
        cal=cal, triads=[(t, _triad_rows(cal, t) if t in cal.triads else None) for t in TRIADS],
        noise=_noise_rows(cal), results=results, figures=figs, notes=notes,
        approved_by=approvals[0].approved_by if approvals else None,
        version=approvals[0].version if approvals else None,
        issued=datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC"), software=__version__)


def write_certificate(cal: CalibrationSet, store, out: Path, pdf: bool = True) -> list[Path]:
    """Write ``out`` (HTML) and, where Chromium is installed, the PDF beside it."""
    written = [atomic_write_text(out, render_certificate(cal, store))]
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    if pdf and chromium:
        pdf_path = out.with_suffix(".pdf")
        proc = subprocess.run([chromium, "--headless", "--no-sandbox", "--disable-gpu", "--no-first-run",
                               "--disable-background-networking", "--disable-component-update", "--disable-sync",
                               f"--print-to-pdf={pdf_path}", "--no-pdf-header-footer", out.resolve().as_uri()],
                              capture_output=True, timeout=120)
        if proc.returncode != 0 or not pdf_path.exists():
            raise WorkbenchError(f"{pdf_path}: Chromium could not print the certificate")
        written.append(pdf_path)
    return written
