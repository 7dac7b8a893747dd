"""The fuzz suite's lab: a store with one set, a recorded session, a set file, a profile and its recording.

Built once per session of the suite (a module-scoped world is shared by the property tests,
which call the CLI entry function in-process: no process per example).
"""

from __future__ import annotations

import copy
import io
import json
import shutil
from contextlib import redirect_stderr, redirect_stdout
from dataclasses import dataclass
from pathlib import Path

import pytest
import yaml
from hypothesis import HealthCheck, Phase, settings

from tests.core.test_import_safety import _recording
from tests.core.test_store import a_set
from workbench.cli import main
from workbench.rigconfig import RIGS_DIR
from workbench.store import Store

# bounded and reproducible: the same examples on every run (CI stays deterministic and fast)
# (no shrinking phase: a failure is reported as found, so a failing run stays as bounded as a passing one)
settings.register_profile("fuzz", max_examples=20, deadline=None, derandomize=True, database=None,
                          phases=[Phase.explicit, Phase.generate],
                          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture,
                                                 HealthCheck.filter_too_much])
settings.load_profile("fuzz")


@dataclass
class World:
    """Files the properties mutate copies of, and the store they must leave unchanged."""

    root: Path
    store: Store
    session: Path  # a recorded multiposition session (session.json + samples.parquet)
    set_file: Path
    profile: Path
    recording: Path
    rig: dict

    def store_state(self) -> tuple:
        """Everything a command could have written to the store."""
        return (tuple((i.id, i.version, i.approved_by) for i in self.store.list_sets()),
                tuple(s.id for s in self.store.list_sessions()), len(self.store.list_results()))

    def fresh(self, name: str) -> Path:
        """A new, empty scratch folder for one example."""
        n = len(list(self.root.glob(f"{name}-*")))
        d = self.root / f"{name}-{n}"
        d.mkdir()
        return d

    def session_copy(self) -> Path:
        d = self.fresh("session") / "s"
        shutil.copytree(self.session, d)
        return d


def tree(folder: Path) -> dict:
    """Every file under ``folder`` with its bytes (a folder left unchanged compares equal)."""
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def cli(argv: list[str]) -> tuple[int, str, str]:
    """Run the CLI entry function in-process; (exit code, stdout, stderr)."""
    out, err = io.StringIO(), io.StringIO()
    with redirect_stdout(out), redirect_stderr(err):
        code = main([str(a) for a in argv])
    return code, out.getvalue(), err.getvalue()


def assert_refused_cleanly(world: World, argv: list[str], watched: list[Path] = (), strict: bool = False) -> int:
    """The property: success, or one line on stderr, exit 2, no traceback, store and ``watched`` unchanged.

    ``strict``: the input is known to be bad, so it must be refused (exit 2).
    """
    before_store, before = world.store_state(), [tree(w) if w.is_dir() else None for w in watched]
    code, out, err = cli(argv)
    assert "Traceback" not in out + err, err
    if code == 0 and not strict:
        return code
    lines = err.strip().splitlines()
    assert code == 2, (argv, code, err)
    assert len(lines) == 1 and lines[0].startswith("error:"), (argv, err)
    assert world.store_state() == before_store
    assert [tree(w) if w.is_dir() else None for w in watched] == before
    return code


@pytest.fixture(scope="session")
def world(tmp_path_factory) -> World:
    root = tmp_path_factory.mktemp("fuzz")
    mp = pytest.MonkeyPatch()
    mp.setenv("WORKBENCH_DB", f"sqlite:///{root}/w.db")
    mp.setenv("WORKBENCH_RUNS", str(root / "runs"))
    mp.chdir(root)
    store = Store()
    store.add_set(a_set(serial="FUZZ-1"))
    code, _, err = cli(["run", "multiposition", "--out", root / "mp", "-o", "dwell_s=2", "--no-store"])
    assert code == 0, err
    set_file = a_set(serial="FUZZ-2", bias=0.02).save(root / "set.json")
    profile, recording = _recording(root / "rec")
    yield World(root, store, root / "mp" / "session", set_file, profile, recording,
                copy.deepcopy(yaml.safe_load((RIGS_DIR / "hil.yaml").read_text())))
    mp.undo()


def dump(path: Path, data, kind: str = "yaml") -> Path:
    """Write ``data`` as YAML or JSON (NaN and infinities as the formats spell them)."""
    path.write_text(yaml.safe_dump(data, allow_unicode=True) if kind == "yaml" else json.dumps(data))
    return path


