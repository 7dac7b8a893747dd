"""End-to-end: the dashboard in a real browser (Debian's Chromium driven by Playwright).

Starts ``streamlit run app.py`` headless on 127.0.0.1 (a free port, a temporary WORKBENCH_DB),
runs a short simulated procedure from the Run page, waits for its result, opens the
calibration-set page and downloads an export, and visits every page checking that none shows
an exception. Screenshots of each page go to ``test-artifacts/dashboard/``. Skipped (with
the reason) only when no Chromium is installed; ``playwright install`` is never used.
"""

from __future__ import annotations

import json
import os
import re
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import pytest

from dashboard.ui import lab_label

pytestmark = pytest.mark.e2e

REPO = Path(__file__).resolve().parents[2]
CHROMIUM = Path("/usr/bin/chromium")
ARTIFACTS = REPO / "test-artifacts" / "dashboard"
CHROME_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
               "--disable-component-update", "--disable-sync", "--no-first-run"]
# the short procedure run from the browser (grade, changed options): the first one installed is used
SHORT_RUNS = [("magnetometer", "consumer_9axis", {"yaw_steps": 6, "dwell_s": 2.0}),
              ("multiposition", "industrial_mems", {"dwell_s": 5.0})]
START_TIMEOUT_S = 40.0  # streamlit start-up on a loaded 2-core box
RUN_TIMEOUT_S = 60.0  # the short simulated run, recorded and analysed


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _wait_healthy(url: str, proc: subprocess.Popen, timeout_s: float) -> None:
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout_s:
        if proc.poll() is not None:
            raise RuntimeError(f"streamlit exited with {proc.returncode}")
        try:
            with urllib.request.urlopen(f"{url}/_stcore/health", timeout=2) as r:
                if r.status == 200:
                    return
        except OSError:
            time.sleep(0.3)
    raise TimeoutError(f"streamlit not healthy at {url} after {timeout_s} s")


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    """The app on a free 127.0.0.1 port with a temporary store; stopped (its process group) afterwards."""
    if not CHROMIUM.exists():
        pytest.skip(f"no browser: {CHROMIUM} is missing (install Debian's chromium: apt-get install -y chromium)")
    pytest.importorskip("playwright.sync_api", reason="playwright (test extra) is not installed")
    tmp = tmp_path_factory.mktemp("e2e")
    port = _free_port()
    env = {**os.environ, "WORKBENCH_DB": f"sqlite:///{tmp / 'wb.db'}", "WORKBENCH_RUNS": str(tmp / "runs"),
           "MPLBACKEND": "Agg"}
    log = open(tmp / "streamlit.log", "w")
    proc = subprocess.Popen([sys.executable, "-m", "streamlit", "run", str(REPO / "app.py"),
                             "--server.headless", "true", "--server.address", "127.0.0.1",
                             "--server.port", str(port), "--browser.gatherUsageStats", "false",
                             "--server.fileWatcherType", "none"],
                            cwd=str(REPO), env=env, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
    url = f"http://127.0.0.1:{port}"
    try:
        _wait_healthy(url, proc, START_TIMEOUT_S)
        yield {"url": url, "tmp": tmp, "env": env}
    finally:
        os.killpg(proc.pid, 15)
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, 9)
            proc.wait()
        for folder in (tmp / "runs").glob("*"):  # runs started from the browser: stop any still going
            job = folder / "job.json"
            if job.exists() and not (folder / "exit_code").exists():
                try:
                    os.killpg(json.loads(job.read_text())["pid"], 15)
                except ProcessLookupError:
                    pass
        log.close()


@pytest.fixture(scope="module")
def browser_page(server):
    from playwright.sync_api import sync_playwright

    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=str(CHROMIUM), args=CHROME_ARGS, headless=True)
        context = browser.new_context(viewport={"width": 1400, "height": 2400}, accept_downloads=True)
        page = context.new_page()
        page.set_default_timeout(20_000)
        try:
            yield page
        finally:
            context.close()
            browser.close()


def _settle(page) -> None:
    """Wait until Streamlit has rendered the page (its title) and finished running the script."""
    page.wait_for_selector("[data-testid='stMain'] h1", timeout=30_000)
    for _ in range(2):  # twice: a rerun may start right after the first one ends
        page.wait_for_timeout(400)
        page.wait_for_function("() => !document.querySelector('[data-testid=\"stStatusWidget\"]') && "
                               "!document.querySelector('[data-testid=\"stSkeleton\"]')", timeout=30_000)


