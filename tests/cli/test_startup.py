"""Start-up cost of the command line: what ``--help`` and ``sets list`` load, and for how long.

Each command runs in a fresh interpreter under ``python -X importtime``, which lists every
module the command imported with its own import time. Two kinds of check:

- What is imported, not seconds: a shared machine can make any import slow, but it cannot
  make a command import pandas. The heavy libraries (numerics, Parquet, plotting, the set
  format's schema validator, migrations) cost 0.05-0.35 s each; ``--help`` loads none of them,
  nor SQLAlchemy or pydantic (the coercion layer typer loads only to convert a command's
  parameters); ``sets list`` of an existing SQLite store loads none of them either, nor
  SQLAlchemy (0.15-0.3 s; the listing is read with ``sqlite3``, :mod:`workbench.store_read`),
  only typer's pydantic, and of the command modules only ``cli/sets.py``.
- How long, as a share that load does not change: the project's own modules (``workbench.*``)
  against the command's whole import time, measured in the same run. What is left is the
  libraries the command cannot do without (typer and rich; for ``sets list`` also typer's
  pydantic layer and ``sqlite3``), which the first check pins. Measured as the test does (the
  smallest own time of three runs over the smallest whole), three times, on this 2-core machine
  at load 5 (issue 23, 2026-12-02): with the byte code cached the own modules are 2.2-3.5 % of
  ``--help`` (all command modules load to list them) and 1.1-1.3 % of ``sets list``; every module
  compiled from source (``PYTHONDONTWRITEBYTECODE``, a copy without ``__pycache__``) 6.5-11.5 % and
  1.1-2.9 %. The seconds of issue 23
  (``--help`` under 0.3 s, ``sets list`` under 0.5 s wall, the console script a user types)
  are printed by ``benchmarks/startup_speed.py``.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
HEAVY = ("numpy", "pandas", "scipy", "pyarrow", "matplotlib", "jsonschema", "cvxpy", "numba", "dask", "streamlit",
         "alembic", "yaml", "PIL", "statsmodels", "allantools")
OWN_SHARE = {"--help": 0.08, "sets list": 0.04}  # the project's modules' part of the import time (see above)


def _import_times(args: list[str], env: dict) -> dict[str, float]:
    """Module -> its own import time (s) under ``python -X importtime ARGS`` (which must exit 0)."""
    p = subprocess.run([sys.executable, "-X", "importtime", *args], env=env, cwd=env["CWD"],
                       capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr[-2000:]
    return {line.split("|")[2].strip(): int(line.split("|")[0].split(":")[1]) / 1e6
            for line in p.stderr.splitlines() if line.startswith("import time:") and "self [us]" not in line}


def _imported(args: list[str], env: dict) -> set[str]:
    """Top-level packages imported by ``python -X importtime ARGS``."""
    return {name.split(".")[0] for name in _import_times(args, env)}


@pytest.fixture(scope="module")
def env(tmp_path_factory) -> dict:
    tmp = tmp_path_factory.mktemp("startup")
    # byte code written and read as for a user's command (a shell may say PYTHONDONTWRITEBYTECODE)
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    env.update(PYTHONPATH=str(ROOT), WORKBENCH_DB=f"sqlite:///{tmp / 'wb.db'}", CWD=str(tmp))
    subprocess.run([sys.executable, "-m", "workbench", "db", "upgrade"], env=env, cwd=tmp, check=True,
                   capture_output=True, timeout=300)  # an existing store: creating one runs the migrations
    return env


def test_the_listing_sees_what_the_commands_import(env):
    # the check itself: a command that imports numpy is seen doing so
    assert {"numpy", "workbench"} <= _imported(["-c", "import numpy, workbench"], env)


def test_help_imports_only_the_cli(env):
    packages = _imported(["-m", "workbench", "--help"], env)
    assert {"workbench", "typer", "rich"} <= packages
    forbidden = packages & {*HEAVY, "sqlalchemy", "pydantic", "click"}
    assert not forbidden, f"--help imports {sorted(forbidden)}"


def test_sets_list_reads_a_sqlite_store_without_sqlalchemy_and_loads_its_command_only(env):
    modules = set(_import_times(["-m", "workbench", "sets", "list"], env))
    packages = {m.split(".")[0] for m in modules}
    assert {"sqlite3", "pydantic"} <= packages  # the store read by sqlite3; typer's coercion layer
    forbidden = packages & {*HEAVY, "sqlalchemy", "click"}  # click: typer brings its own copy
    assert not forbidden, f"sets list imports {sorted(forbidden)}"
    others = {m for m in modules if m.startswith("workbench.cli.")} - {"workbench.cli.sets"}
    assert not others, f"sets list imports {sorted(others)}"


def test_sets_list_of_a_store_to_create_goes_through_sqlalchemy(env, tmp_path):
    # no store yet: the Store creates it (the check above is not passed by never opening one)
    new = {**env, "WORKBENCH_DB": f"sqlite:///{tmp_path / 'new.db'}"}
    assert "sqlalchemy" in _imported(["-m", "workbench", "sets", "list"], new)
    assert (tmp_path / "new.db").is_file()


@pytest.mark.parametrize("command", ["--help", "sets list"])
def test_the_projects_own_modules_are_a_small_part_of_the_start_up(env, command):
    runs = [_import_times(["-m", "workbench", *command.split()], env) for _ in range(3)]
    own = min(sum(t for m, t in times.items() if m.split(".")[0] == "workbench") for times in runs)
    whole = min(sum(times.values()) for times in runs)
    assert own / whole < OWN_SHARE[command], f"workbench {command}: own modules {own:.3f} s of {whole:.3f} s"
