"""Fixtures of the dashboard tests: a temporary store seeded with two set versions; the app in Debian's Chromium."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from workbench.calset import CalibrationSet, Provenance, TriadCalibration, Unit
from workbench.model import TriadModel
from workbench.store import Store

SERIAL = "DASH-001"
# gyro x bias moves by 3e-6 rad/s between versions with sigma 1e-6 each: (3e-6)/sqrt(2)/1e-6 = 2.12 sigma
BIAS_V1 = np.array([1e-5, -2e-5, 3e-5])
BIAS_V2 = BIAS_V1 + np.array([3e-6, 0.0, 0.0])
BIAS_SIGMA = np.array([1e-6, 1e-6, np.nan])  # z not observed


def make_set(bias: np.ndarray) -> CalibrationSet:
    """A gyro-only set with the given bias (rad/s) and a known sigma."""
    tc = TriadCalibration(TriadModel(bias=bias, scale_misalignment=np.diag([1e-4, -2e-4, 5e-5])),
                          {"bias": BIAS_SIGMA, "scale_misalignment": np.full((3, 3), 1e-5)})
    return CalibrationSet(Unit(SERIAL, "test-imu"), {"gyro": tc},
                          noise={"gyro": {"arw": [1e-4, 1e-4, None]}},
                          provenance=Provenance(procedures=("multiposition",)))


@pytest.fixture
def seeded_db(tmp_path, monkeypatch):
    """WORKBENCH_DB (and WORKBENCH_RUNS) pointing at a fresh store holding versions 1 and 2 of DASH-001."""
    url = f"sqlite:///{tmp_path / 'wb.db'}"
    monkeypatch.setenv("WORKBENCH_DB", url)
    monkeypatch.setenv("WORKBENCH_RUNS", str(tmp_path / "runs"))
    store = Store(url)
    store.add_set(make_set(BIAS_V1))
    store.add_set(make_set(BIAS_V2))
    return store


def make_session(n_per_step: int = 100, rate_hz: float = 10.0):
    """A two-step static session (z-down, x-up) at ``rate_hz`` with gravity on the down axis, in memory."""
    import pandas as pd

    from workbench.session import Session, Site, StepRecord
    from workbench.sequence import mount_matrix

    g = 9.80665  # m/s^2
    rows, steps = [], []
    for i, (mount, acc) in enumerate((("z-down", (0, 0, -g)), ("x-up", (g, 0, 0)))):
        t = (i * n_per_step + np.arange(n_per_step)) / rate_hz
        rows.append(pd.DataFrame({"t": t, "step": i, "gx": 1e-5, "gy": 0.0, "gz": 0.0,
                                  "ax": acc[0], "ay": acc[1], "az": acc[2]}))
        steps.append(StepRecord(i, "static", float(t[0]), float(t[-1]) + 0.5 / rate_hz, mount_matrix(mount),
                                label=mount))
    return Session("sess-0001", Unit(SERIAL, "test-imu"), Site(40.8, table_zero_azimuth_deg=0.0), rate_hz,
                   "multiposition", steps, pd.concat(rows, ignore_index=True))


@pytest.fixture
def stored_session(seeded_db, tmp_path):
    """A session folder written with write_session and recorded in the seeded store."""
    from workbench.session import write_session

    folder = write_session(make_session(), tmp_path / "session")
    seeded_db.add_session("sess-0001", SERIAL, "test-imu", "multiposition", str(folder), n_steps=2)
    return folder


# -- the dashboard in a real browser (Debian's Chromium driven by Playwright; never `playwright install`) ----------
REPO = Path(__file__).resolve().parents[2]
CHROMIUM = Path("/usr/bin/chromium")
CHROME_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
               "--disable-component-update", "--disable-sync", "--no-first-run"]
START_TIMEOUT_S = 180.0  # streamlit start-up on a loaded 2-core machine (it took 40 s at load 12)
RUN_TIMEOUT_S = 300.0  # s a page may stay in Streamlit's "running" state before the test gives up


class Browser:
    """A Playwright page on a Streamlit app, with waits on Streamlit's own script state (never fixed sleeps).

    ``settle()`` waits until the app root reports ``data-test-script-state="notRunning"`` after a
    rerun has had the chance to start, so a slow machine only makes the test slower, not wrong.
    """

    def __init__(self, page, url: str, artifacts):
        self.page, self.url, self.artifacts = page, url, artifacts

    def state(self) -> str:
        return self.page.evaluate(
            "() => document.querySelector('[data-testid=\"stApp\"]')?.getAttribute('data-test-script-state') || ''")

    def settle(self, timeout_s: float = RUN_TIMEOUT_S) -> None:
        """Wait for the page's title, then for the script (and any rerun it asked for) to finish."""
        self.page.wait_for_selector("[data-testid='stMain'] h1", timeout=timeout_s * 1000)
        for _ in range(2):  # a rerun (st.rerun, a widget's callback) may start right after the first run ends
            self.page.wait_for_function(
                "() => { const a = document.querySelector('[data-testid=\"stApp\"]');"
                " return a && a.getAttribute('data-test-script-state') === 'notRunning'"
                " && a.getAttribute('data-test-connection-state') === 'CONNECTED'"
                " && !document.querySelector('[data-testid=\"stSkeleton\"]'); }", timeout=timeout_s * 1000)
            self.page.wait_for_timeout(300)

    def act(self, action, timeout_s: float = RUN_TIMEOUT_S) -> None:
        """Do ``action()`` (a click, a key press) and wait for the rerun it causes to end."""
        action()
        try:  # the backend answers within a moment; on a fast machine the run may already be over
            self.page.wait_for_function("() => document.querySelector('[data-testid=\"stApp\"]')"
                                        "?.getAttribute('data-test-script-state') !== 'notRunning'", timeout=5_000)
        except Exception:  # noqa: BLE001 - playwright's TimeoutError: the rerun was faster than the poll
            pass
        self.settle(timeout_s)

    def goto(self, name: str) -> None:
        self.page.goto(f"{self.url}/{name}")
        self.settle()

    def select(self, label: str, option: str) -> None:
        """Choose ``option`` in the Streamlit select box labelled ``label``."""
        import re

        self.page.get_by_label(label, exact=True).click()
        self.act(lambda: self.page.get_by_role("option", name=re.compile(f"^{re.escape(option)}\\b")).first.click())

    def shot(self, name: str) -> None:
        self.artifacts.mkdir(parents=True, exist_ok=True)
        self.page.screenshot(path=str(self.artifacts / f"{name}.png"), full_page=True)

    def every_page(self) -> list[str]:
        """Open every page of ``dashboard/pages`` in order, screenshot it (named after its file) and return
        the problems found (``'NN_name.py: ...'``)."""
        pages = sorted((REPO / "dashboard" / "pages").glob("[0-9]*_*.py"))
        failures = []
        for f in pages:
            self.goto("" if f == pages[0] else f.stem.split("_", 1)[1])  # the first page is the default, at /
            self.shot(f.stem)
            failures += [f"{f.name}: {p}" for p in self.problems()]
        return failures

    def problems(self) -> list[str]:
        """Exception boxes and 'unexpected' error boxes (a bug caught by dashboard.ui.show_error) on the page."""
        found = [t[:400] for t in self.page.locator("[data-testid='stException']").all_inner_texts()]
        found += [t[:400] for t in self.page.locator("[data-testid='stAlert']").all_inner_texts()
                  if "unexpected" in t or "Traceback" in t]
        return found