def _shot(page, name: str) -> None:
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    page.screenshot(path=str(ARTIFACTS / f"{name}.png"), full_page=True)


def _assert_no_exception(page, where: str) -> None:
    exc = page.locator("[data-testid='stException']")
    assert exc.count() == 0, f"{where}: the page shows an exception: {exc.first.inner_text()[:500]}"


def _select(page, label: str, option: str) -> None:
    """Choose ``option`` in the Streamlit select box labelled ``label``."""
    box = page.get_by_label(label, exact=True)
    box.click()
    page.get_by_role("option", name=re.compile(f"^{re.escape(option)}\\b")).first.click()
    _settle(page)


def _installed_short_run(server) -> tuple[str, str, dict]:
    out = subprocess.run([sys.executable, "-c", "from workbench import registry; print(' '.join(registry.procedures()))"],
                         cwd=str(REPO), env=server["env"], capture_output=True, text=True, timeout=60)
    names = set(out.stdout.split())
    for name, grade, options in SHORT_RUNS:
        if name in names:
            return name, grade, options
    pytest.skip(f"none of the short procedures {[r[0] for r in SHORT_RUNS]} is installed (have: {sorted(names)})")


def test_run_then_download_in_browser(server, browser_page):
    page, url = browser_page, server["url"]
    proc, grade, options = _installed_short_run(server)

    page.goto(f"{url}/run")
    _settle(page)
    _select(page, "Procedure", proc)
    _select(page, "Unit grade", grade)
    for name, value in options.items():
        field = page.get_by_label(lab_label(name), exact=True)  # e.g. "dwell (s)" for dwell_s
        field.fill(str(value))
        field.press("Enter")
        _settle(page)
    page.get_by_text("Total time (rig time)").wait_for()
    _shot(page, "20_run_preview")
    _assert_no_exception(page, "run page (preview)")
    t0 = time.monotonic()
    page.get_by_role("button", name="Start run").click()
    # while it records: progress (or already the result on a fast machine); then reload the page,
    # which must neither stop the run nor lose it (the newest run is shown after a reload)
    done = re.compile("finished: .* steps recorded|failed \\(exit code|was stopped")
    page.get_by_text(re.compile("steps recorded")).first.wait_for(timeout=RUN_TIMEOUT_S * 1000)
    _shot(page, "20_run_progress")
    page.reload()
    _settle(page)
    page.get_by_text(done).wait_for(timeout=max(RUN_TIMEOUT_S - (time.monotonic() - t0), 5) * 1000)
    _settle(page)
    _shot(page, "20_run_result")
    _assert_no_exception(page, "run page (result)")
    if page.get_by_text(re.compile("finished: .* steps recorded")).count() != 1:
        alerts = page.locator("[data-testid='stAlert']").all_inner_texts()
        codes = page.locator("[data-testid='stCode']").all_inner_texts()
        pytest.fail(f"the run did not finish: {alerts}\n{codes[-1][-1500:] if codes else ''}")

    page.goto(f"{url}/calibration_sets")
    _settle(page)
    _shot(page, "95_calibration_sets_after_run")
    _assert_no_exception(page, "calibration sets")
    button = page.get_by_role("button", name=re.compile(r"^json \(\.json\)"))
    with page.expect_download() as dl:
        button.click()
    path = dl.value.path()
    doc = json.loads(Path(path).read_text())
    assert doc["format"] == "workbench-calibration/1" and proc in doc["provenance"]["procedures"]


def test_every_page_renders_without_exception(server, browser_page):
    page, url = browser_page, server["url"]
    pages = sorted((REPO / "dashboard" / "pages").glob("[0-9]*_*.py"))
    failures = []
    for f in pages:
        name = "" if f == pages[0] else f.stem.split("_", 1)[1]  # the first page is the default, at /
        page.goto(f"{url}/{name}")
        _settle(page)
        _shot(page, f.stem)
        exc = page.locator("[data-testid='stException']")
        if exc.count():
            failures.append(f"{f.name}: {exc.first.inner_text()[:300]}")
    assert not failures, "\n".join(failures)
