"""User text is printed as it is, never parsed as Rich markup (issue 16)."""

from tests.core.test_cli_sets import db  # noqa: F401 (fixture: a store URL in $WORKBENCH_DB)
from tests.core.test_store import a_set
from workbench.cli import main
from workbench.store import Store


def _a_set_of_model(serial: str, model: str):
    from dataclasses import replace

    from workbench.values import Unit

    return replace(a_set(serial=serial), unit=Unit(serial, model))


def test_markup_in_a_model_stored_by_merge_does_not_break_sets_list(db, tmp_path, capsys):
    """A model is free text (a serial is a safe name: markup characters are refused in it)."""
    path = _a_set_of_model("SN-1", "M[/]x").save(tmp_path / "s.json")
    assert main(["sets", "merge", str(path)]) == 0
    Store(db).add_set(_a_set_of_model("U2", "[bold red]M2[/]"))
    capsys.readouterr()
    assert main(["sets", "list"]) == 0
    listing = capsys.readouterr().out
    assert "M[/]x" in listing and "[bold red]M2[/]" in listing
    [info] = [i for i in Store(db).list_sets() if i.serial == "SN-1"]
    assert main(["sets", "show", info.id]) == 0 and "M[/]x" in capsys.readouterr().out


def test_bracketed_text_in_an_error_survives(db, tmp_path, capsys):
    assert main(["run", "multiposition", "--unit", str(tmp_path / "[step 3] [/].yaml")]) == 2
    err = capsys.readouterr().err
    assert "[step 3] [/].yaml" in err and len(err.strip().splitlines()) == 1


def test_bracketed_step_labels_survive_the_sequence_table(db, capsys):
    from workbench.cli.run import _print_sequence
    from workbench.sequence import Hold, Sequence

    _print_sequence(Sequence("demo", [Hold("z-down", dwell_s=1.0, label="[bold]up[/] [x]")]))
    assert "[bold]up[/] [x]" in capsys.readouterr().out
