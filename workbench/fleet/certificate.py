"""Calibration certificates: one HTML page (and PDF where Chromium is available) per stored set.

Everything on the certificate comes from the store and what was stored with the sessions,
nothing is re-analysed or typed in:

- coefficients and noise terms of the set (``workbench.coefficients``, lab units of
  ``workbench.units``) with expanded uncertainties U = k·u, k = 2;
- the summary and options of each procedure's stored result, and the figures drawn when
  that result was computed (``figures/*.png`` beside the session's folder);
- reference equipment and its traceability from the rig configuration recorded with each
  session (``rig_config`` of ``session.json``), ambient conditions from the session manifests;
- the approval recorded in the store; a certificate number derived from the set.

User text (serials, names, comments) is escaped (Jinja autoescape on). The PDF is printed by
one headless Chromium process with JavaScript blocked in its profile and every network request
sent nowhere; the page also carries a Content-Security-Policy that allows no script and no remote
resource.
"""

from __future__ import annotations

import base64
import json
import os
import shutil
import signal
import subprocess
import tempfile
import time
from collections.abc import Callable
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
from jinja2 import Environment, FileSystemLoader

from workbench import __version__
from workbench.calset import TRIADS, CalibrationSet, atomic_write_text
from workbench.coefficients import TRIAD_TITLES, ci_text, noise_rows, sigma_text, thermal_reference, triad_rows
from workbench.coefficients import value_text
from workbench.errors import WorkbenchError
from workbench.stored import option_text, stored_figures, stored_options

TEMPLATES = Path(__file__).resolve().parents[1] / "templates"
COVERAGE_K = 2.0  # expanded uncertainty U = k u (about 95 % coverage for a normal distribution)
CHROMIUM_ARGS = ("--headless", "--no-sandbox", "--disable-gpu", "--no-first-run", "--disable-extensions",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync",
                 "--disable-default-apps",
                 # belt and braces beside the request filter: any request would go to a proxy that does not exist
                 "--proxy-server=http://127.0.0.1:9", "--proxy-bypass-list=<-loopback>")

Progress = Callable[[str], None]


def certificate_number(cal: CalibrationSet, version: int | None) -> str:
    """A stable certificate number: ``WB-<serial>-v<version>-<first 8 hex of the set id>``."""
    return f"WB-{cal.unit.serial}-v{version if version is not None else 0}-{cal.id[:8]}"


def _triad_rows(cal: CalibrationSet, triad: str) -> list[dict]:
    return [{"name": r.name, "value": value_text(r.value), "unit": r.unit,
             "u": sigma_text(r.sigma), "U": sigma_text(r.sigma, COVERAGE_K)} for r in triad_rows(cal, triad)]


def _noise_rows(cal: CalibrationSet) -> list[dict]:
    return [{"name": f"{r.triad} {r.term.replace('_', ' ')} {r.axis}",
             "value": "not observed" if not np.isfinite(r.value) else f"{r.value:.4g}",
             "ci95": ci_text(r.ci95), "unit": r.unit} for r in noise_rows(cal)]


def _manifest(path: str | None) -> dict | None:
    if not path:
        return None
    try:
        return json.loads((Path(path) / "session.json").read_text())
    except (OSError, json.JSONDecodeError):
        return None


def _ambient(manifest: dict) -> str:
    """Temperatures a session was recorded at, from its manifest (setpoints and the chamber at the end)."""
    temps = [s["temperature_c"] for s in manifest.get("steps", []) if s.get("temperature_c") is not None]
    state = manifest.get("rig_state") or {}
    parts = []
    if temps:
        lo, hi = min(temps), max(temps)
        parts.append(f"setpoints {lo:.1f} °C" if lo == hi else f"setpoints {lo:.1f} .. {hi:.1f} °C")
    if state.get("air_c") is not None:
        parts.append(f"chamber air {float(state['air_c']):.1f} °C at the end")
    if state.get("unit_c") is not None:
        parts.append(f"unit {float(state['unit_c']):.1f} °C at the end")
    return "; ".join(parts) or "not recorded"


