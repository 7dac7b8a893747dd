"""What was stored with an analysis result: the options that produced it and the figures drawn from it.

A run or campaign writes ``<out>/<procedure>/session/`` (the recording), ``result.json`` and
``figures/*.png`` beside it (``workbench analyze --figures DIR`` writes them into DIR and the stored
result names that folder, ``figures_dir``); the options it analysed with are in ``result.json`` (``options``),
else in the session manifest (``analysis_options``, written by ``workbench run``), else in the
campaign's ``campaign.json`` (``analysis_options[procedure]``). Readers that must show the stored
result, not a re-analysis (the certificate, the dashboard's analysis pages), use these.
"""

from __future__ import annotations

import json
from pathlib import Path


def _read(path: Path) -> dict:
    try:
        doc = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError):
        return {}
    return doc if isinstance(doc, dict) else {}


def stored_options(session_dir: str | Path | None, procedure: str, result: dict | None = None) -> dict | None:
    """The analysis options a stored result was computed with (lab units, as given), None when not recorded."""
    if result and isinstance(result.get("options"), dict):
        return dict(result["options"])
    if not session_dir:
        return None
    folder = Path(session_dir)
    manifest = _read(folder / "session.json")
    if isinstance(manifest.get("analysis_options"), dict):
        return dict(manifest["analysis_options"])
    campaign = _read(folder.parent.parent / "campaign.json").get("analysis_options") or {}
    if procedure in campaign:
        return dict(campaign[procedure])
    return {} if manifest else None


def stored_figures(session_dir: str | Path | None, result: dict | None = None) -> list[Path]:
    """The PNG figures drawn when a stored result was computed: in the folder the result names
    (``figures_dir``, written by ``workbench analyze ... --figures DIR``), else beside the session
    (``../figures/*.png``, a run or campaign)."""
    named = (result or {}).get("figures_dir")
    if isinstance(named, str) and named and Path(named).is_dir():
        return sorted(Path(named).glob("*.png"))
    if not session_dir:
        return []
    return sorted((Path(session_dir).parent / "figures").glob("*.png"))


def _rounded(value):
    if isinstance(value, float):
        return float(f"{value:.4g}")
    if isinstance(value, list):
        return [_rounded(v) for v in value]
    if isinstance(value, dict):
        return {k: _rounded(v) for k, v in value.items()}
    return value


def option_text(value) -> str:
    """A stored option value for people: a string as it is, anything else as JSON with floats to
    4 significant digits (``[0.058023922532, 0.0568]`` -> ``'[0.05802, 0.0568]'``)."""
    return value if isinstance(value, str) else json.dumps(_rounded(value))
