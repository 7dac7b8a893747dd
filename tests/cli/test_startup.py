"""Start-up cost of the command line: what ``--help`` and ``sets list`` import, and how long it takes.

Each command runs in a fresh interpreter under ``python -X importtime``; its import time is the
sum of the cumulative times of the top-level imports it triggered (its whole import closure,
the interpreter's own start-up included). The machine these tests run on is shared, so the
budget is not an absolute time but a multiple of the import time of what the command cannot do
without, measured the same way in the same test: the CLI framework (typer, rich and typer's
help renderer) for ``--help``; that plus SQLAlchemy and typer's parameter adapters (pydantic)
for ``sets list``. Our own modules and anything they pull in must fit in the margin, and the
heavy libraries a command does not use must not be loaded at all. The targets behind this
(issue 23): ``workbench --help`` under 0.3 s and ``sets list`` under 0.5 s wall.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
HEAVY = ("numpy", "pandas", "scipy", "pyarrow", "matplotlib", "jsonschema", "cvxpy", "numba", "dask", "streamlit",
         "alembic", "yaml")
FRAMEWORK = "import typer, typer.rich_utils, rich.console, rich.table, rich.progress"
STORE = FRAMEWORK + ", typer._adapters, sqlalchemy.orm, sqlalchemy.dialects.sqlite, sqlite3"
MARGIN = 2.0  # our own code, and the noise of a shared machine, may add as much again as the command needs
RUNS = 3  # the minimum of a few runs: a shared machine only ever adds time


def _importtime(args: list[str], env: dict) -> tuple[float, set[str]]:
    """(import time s, top-level packages imported) of ``python -X importtime ARGS``."""
    p = subprocess.run([sys.executable, "-X", "importtime", *args], env=env, cwd=env["CWD"],
                       capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr[-2000:]
    total, packages = 0.0, set()
    for line in p.stderr.splitlines():
        if not line.startswith("import time:") or "cumulative" in line:
            continue
        _, cumulative, name = line.split("|")
        if not name[1:].startswith(" "):  # a top-level entry: its cumulative time covers its sub-imports
            total += int(cumulative) * 1e-6
        packages.add(name.strip().split(".")[0])
    return total, packages


def _best(args: list[str], env: dict) -> tuple[float, set[str]]:
    runs = [_importtime(args, env) for _ in range(RUNS)]
    return min(t for t, _ in runs), runs[0][1]


@pytest.fixture(scope="module")
def env(tmp_path_factory) -> dict:
    tmp = tmp_path_factory.mktemp("startup")
    env = {**os.environ, "PYTHONPATH": str(ROOT), "WORKBENCH_DB": f"sqlite:///{tmp / 'wb.db'}", "CWD": str(tmp)}
    subprocess.run([sys.executable, "-m", "workbench", "db", "upgrade"], env=env, cwd=tmp, check=True,
                   capture_output=True, timeout=120)  # an existing store: creating one runs the migrations
    return env


def test_help_imports_only_the_cli(env):
    took, packages = _best(["-m", "workbench", "--help"], env)
    needed = _best(["-c", FRAMEWORK], env)[0]
    print(f"--help imports {took:.3f} s, the CLI framework {needed:.3f} s")
    assert not packages & {*HEAVY, "sqlalchemy"}, f"--help imports {sorted(packages & {*HEAVY, 'sqlalchemy'})}"
    assert took < MARGIN * needed, f"--help imports take {took:.3f} s, the CLI framework {needed:.3f} s"


def test_sets_list_imports_the_store_but_no_numerics(env):
    took, packages = _best(["-m", "workbench", "sets", "list"], env)
    needed = _best(["-c", STORE], env)[0]
    print(f"sets list imports {took:.3f} s, the CLI framework and the store's libraries {needed:.3f} s")
    assert "sqlalchemy" in packages  # the store is what the command needs
    assert not packages & set(HEAVY), f"sets list imports {sorted(packages & set(HEAVY))}"
    assert took < MARGIN * needed, f"sets list imports take {took:.3f} s, its libraries {needed:.3f} s"
