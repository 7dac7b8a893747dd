"""What was stored with a result (workbench/stored.py): options from result.json, the manifest or the campaign."""

import json

from workbench.stored import stored_figures, stored_options


def _campaign(tmp_path, manifest: dict | None, campaign: dict | None):
    session = tmp_path / "camp" / "multiposition" / "session"
    session.mkdir(parents=True)
    if manifest is not None:
        (session / "session.json").write_text(json.dumps(manifest))
    if campaign is not None:
        (tmp_path / "camp" / "campaign.json").write_text(json.dumps(campaign))
    return session


def test_result_options_come_first(tmp_path):
    session = _campaign(tmp_path, {"analysis_options": {"a": 1}}, {"analysis_options": {"multiposition": {"b": 2}}})
    assert stored_options(session, "multiposition", {"options": {"c": 3}}) == {"c": 3}
    assert stored_options(session, "multiposition", {}) == {"a": 1}  # then the manifest's


def test_campaign_options_then_empty_then_unknown(tmp_path):
    session = _campaign(tmp_path, {"id": "s"}, {"analysis_options": {"multiposition": {"b": 2}}})
    assert stored_options(session, "multiposition") == {"b": 2}
    assert stored_options(session, "rate") == {}  # a manifest without options: none were given
    (session / "session.json").write_text("{broken")
    assert stored_options(session, "rate") is None  # nothing readable: not recorded
    assert stored_options(None, "rate") is None


def test_figures_beside_the_session(tmp_path):
    session = _campaign(tmp_path, {}, None)
    figs = session.parent / "figures"
    figs.mkdir()
    for name in ("b.png", "a.png", "notes.txt"):
        (figs / name).write_text("")
    assert [p.name for p in stored_figures(session)] == ["a.png", "b.png"]
    assert stored_figures(None) == []


def test_figures_in_the_folder_the_stored_result_names(tmp_path):
    """``workbench analyze --figures DIR`` writes them into DIR: the stored result names it and wins."""
    session = _campaign(tmp_path, {}, None)
    (session.parent / "figures").mkdir()
    (session.parent / "figures" / "beside.png").write_text("")
    named = tmp_path / "elsewhere" / "figures"
    named.mkdir(parents=True)
    (named / "mag_free_quality.png").write_text("")
    assert [p.name for p in stored_figures(session, {"figures_dir": str(named)})] == ["mag_free_quality.png"]
    assert [p.name for p in stored_figures(session, {"figures_dir": str(tmp_path / "gone")})] == ["beside.png"]
    assert [p.name for p in stored_figures(None, {"figures_dir": str(named)})] == ["mag_free_quality.png"]
