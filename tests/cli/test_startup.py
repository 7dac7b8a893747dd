"""Start-up cost of the command line: which libraries ``--help`` and ``sets list`` load.

Each command runs in a fresh interpreter under ``python -X importtime``, which lists every
module the command imported. The test asserts on that list, not on seconds: a shared machine
can make any import slow, but it cannot make a command import pandas. The heavy libraries
(numerics, Parquet, plotting, the set format's schema validator, migrations) cost 0.05-0.35 s
each to import; ``--help`` must load none of them, nor SQLAlchemy or pydantic (the coercion
layer typer loads only to convert a command's parameters), and ``sets list`` only the store's
SQLAlchemy and typer's pydantic. The seconds behind this (issue 23: ``workbench --help`` under
0.3 s, ``sets list`` under 0.5 s wall) are printed by ``benchmarks/startup_speed.py``.
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


def _imported(args: list[str], env: dict) -> set[str]:
    """Top-level packages imported by ``python -X importtime ARGS`` (which must exit 0)."""
    p = subprocess.run([sys.executable, "-X", "importtime", *args], env=env, cwd=env["CWD"],
                       capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr[-2000:]
    return {line.split("|")[2].strip().split(".")[0] for line in p.stderr.splitlines()
            if line.startswith("import time:") and "cumulative" not in line}


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
    forbidden = packages & {*HEAVY, "sqlalchemy", "pydantic"}
    assert not forbidden, f"--help imports {sorted(forbidden)}"


def test_sets_list_imports_the_store_but_no_numerics(env):
    packages = _imported(["-m", "workbench", "sets", "list"], env)
    assert "sqlalchemy" in packages  # the store is what the command needs
    forbidden = packages & set(HEAVY)
    assert not forbidden, f"sets list imports {sorted(forbidden)}"
