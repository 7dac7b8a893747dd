"""End-to-end on what the README's main job stores: the dashboard in Debian's Chromium on a campaign store.

The store is filled by the real commands: ``workbench run campaign --unit
fixtures/units/industrial_mems.yaml --rig sim`` (version 1: the merged set of allan,
multiposition, rate, thermal and magnetometer, with noise terms and thermal polynomials), then
``workbench run multiposition`` of the same unit (version 2: a partial set, so the diff has
coefficients version 2 did not observe). The browser then checks, on 127.0.0.1:

- every page opens without an exception or an "unexpected" error box, and the analysis pages
  show the campaign's stored results (not a re-analysis with defaults);
- the Calibration sets page shows the merged set; its downloads parse back to that set;
- approval, then the certificate (HTML and PDF downloads, from the store only);
- the v1 -> v2 diff states exactly what ``workbench.diff.diff_sets`` finds: changes in sigma only
  where both versions observed the coefficient, the rest "not observed", never an alarm.

Screenshots: ``test-artifacts/dashboard/campaign/``. Waits are on Streamlit's script state
(``conftest.Browser``) with generous time-outs, never fixed sleeps.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

pytestmark = pytest.mark.e2e

REPO = Path(__file__).resolve().parents[2]
ARTIFACTS = REPO / "test-artifacts" / "dashboard" / "campaign"
UNIT = REPO / "fixtures" / "units" / "industrial_mems.yaml"
SERIAL = "industrial_mems-1"  # the unit drawn with seed 1
CAMPAIGN_TIMEOUT_S = 1800.0  # ~35 s idle; the shared 2-core machine runs at load 10+
PROCEDURES = ["allan", "multiposition", "rate", "thermal", "magnetometer"]


def _workbench(env: dict, *args: str) -> str:
    done = subprocess.run([sys.executable, "-m", "workbench", *args], cwd=str(REPO), env=env, capture_output=True,
                          text=True, timeout=CAMPAIGN_TIMEOUT_S)
    assert done.returncode == 0, f"workbench {' '.join(args)} exited {done.returncode}: {done.stderr[-2000:]}"
    return done.stdout


@pytest.fixture(scope="module")
def campaign(dashboard_app, tmp_path_factory):
    """A store filled by the campaign (v1) and a multi-position run of the same unit (v2); the app on it."""
    tmp = tmp_path_factory.mktemp("campaign")
    env = {**os.environ, "WORKBENCH_DB": f"sqlite:///{tmp / 'wb.db'}", "WORKBENCH_RUNS": str(tmp / "runs"),
           "MPLBACKEND": "Agg"}
    _workbench(env, "run", "campaign", "--unit", str(UNIT), "--rig", "sim", "--seed", "1", "--out", str(tmp / "c"))
    _workbench(env, "run", "multiposition", "--unit", str(UNIT), "--rig", "sim", "--seed", "1", "--out",
               str(tmp / "mp"))
    from workbench.store import Store

    store = Store(env["WORKBENCH_DB"])
    history = store.history(SERIAL)
    assert [h.version for h in history] == [2, 1] and list(history[1].procedures) == PROCEDURES
    url = dashboard_app({k: env[k] for k in ("WORKBENCH_DB", "WORKBENCH_RUNS")})
    return {"url": url, "store": store, "v1": store.get_set(history[1].id), "v2": store.get_set(history[0].id)}


def test_every_page_on_the_campaign_store(campaign, browser_page_factory):
    b = browser_page_factory(campaign["url"], ARTIFACTS)
    failures = b.every_page()
    assert not failures, "\n".join(failures)


@pytest.mark.parametrize("page_name,prepare", [
    ("allan", "Recorded session"), ("turntable", "Result of a session"), ("thermal", None), ("magnetometer", None)])
def test_analysis_pages_show_the_stored_result(campaign, browser_page_factory, page_name, prepare):
    b = browser_page_factory(campaign["url"], ARTIFACTS)
    b.goto(page_name)
    if prepare:
        b.act(lambda: b.page.get_by_text(prepare, exact=True).first.click())
    b.page.get_by_text(re.compile("Stored result of .* nothing re-analysed")).first.wait_for()
    b.shot(f"stored_{page_name}")
    assert not b.problems()
    assert b.page.get_by_text(re.compile("Options it was computed with")).count() >= 1
    assert b.page.locator("[data-testid='stImage'] img").count() >= 1  # the figures drawn when it was computed


def test_calibration_sets_merged_set_downloads_approval_certificate_and_diff(campaign, browser_page_factory):
    b, v1, v2 = browser_page_factory(campaign["url"], ARTIFACTS), campaign["v1"], campaign["v2"]
    page = b.page
    b.goto("calibration_sets")
    b.select("Version", "1")
    page.get_by_text(f"Set {v1.id}").wait_for()
    assert page.get_by_text(re.compile("procedures " + ", ".join(PROCEDURES))).count() == 1
    page.get_by_text("Noise terms", exact=True).wait_for()
    b.shot("95_merged_set")
    assert not b.problems()

    # downloads are the merged set, in the formats' own syntax
    with page.expect_download() as dl:
        page.get_by_role("button", name=re.compile(r"^json \(\.json\)")).click()
    doc = json.loads(Path(dl.value.path()).read_text())
    assert doc["id"] == v1.id and doc["provenance"]["procedures"] == PROCEDURES
    assert {"gyro", "accel", "mag"} <= set(doc) and doc["gyro"]["thermal"] and set(doc["noise"]) == {"gyro", "accel"}
    with page.expect_download() as dl:
        page.get_by_role("button", name=re.compile(r"^yaml \(")).click()
    assert yaml.safe_load(Path(dl.value.path()).read_text())["id"] == v1.id

    # approval, then the certificate rendered from the store (HTML and PDF)
    by = page.get_by_label("Approved by", exact=True)
    by.fill("e2e operator")
    b.act(lambda: by.press("Enter"))
    b.act(lambda: page.get_by_role("button", name="Approve").click())
    page.get_by_text("Approved by e2e operator.").wait_for()
    b.act(lambda: page.get_by_role("button", name="Render the certificate").click())
    page.get_by_role("button", name="certificate (.html)").wait_for()
    b.shot("95_certificate_ready")
    assert not b.problems()
    with page.expect_download() as dl:
        page.get_by_role("button", name="certificate (.html)").click()
    html = Path(dl.value.path()).read_text()
    assert f"WB-{SERIAL}-v1-{v1.id[:8]}" in html and "e2e operator" in html and "draft" not in html
    assert html.count("data:image/png;base64") >= len(PROCEDURES)  # the stored figures of every procedure
    with page.expect_download() as dl:
        page.get_by_role("button", name="certificate (.pdf)").click()
    assert Path(dl.value.path()).read_bytes()[:5] == b"%PDF-"

    # diff v1 -> v2: what diff_sets finds, and nothing v2 did not observe counts as a change
    from workbench.diff import CHANGED, diff_sets

    rows = diff_sets(v1, v2)
    observed = [r for r in rows if r.state == CHANGED]
    assert len(observed) < len(rows)  # v2 (multi-position only) left most of v1's coefficients unobserved
    n_alarm = sum(abs(r.change_in_sigma) > 3.0 for r in observed)
    b.act(lambda: page.get_by_role("tab", name="Diff two versions").click())
    caption = page.get_by_text(re.compile(r"coefficients differ: ")).inner_text()
    b.shot("95_diff_v1_v2")
    assert caption.startswith(f"{len(rows)} coefficients differ: {len(observed)} observed in both versions, "
                              f"{n_alarm} of them by more than 3 σ"), caption
    assert f"{len(rows) - len(observed)} not observed in one version" in caption
    assert not b.problems()
