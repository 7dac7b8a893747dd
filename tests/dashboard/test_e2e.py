"""End-to-end: the dashboard in a real browser (Debian's Chromium driven by Playwright).

Starts ``streamlit run app.py`` headless on 127.0.0.1 (a free port, a temporary WORKBENCH_DB),
runs a short simulated procedure from the Run page, waits for its result, opens the
calibration-set page and downloads an export, and visits every page checking that none shows
an exception. Screenshots of each page go to ``test-artifacts/dashboard/``. Skipped (with
the reason) only when no Chromium is installed; ``playwright install`` is never used. Waits
are on Streamlit's script state (``conftest.Browser``), never fixed sleeps.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import time
from pathlib import Path

import pytest

from dashboard.ui import lab_label

pytestmark = pytest.mark.e2e

REPO = Path(__file__).resolve().parents[2]
ARTIFACTS = REPO / "test-artifacts" / "dashboard"
# the short procedure run from the browser (grade, changed options): the first one installed is used
SHORT_RUNS = [("magnetometer", "consumer_9axis", {"yaw_steps": 6, "dwell_s": 2.0}),
              ("multiposition", "industrial_mems", {"dwell_s": 5.0})]
RUN_TIMEOUT_S = 600.0  # the short simulated run, recorded and analysed, on a loaded machine


@pytest.fixture(scope="module")
def server(dashboard_app, tmp_path_factory):
    """The app on a free 127.0.0.1 port with an empty temporary store."""
    tmp = tmp_path_factory.mktemp("e2e")
    env = {"WORKBENCH_DB": f"sqlite:///{tmp / 'wb.db'}", "WORKBENCH_RUNS": str(tmp / "runs")}
    return {"url": dashboard_app(env), "tmp": tmp, "env": {**os.environ, **env}}


def _installed_short_run(server) -> tuple[str, str, dict]:
    out = subprocess.run([sys.executable, "-c", "from workbench import registry; print(' '.join(registry.procedures()))"],
                         cwd=str(REPO), env=server["env"], capture_output=True, text=True, timeout=120)
    names = set(out.stdout.split())
    for name, grade, options in SHORT_RUNS:
        if name in names:
            return name, grade, options
    pytest.skip(f"none of the short procedures {[r[0] for r in SHORT_RUNS]} is installed (have: {sorted(names)})")


def test_run_then_download_in_browser(server, browser_page_factory):
    b = browser_page_factory(server["url"], ARTIFACTS)
    page = b.page
    proc, grade, options = _installed_short_run(server)

    b.goto("run")
    b.select("Procedure", proc)
    b.select("Unit grade", grade)
    for name, value in options.items():
        field = page.get_by_label(lab_label(name), exact=True)  # e.g. "dwell (s)" for dwell_s
        field.fill(str(value))
        b.act(lambda: field.press("Enter"))
    page.get_by_text("Total time (rig time)").wait_for()
    b.shot("20_run_preview")
    assert not b.problems(), "run page (preview)"
    t0 = time.monotonic()
    page.get_by_role("button", name="Start run").click()
    # while it records: progress (or already the result on a fast machine); then reload the page,
    # which must neither stop the run nor lose it (the newest run is shown after a reload)
    done = re.compile("finished: .* steps recorded|failed \\(exit code|was stopped")
    page.get_by_text(re.compile("steps recorded")).first.wait_for(timeout=RUN_TIMEOUT_S * 1000)
    b.shot("20_run_progress")
    page.reload()
    b.settle()
    page.get_by_text(done).wait_for(timeout=max(RUN_TIMEOUT_S - (time.monotonic() - t0), 5) * 1000)
    b.settle()
    b.shot("20_run_result")
    assert not b.problems(), "run page (result)"
    if page.get_by_text(re.compile("finished: .* steps recorded")).count() != 1:
        alerts = page.locator("[data-testid='stAlert']").all_inner_texts()
        pytest.fail(f"the run did not finish: {alerts}")

    b.goto("calibration_sets")
    b.shot("95_calibration_sets_after_run")
    assert not b.problems(), "calibration sets"
    button = page.get_by_role("button", name=re.compile(r"^json \(\.json\)"))
    with page.expect_download() as dl:
        button.click()
    doc = json.loads(Path(dl.value.path()).read_text())
    assert doc["format"] == "workbench-calibration/1" and proc in doc["provenance"]["procedures"]


def test_every_page_renders_without_exception(server, browser_page_factory):
    b = browser_page_factory(server["url"], ARTIFACTS)
    failures = b.every_page()
    assert not failures, "\n".join(failures)
