"""The ``workbench`` command line (also ``python -m workbench``).

Command groups live in the modules of this package; each defines ``register(app)`` and is
discovered here, so a new command is one new module. Every
:class:`~workbench.errors.WorkbenchError` becomes one line on stderr and exit code 2.
"""

from __future__ import annotations

import importlib
import os
import pkgutil
import sys

import click
import typer
from rich.console import Console

from workbench import __version__
from workbench.errors import WorkbenchError

app = typer.Typer(no_args_is_help=True, add_completion=False, pretty_exceptions_enable=False,
                  help="Calibration workbench for inertial and magnetic sensors.")
err = Console(stderr=True)
out = Console()


@app.callback()
def _root(db: str = typer.Option(None, "--db", help="Store URL (SQLAlchemy); default $WORKBENCH_DB or "
                                                     "sqlite:///workbench.db"),
          version: bool = typer.Option(False, "--version", help="Print the version and exit.")) -> None:
    if version:
        out.print(f"workbench {__version__}")
        raise typer.Exit()
    if db:
        os.environ["WORKBENCH_DB"] = db


def _register_all() -> None:
    for m in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name):
        if not m.name.startswith("_"):
            module = importlib.import_module(f"{__name__}.{m.name}")
            if hasattr(module, "register"):
                module.register(app)


_register_all()


def main(argv: list[str] | None = None) -> int:
    """Entry point: run the CLI, turning user errors into one line and a non-zero exit."""
    command = typer.main.get_command(app)
    try:
        command.main(args=argv, prog_name="workbench", standalone_mode=False)
    except WorkbenchError as exc:
        err.print(f"[bold red]error:[/] {exc}", highlight=False, soft_wrap=True)
        return 2
    except click.exceptions.Exit as exc:
        return exc.exit_code
    except click.ClickException as exc:
        exc.show()
        return exc.exit_code
    except (KeyboardInterrupt, click.exceptions.Abort):
        err.print("interrupted")
        return 130
    return 0


if __name__ == "__main__":
    sys.exit(main())


def entry() -> None:
    """Console-script entry point."""
    sys.exit(main())
