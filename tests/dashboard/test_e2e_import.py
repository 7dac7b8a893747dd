"""End-to-end: a real MARG recording (shared/data/marg_mpu6050_hmc5883l/, README there) imported through the
Sessions page in a real browser (Debian's Chromium driven by Playwright; never ``playwright install``).

The app runs headless on 127.0.0.1 (a free port, a temporary store; stopped by ``conftest.dashboard_app``).
The four stream files of ``tilt-sphere`` are uploaded with the shipped import profile, and what the page then
shows (the import's success line, the session's samples, its one ``free`` step, its unit) is checked against
the CLI's importer run on the same raw files in the test, and against the store. Skipped only when the data
or Chromium are missing. Screenshots go to ``test-artifacts/dashboard/``.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

pytestmark = pytest.mark.e2e

REPO = Path(__file__).resolve().parents[2]
ARTIFACTS = REPO / "test-artifacts" / "dashboard"
# beside the checkout (/work/main) or beside the worktrees' folder (/work/wt/NAME)
DATA = next((p / "shared" / "data" / "marg_mpu6050_hmc5883l" for p in (REPO.parent, REPO.parent.parent)
             if (p / "shared" / "data" / "marg_mpu6050_hmc5883l").exists()), REPO.parent / "shared" / "data")
RECORDING = DATA / "tilt-sphere"
PROFILE = REPO / "fixtures" / "import_profiles" / "marg_mpu6050_hmc5883l.yaml"
STREAM_FILES = ("accelerometer.csv", "gyroscope.csv", "temperature.csv", "magnetometer.csv")
IMPORT_TIMEOUT_S = 600.0  # the import (clock fits, merge, axis checks) on a loaded 2-core machine


@pytest.fixture(scope="module")
def server(dashboard_app, tmp_path_factory):
    """The app on a free 127.0.0.1 port with an empty temporary store and runs folder."""
    if not RECORDING.exists():
        pytest.skip(f"{RECORDING} is not beside the checkout")
    tmp = tmp_path_factory.mktemp("e2e-import")
    env = {"WORKBENCH_DB": f"sqlite:///{tmp / 'wb.db'}", "WORKBENCH_RUNS": str(tmp / "runs")}
    return {"url": dashboard_app(env), "tmp": tmp, "db": env["WORKBENCH_DB"]}


def test_marg_recording_imported_through_the_sessions_page(server, browser_page_factory, tmp_path):
    from workbench.importer import import_file
    from workbench.store import Store

    reference = import_file(PROFILE, RECORDING, tmp_path / "cli")  # the CLI's importer on the same raw files
    b = browser_page_factory(server["url"], ARTIFACTS)
    page = b.page
    b.goto("sessions")
    assert page.get_by_text("No sessions yet.").count() == 1  # the store starts empty
    b.act(lambda: page.get_by_role("tab", name="Import a recording").click())
    b.select("Import profile", PROFILE.stem)
    page.get_by_text("This profile reads 4 streams from a data folder").wait_for()
    uploader = page.locator("[data-testid='stFileUploader']").filter(has_text="Recording file(s)")
    b.act(lambda: uploader.locator("input[type='file']").set_input_files([str(RECORDING / f) for f in STREAM_FILES]))
    for f in STREAM_FILES:
        uploader.get_by_text(f, exact=True).wait_for()
    b.act(lambda: page.get_by_role("button", name="Import", exact=True).click(), timeout_s=IMPORT_TIMEOUT_S)
    b.shot("30_sessions_marg_import")
    assert not b.problems(), "sessions page (import)"
    success = page.locator("[data-testid='stAlert']").filter(has_text="Imported into")
    assert success.count() == 1, page.locator("[data-testid='stAlert']").all_inner_texts()
    dest = Path(re.search(r"Imported into (\S+)", success.inner_text()).group(1))
    assert dest.parent == server["tmp"] / "runs" / "imports" and (dest / "session.json").exists()

    # the store holds the one session; picked in the Browse tab, it shows as the CLI imports it
    (row,) = Store(server["db"]).list_sessions()
    assert row.path == str(dest) and row.serial == reference.unit.serial and row.n_steps == 1
    b.act(lambda: page.get_by_role("tab", name="Browse and inspect").click())
    # the Browse tab already shows the session just imported
    assert page.get_by_text("No sessions yet.").count() == 0
    assert page.locator("[data-testid='stText']").first.inner_text() == reference.unit.serial
    b.select("Session", f"{row.created} · {row.procedure} · {row.serial} · {row.id[:8]}")
    b.shot("30_sessions_marg_browse")
    metrics = dict(zip(page.locator("[data-testid='stMetricLabel']").all_inner_texts(),
                       page.locator("[data-testid='stMetricValue']").all_inner_texts()))
    # the serial is plain text shown whole: inner_text would read a value the page cuts with an ellipsis, so the
    # element's content must fit its box too
    unit = page.locator("[data-testid='stText']").first
    assert unit.inner_text() == reference.unit.serial
    assert unit.evaluate("e => e.scrollWidth <= e.clientWidth && e.scrollHeight <= e.clientHeight + 1")
    assert metrics["Samples"] == f"{len(reference.samples):,}"
    # the steps table is drawn on a canvas; the Step box lists the same steps as text
    page.get_by_label("Step", exact=True).click()
    shown = page.get_by_role("option").all_inner_texts()
    page.keyboard.press("Escape")
    assert [o.strip() for o in shown] == ["all steps", *(f"{st.index}: {st.kind} {st.label}" for st in reference.steps)]
    assert [st.kind for st in reference.steps] == ["free"]
    assert page.locator("[data-testid='stCaptionContainer']").filter(has_text=f"{reference.sample_rate_hz:g} Hz").count() == 1