def _rig_equipment(ref: str) -> tuple[str, list[dict]]:
    """(rig name, reference instruments) of the rig file a session names: a YAML path as the runner
    records it is read with the schema alone (without the SI conversion of
    :func:`workbench.rigconfig.load_rig_config` and what it imports); a rig name through it."""
    path = Path(ref)
    if not path.suffix or not path.is_file():
        from workbench.rigconfig import load_rig_config

        cfg = load_rig_config(ref)
        return cfg.name, [dict(r) for r in cfg.reference_equipment]
    from workbench.rigschema import parse_rig_file
    from workbench.safe_yaml import load_yaml_file

    f = parse_rig_file(load_yaml_file(path), str(path))
    return f.name or f.driver, [r.model_dump() for r in f.reference_equipment]


def _reference_equipment(manifests: list[dict]) -> tuple[list[dict], list[str]]:
    """Reference instruments of the rig configurations the sessions were recorded with (deduplicated)."""
    seen, equipment, notes = set(), [], []
    for m in manifests:
        ref = m.get("rig_config")
        if not ref or ref in seen:
            continue
        seen.add(ref)
        try:
            name, instruments = _rig_equipment(ref)
        except WorkbenchError as exc:
            notes.append(f"rig configuration of session {m.get('id', '?')[:8]} not readable ({exc}): "
                         "its reference equipment is not stated")
            continue
        equipment += [{"rig": name, **item} for item in instruments]
        if not instruments:
            notes.append(f"rig {name} ({ref}) lists no reference equipment")
    return equipment, notes


def _figures(folder: Path | None, result: dict) -> list[tuple[str, str]]:
    """(title, base64 PNG) of the figures drawn when the session's stored ``result`` was computed."""
    return [(p.stem.replace("_", " "), base64.b64encode(p.read_bytes()).decode())
            for p in stored_figures(folder, result)]


def _sessions(cal: CalibrationSet, store, progress: Progress) -> tuple[list[dict], list[str]]:
    """One entry per provenance session: procedure, stored result (summary, options), rig, ambient, figures."""
    paths = {s.id: s.path for s in store.list_sessions(cal.unit.serial)}
    results = {}
    for r in store.list_results(serial=cal.unit.serial):  # newest first: keep the newest per session
        results.setdefault(r["session_id"], r["result"])
    out, notes = [], []
    for prov in cal.provenance.sessions:
        progress(f"session {prov['id'][:8]} ({prov['procedure']})")
        path = paths.get(prov["id"])
        manifest = _manifest(path)
        if manifest is not None and manifest.get("id") != prov["id"]:
            manifest = None  # the folder now holds another recording
        result = results.get(prov["id"], {})
        figures = _figures(Path(path), result) if manifest is not None else []
        if manifest is None:
            notes.append(f"session {prov['id'][:8]} ({prov['procedure']}): recording not found; its rig, ambient "
                         "conditions and figures cannot be stated")
        elif not figures:
            notes.append(f"session {prov['id'][:8]} ({prov['procedure']}): no figures were stored with its result")
        options = (stored_options(path, prov["procedure"], result) if manifest is not None else None) or {}
        out.append({"id": prov["id"], "procedure": prov["procedure"], "sha256": prov.get("sha256", ""),
                    "rig": prov.get("rig") or (manifest or {}).get("rig") or "",
                    "recorded": (manifest or {}).get("created", ""),
                    "ambient": _ambient(manifest) if manifest is not None else "not recorded",
                    "summary": [str(s) for s in result.get("summary", [])],
                    "warnings": [str(w) for w in result.get("warnings", [])],
                    "options": {k: option_text(v) for k, v in options.items()},
                    "software": (result.get("software") or {}).get("workbench", ""),
                    "figures": figures, "manifest": manifest})
    return out, notes


def render_certificate(cal: CalibrationSet, store, progress: Progress | None = None) -> str:
    """The certificate HTML of a stored set (absent triads are shown as absent, not omitted)."""
    say = progress or (lambda _msg: None)
    say("coefficients")
    info = next((i for i in store.list_sets(cal.unit.serial) if i.id == cal.id), None)
    version = info.version if info else None
    sessions, notes = _sessions(cal, store, say)
    say("reference equipment")
    equipment, eq_notes = _reference_equipment([s["manifest"] for s in sessions if s["manifest"] is not None])
    say("template")
    env = Environment(loader=FileSystemLoader(TEMPLATES), autoescape=True)  # every value escaped
    return env.get_template("certificate.html.j2").render(
        cal=cal, number=certificate_number(cal, version), version=version, k=f"{COVERAGE_K:g}",
        triads=[(TRIAD_TITLES[t], t, _triad_rows(cal, t) if t in cal.triads else None,
                 thermal_reference(cal, t) if t in cal.triads else None) for t in TRIADS],
        noise=_noise_rows(cal), sessions=sessions, notes=notes + eq_notes, equipment=equipment,
        approval=store.approval(cal.id), issued=datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC"),
        software=__version__)


