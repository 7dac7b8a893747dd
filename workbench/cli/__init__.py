"""The ``workbench`` command line (also ``python -m workbench``).

Command groups live in the modules of this package; each defines ``register(app)`` and is
discovered here, so a new command is one new module. A command line loads only the module of
its command when that module is named after it (see :func:`register_for`). Every
:class:`~workbench.errors.WorkbenchError` becomes one line on stderr and exit code 2.
"""

from __future__ import annotations

import importlib
import os
import pkgutil
import sys
from collections.abc import Iterator
from contextlib import contextmanager

import typer
from rich.console import Console
from rich.text import Text

from workbench import __version__
from workbench.errors import WorkbenchError

app = typer.Typer(no_args_is_help=True, add_completion=False, pretty_exceptions_enable=False,
                  help="Calibration workbench for inertial and magnetic sensors.")
# markup off: user text (serials, labels, file names, messages) is printed as it is, never parsed as
# Rich markup; styled labels are passed as Text (see :func:`styled`). No automatic highlighting:
# digits inside paths and ids are not numbers to colour.


def wrap_words(text: Text, width: int) -> Text:
    """``text`` with its lines broken at spaces only, to ``width`` columns where a word allows: a path
    or id longer than ``width`` stays whole on a line of its own (styles kept)."""
    pieces, start = [], 0
    plain = text.plain
    for paragraph in plain.split("\n"):
        end_par = start + len(paragraph)
        line_start, last_space, pos = start, None, start
        while pos < end_par:
            if plain[pos] == " ":
                last_space = pos
            if pos - line_start >= width and last_space is not None and last_space > line_start:
                pieces.append(text[line_start:last_space])
                line_start, last_space = last_space + 1, None
            pos += 1
        pieces.append(text[line_start:end_par])
        start = end_par + 1
    return Text("\n").join(pieces)


class _Console(Console):
    """Lines wrap between words only: a path or id longer than the terminal stays whole (never
    folded mid-path), so it can be copied; tables still fit the width."""

    def print(self, *objects, sep: str = " ", **kwargs) -> None:  # type: ignore[override]
        if objects and all(isinstance(o, (str, Text)) for o in objects) and not kwargs.get("soft_wrap"):
            text = Text(sep).join(o if isinstance(o, Text) else Text(o) for o in objects)
            super().print(wrap_words(text, self.width), overflow="ignore", crop=False, **kwargs)
            return
        super().print(*objects, sep=sep, **kwargs)


err = _Console(stderr=True, markup=False, highlight=False)
out = _Console(markup=False, highlight=False)


def styled(tag: str, style: str, rest: str = "") -> Text:
    """``tag`` in ``style`` followed by ``rest`` verbatim (no markup is parsed in either)."""
    return Text.assemble((tag, style), rest)


@contextmanager
def progress_bar(*columns) -> Iterator:
    """A rich progress bar with ``columns`` on stderr. A command that fails while it shows clears it,
    so the error is the one line left (a rig refusing the plan, a rig that cannot be opened)."""
    from rich.progress import Progress

    bar = Progress(*columns, console=err, transient=False)
    bar.start()
    try:
        yield bar
    except BaseException:
        bar.live.transient = True
        bar.live.stop()  # not bar.stop(): it ends a non-terminal's output with an empty line
        raise
    bar.stop()


def _version(value: bool) -> None:
    if value:
        out.print(f"workbench {__version__}")
        raise typer.Exit()


@app.callback()
def _root(db: str = typer.Option(None, "--db", help="Store URL (SQLAlchemy); default $WORKBENCH_DB or "
                                                     "sqlite:///workbench.db"),
          version: bool = typer.Option(False, "--version", callback=_version, is_eager=True,
                                       help="Print the version and exit.")) -> None:
    if db:
        os.environ["WORKBENCH_DB"] = db


_ROOT_VALUE_OPTIONS = ("--db",)  # the options of _root that take a value (the command comes after it)


_MODULES = sorted(m.name for m in pkgutil.iter_modules(__path__) if not m.name.startswith("_"))
_registered: set[str] = set()  # command modules whose register(app) has run


def _register(names: list[str]) -> None:
    """Import the command modules ``names`` and register their commands (each module once)."""
    for name in names:
        if name not in _registered:
            _registered.add(name)
            module = importlib.import_module(f"{__name__}.{name}")
            if hasattr(module, "register"):
                module.register(app)


def _command_names() -> set[str]:
    return {c.name for c in app.registered_commands} | {g.name for g in app.registered_groups}


def register_for(args: list[str]) -> None:
    """Register what the command line ``args`` needs: only the module named after its command
    when that module defines the command (``workbench sets list`` loads ``cli/sets.py`` alone),
    else every module (``--help`` lists them all; a command defined elsewhere is found)."""
    rest = iter(args)
    named = None
    for a in rest:
        if a in _ROOT_VALUE_OPTIONS:
            next(rest, None)
        elif not a.startswith("-"):
            named = a if a in _MODULES else None
            break
    if named is not None:
        _register([named])
        if named in _command_names():
            return
    _register(_MODULES)


def _click_errors() -> tuple[tuple, tuple, tuple]:
    """(usage errors, exits, aborts) of every click the installed typer may raise.

    Typer up to 0.15 raises ``click``'s exceptions; later versions raise those of their own
    vendored copy (``typer._click``) and ``typer.Exit`` / ``typer.Abort`` of their own. Whichever
    it is, typer has imported it already: a click nobody imported raises nothing, and importing
    it here would cost every command about 0.05 s.
    """
    mods = [m for m in map(sys.modules.get, ("click.exceptions", "typer._click.exceptions")) if m is not None]

    def found(name: str, *extra: type) -> tuple:
        return tuple({*(getattr(m, name) for m in mods if hasattr(m, name)), *extra})
    return found("ClickException"), found("Exit", typer.Exit), found("Abort", typer.Abort)


def _usage_line(exc: Exception) -> str:
    """One line for a click usage error: the message and, for a command, where to look for help."""
    message = " ".join(exc.format_message().split()) or "missing command"  # no arguments: help was shown
    ctx = getattr(exc, "ctx", None)
    path = getattr(ctx, "command_path", None) or "workbench"
    return f"error: {message} (see '{path} --help')"


def main(argv: list[str] | None = None) -> int:
    """Entry point: run the CLI, turning user errors into one line on stderr and exit code 2.

    Usage errors (a missing argument, a bad choice, an unknown command or option) and every
    :class:`~workbench.errors.WorkbenchError` are one line and exit 2; Ctrl-C exits 130.
    """
    register_for(sys.argv[1:] if argv is None else argv)
    usage, exits, aborts = _click_errors()
    command = typer.main.get_command(app)
    try:
        rv = command.main(args=argv, prog_name="workbench", standalone_mode=False)
    except WorkbenchError as exc:
        err.print(styled("error:", "bold red", " " + " ".join(str(exc).split())), highlight=False, soft_wrap=True)
        return 2
    except exits as exc:
        return int(exc.exit_code or 0)
    except usage as exc:
        err.print(_usage_line(exc), highlight=False, soft_wrap=True)
        return 2
    except (KeyboardInterrupt, *aborts):
        err.print("interrupted", highlight=False)
        return 130
    return rv if isinstance(rv, int) else 0


if __name__ == "__main__":
    sys.exit(main())


def entry() -> None:
    """Console-script entry point."""
    sys.exit(main())
