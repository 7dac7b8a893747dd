"""Start-up cost of the command line: what ``--help`` and ``sets list`` load, and for how long.

Each command runs in a fresh interpreter under ``python -X importtime``, which lists every
module the command imported with its own import time. Two kinds of check:

- What is imported, not seconds: a shared machine can make any import slow, but it cannot
  make a command import pandas. The heavy libraries (numerics, Parquet, plotting, the set
  format's schema validator, migrations) cost 0.05-0.35 s each; ``--help`` loads none of them,
  nor SQLAlchemy or pydantic (the coercion layer typer loads only to convert a command's
  parameters); ``sets list`` loads only SQLAlchemy Core (not its ORM), typer's pydantic, and
  of the command modules only ``cli/sets.py``.
- How long, as a share that load does not change: the project's own modules (``workbench.*``)
  against the command's whole import time, measured in the same run. What is left is the
  libraries the command cannot do without (typer and rich; for ``sets list`` also typer's
  pydantic layer and SQLAlchemy Core with its SQLite dialect), which the first check pins.
  Measured on this 2-core machine (issue 23, load 3-13): the own modules are 10-13 % of
  ``--help`` (all command modules load to list them) and 1.4 % of ``sets list``; in CPU seconds
  ``--help`` is 0.22-0.26 s against 0.17-0.18 s for its libraries alone, and ``sets list``
  0.49-0.53 s against 0.46-0.52 s (0.66-0.69 s before the store moved off the ORM and the
  command modules loaded lazily). The seconds of issue 23 (``--help`` under 0.3 s, ``sets
  list`` under 0.5 s wall on a quiet machine) are printed by ``benchmarks/startup_speed.py``.
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
OWN_SHARE = {"--help": 0.2, "sets list": 0.05}  # the project's modules' part of the import time (see above)


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
    env = {**os.environ, "PYTHONPATH": str(ROOT), "WORKBENCH_DB": f"sqlite:///{tmp / 'wb.db'}", "CWD": str(tmp)}
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


def test_sets_list_imports_the_store_core_and_its_command_only(env):
    modules = set(_import_times(["-m", "workbench", "sets", "list"], env))
    packages = {m.split(".")[0] for m in modules}
    assert "sqlalchemy" in packages  # the store is what the command needs
    forbidden = packages & {*HEAVY, "click"}  # click: typer brings its own copy
    assert not forbidden, f"sets list imports {sorted(forbidden)}"
    others = {m for m in modules if m.startswith(("sqlalchemy.orm", "workbench.cli."))} - {"workbench.cli.sets"}
    assert not others, f"sets list imports {sorted(others)}"


@pytest.mark.parametrize("command", ["--help", "sets list"])
def test_the_projects_own_modules_are_a_small_part_of_the_start_up(env, command):
    runs = [_import_times(["-m", "workbench", *command.split()], env) for _ in range(3)]
    own = min(sum(t for m, t in times.items() if m.split(".")[0] == "workbench") for times in runs)
    whole = min(sum(times.values()) for times in runs)
    assert own / whole < OWN_SHARE[command], f"workbench {command}: own modules {own:.3f} s of {whole:.3f} s"
