"""Folders the dashboard may read: typed-in paths confined to the configured data roots.

``WORKBENCH_DATA_ROOTS`` (paths separated by ``os.pathsep``) lists them; by default the runs
folder and the dashboard's working directory. A typed folder outside every root (after
resolving ``..`` and symlinks) is refused, so a visitor cannot browse the machine.
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path

from workbench.errors import WorkbenchError

ROOTS_ENV = "WORKBENCH_DATA_ROOTS"


def data_roots(defaults: Iterable[Path]) -> list[Path]:
    """The data roots, resolved: ``WORKBENCH_DATA_ROOTS`` if set, else ``defaults``."""
    env = os.environ.get(ROOTS_ENV)
    roots = [Path(p) for p in env.split(os.pathsep) if p.strip()] if env else list(defaults)
    return [r.expanduser().resolve() for r in roots]


def confined_folder(typed: str, roots: list[Path]) -> Path:
    """The folder ``typed`` resolved, if it lies inside one of ``roots``; WorkbenchError otherwise."""
    path = Path(typed.strip()).expanduser().resolve()
    if not any(path == r or r in path.parents for r in roots):
        raise WorkbenchError(f"{typed}: outside the data roots ({', '.join(map(str, roots))}); "
                             f"set {ROOTS_ENV} to add a folder")
    return path


def _store_dir() -> Path | None:
    """The folder of the SQLite store named by ``WORKBENCH_DB`` (None for another database or ``:memory:``)."""
    from workbench.store import default_url

    url = default_url()
    if url.startswith("sqlite:///") and url != "sqlite:///:memory:":
        return Path(url.removeprefix("sqlite:///")).resolve().parent
    return None


def runs_dir() -> Path:
    """Where dashboard runs write their folders: ``WORKBENCH_RUNS``, else next to a SQLite store, else ./runs."""
    env = os.environ.get("WORKBENCH_RUNS")
    if env:
        return Path(env)
    store = _store_dir()
    return store / "runs" if store is not None else Path("runs").resolve()


def default_roots() -> list[Path]:
    """Folders a typed session folder may lie in by default: the runs folder, a SQLite store's folder, the cwd."""
    store = _store_dir()
    return [runs_dir(), *([store] if store is not None else []), Path.cwd()]