# a fresh browser profile with JavaScript blocked for every site (Chromium's content setting 2 = block)
PROFILE_PREFERENCES = {"profile": {"default_content_setting_values": {"javascript": 2}}}


def chromium_command(chromium: str, profile: Path, *action: str) -> list[str]:
    """The headless Chromium command line used for certificates: a throw-away ``profile`` folder
    (:data:`PROFILE_PREFERENCES`, no script runs), every request sent to a proxy that does not exist
    (nothing is fetched, loopback included), then ``action`` (e.g. ``--print-to-pdf=F URL``)."""
    return [chromium, *CHROMIUM_ARGS, f"--user-data-dir={profile}", *action]


def new_profile(folder: Path) -> Path:
    """Write the JavaScript-blocking browser profile into ``folder`` (returned)."""
    (folder / "Default").mkdir(parents=True, exist_ok=True)
    (folder / "Default" / "Preferences").write_text(json.dumps(PROFILE_PREFERENCES))
    return folder


def print_pdf(html_path: Path, pdf_path: Path, chromium: str, timeout_s: float = 120.0) -> Path:
    """Print ``html_path`` to ``pdf_path`` (A4, the page's own ``@page`` margins and page numbers).

    One headless Chromium process prints the file (``--print-to-pdf``; no driver process between):
    JavaScript is blocked in its profile, every request goes to a proxy that does not exist, and
    the page's Content-Security-Policy allows no script and no remote resource. The PDF is
    written beside ``pdf_path`` and renamed into place, so a reader never sees half of one.
    """
    tmp_pdf = pdf_path.with_name(f".{pdf_path.name}.tmp")
    tmp_pdf.unlink(missing_ok=True)
    with tempfile.TemporaryDirectory(prefix="workbench-chromium-") as tmp:
        cmd = chromium_command(chromium, new_profile(Path(tmp)), "--no-pdf-header-footer",
                               f"--print-to-pdf={tmp_pdf}", html_path.resolve().as_uri())
        proc = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                text=True, start_new_session=True)
        try:
            _, stderr = proc.communicate(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)  # its own process group: renderer and GPU processes too
            proc.communicate()
            tmp_pdf.unlink(missing_ok=True)
            raise WorkbenchError(f"{pdf_path}: Chromium did not print the certificate within {timeout_s:g} s") from None
    ok = tmp_pdf.exists() and tmp_pdf.read_bytes()[:5] == b"%PDF-"
    if not ok:
        tmp_pdf.unlink(missing_ok=True)
        last = next((line for line in reversed(stderr.splitlines()) if line.strip()), "no output")
        raise WorkbenchError(f"{pdf_path}: Chromium could not print the certificate (exit {proc.returncode}: {last})")
    tmp_pdf.replace(pdf_path)
    return pdf_path


def find_chromium() -> str | None:
    """The Chromium executable that prints certificates (``chromium`` or ``chromium-browser`` on PATH), or None."""
    return shutil.which("chromium") or shutil.which("chromium-browser")


def write_certificate(cal: CalibrationSet, store, out: Path, pdf: bool = True,
                      progress: Progress | None = None) -> list[Path]:
    """Write ``out`` (HTML) and, where Chromium is installed, the PDF beside it; ``progress(msg)`` per stage."""
    say = progress or (lambda _msg: None)
    t0 = time.monotonic()
    written = [atomic_write_text(out, render_certificate(cal, store, say))]
    chromium = find_chromium()
    if pdf and chromium:
        say(f"PDF (HTML in {time.monotonic() - t0:.1f} s)")
        written.append(print_pdf(out, out.with_suffix(".pdf"), chromium))
    return written