@pytest.fixture(scope="module")
def dashboard_app(tmp_path_factory):
    """A function ``start(env) -> url`` serving ``app.py`` on a free 127.0.0.1 port with ``env``; every
    server (and any run it started) is stopped, by its process group, when the module's tests end."""
    import json
    import os
    import socket
    import subprocess
    import sys
    import time
    import urllib.request

    if not CHROMIUM.exists():
        pytest.skip(f"no browser: {CHROMIUM} is missing (install Debian's chromium: apt-get install -y chromium)")
    pytest.importorskip("playwright.sync_api", reason="playwright (test extra) is not installed")
    started = []

    def start(env: dict) -> str:
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            port = s.getsockname()[1]
        log = open(tmp_path_factory.mktemp("streamlit") / "streamlit.log", "w")
        proc = subprocess.Popen([sys.executable, "-m", "streamlit", "run", str(REPO / "app.py"),
                                 "--server.headless", "true", "--server.address", "127.0.0.1",
                                 "--server.port", str(port), "--browser.gatherUsageStats", "false",
                                 "--server.fileWatcherType", "none"],
                                cwd=str(REPO), env={**os.environ, "MPLBACKEND": "Agg", **env}, stdout=log,
                                stderr=subprocess.STDOUT, start_new_session=True)
        started.append((proc, log, env))
        url = f"http://127.0.0.1:{port}"
        t0 = time.monotonic()
        while time.monotonic() - t0 < START_TIMEOUT_S:
            if proc.poll() is not None:
                raise RuntimeError(f"streamlit exited with {proc.returncode} (log: {log.name})")
            try:
                with urllib.request.urlopen(f"{url}/_stcore/health", timeout=5) as r:
                    if r.status == 200:
                        return url
            except OSError:
                time.sleep(0.5)
        raise TimeoutError(f"streamlit not healthy at {url} after {START_TIMEOUT_S} s")

    yield start
    for proc, log, env in started:
        os.killpg(proc.pid, 15)
        try:
            proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, 9)
            proc.wait()
        runs = env.get("WORKBENCH_RUNS")
        for folder in (Path(runs).glob("*") if runs else []):  # runs started from a page
            job = folder / "job.json"
            if job.exists() and not (folder / "exit_code").exists():
                try:
                    os.killpg(json.loads(job.read_text())["pid"], 15)
                except ProcessLookupError:
                    pass
        log.close()


@pytest.fixture(scope="module")
def chromium_browser():
    """Debian's Chromium, headless, through Playwright (one per test module)."""
    from playwright.sync_api import sync_playwright

    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=str(CHROMIUM), args=CHROME_ARGS, headless=True)
        try:
            yield browser
        finally:
            browser.close()


def open_page(browser, url: str, artifacts) -> Browser:
    """A new page (1400 x 3000 px: screenshots show whole pages; downloads accepted) on ``url`` wrapped in :class:`Browser`."""
    context = browser.new_context(viewport={"width": 1400, "height": 3000}, accept_downloads=True)
    page = context.new_page()
    page.set_default_timeout(RUN_TIMEOUT_S * 1000)
    return Browser(page, url, artifacts)


@pytest.fixture
def browser_page_factory(chromium_browser):
    """``make(url, artifacts) -> Browser``; the pages' contexts are closed after the test."""
    made = []

    def make(url: str, artifacts) -> Browser:
        b = open_page(chromium_browser, url, artifacts)
        made.append(b)
        return b

    yield make
    for b in made:
        b.page.context.close()
