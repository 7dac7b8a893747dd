import os
import subprocess
import sys

import numpy as np
import pytest

from workbench.calset import CalibrationSet, TriadCalibration, Unit
from workbench.diff import diff_sets
from workbench.errors import StoreError
from workbench.model import TriadModel
from workbench.store import Store


def a_set(serial="U1", bias=0.01) -> CalibrationSet:
    tc = TriadCalibration(TriadModel(bias=[bias, 0, 0]), {"bias": np.full(3, 0.001)})
    return CalibrationSet(Unit(serial, "m"), {"accel": tc})


def test_versions_latest_history_and_diff(tmp_path):
    store = Store(f"sqlite:///{tmp_path}/w.db")
    s1, s2 = a_set(bias=0.010), a_set(bias=0.013)
    assert store.add_set(s1) == 1 and store.add_set(s2) == 2
    assert store.latest("U1").id == s2.id
    assert [i.version for i in store.history("U1")] == [2, 1]
    rows = diff_sets(store.get_set(s1.id), store.get_set(s2.id[:8]))
    assert len(rows) == 1 and rows[0].field == "bias" and rows[0].index == (0,)
    assert np.isclose(rows[0].change_in_sigma, 0.003 / np.sqrt(2 * 0.001**2))
    with pytest.raises(StoreError, match="immutable"):
        store.add_set(s1)


def test_unopenable_store_is_a_clear_error(tmp_path):
    with pytest.raises(StoreError, match="does not exist"):
        Store(f"sqlite:///{tmp_path}/missing/dir/w.db")


def test_crash_mid_write_leaves_nothing(tmp_path):
    # a writer killed inside its transaction (after the INSERT, before COMMIT)
    url = f"sqlite:///{tmp_path}/w.db"
    store = Store(url)
    store.add_set(a_set())
    code = f"""
import os
from sqlalchemy import event
from workbench.store import Store
from tests.core.test_store import a_set
store = Store({url!r})
@event.listens_for(store.engine, "commit")
def die(conn):
    os._exit(9)
store.add_set(a_set(bias=0.5))
"""
    env = {**os.environ, "PYTHONPATH": os.getcwd()}
    proc = subprocess.run([sys.executable, "-c", code], env=env, cwd=os.getcwd())
    assert proc.returncode == 9
    fresh = Store(url)
    assert [i.version for i in fresh.history("U1")] == [1]
    assert fresh.latest("U1").model("accel").bias[0] == pytest.approx(0.01)


WRITER = """
import sys
from workbench.store import Store
from tests.core.test_store import a_set
store = Store(sys.argv[1])
for k in range(int(sys.argv[3])):
    store.add_set(a_set(bias=float(sys.argv[2]) + k * 1e-3))
"""


def run_writers(url: str, processes: int, sets_each: int) -> None:
    """``processes`` concurrent processes each storing ``sets_each`` versions of unit U1."""
    env = {**os.environ, "PYTHONPATH": os.getcwd()}
    procs = [subprocess.Popen([sys.executable, "-c", WRITER, url, str(s), str(sets_each)], env=env)
             for s in range(1, processes + 1)]
    assert [p.wait(180) for p in procs] == [0] * processes


def test_two_concurrent_writers(tmp_path):
    url = f"sqlite:///{tmp_path}/w.db"
    Store(url)
    run_writers(url, 2, 15)
    versions = sorted(i.version for i in Store(url).history("U1"))
    assert versions == list(range(1, 31))
