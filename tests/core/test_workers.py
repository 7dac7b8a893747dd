"""Forked worker processes (workbench/workers.py): values, progress, failures and dead workers reach the parent."""

from __future__ import annotations

import os

import pytest

from workbench.errors import ProcedureError, WorkbenchError
from workbench.workers import Workers, usable_workers


def _handler(memory: dict, kind: str, args: tuple, emit) -> object:
    if kind == "square":
        emit(("working on", args[0]))
        memory["last"] = args[0]
        return args[0] ** 2, os.getpid()
    if kind == "last":  # what an earlier job left in this worker's memory
        return memory.get("last")
    if kind == "fail":
        raise ProcedureError(f"thermal: step {args[0]}: the soak did not settle")
    if kind == "die":
        os._exit(3)
    raise ValueError(kind)


def _value(pool: Workers):
    """The value of the next job that finishes (progress messages skipped)."""
    while True:
        kind, _, _, payload = pool.receive()
        if kind == "done":
            return payload[0]


def test_jobs_run_in_other_processes_and_keep_their_memory():
    with Workers(2, _handler) as pool:
        pool.send(0, "a", "square", 3)
        pool.send(1, "b", "square", 4)
        got, progress = {}, []
        while pool.busy:
            kind, worker, key, payload = pool.receive()
            if kind == "progress":
                progress.append((key, payload))
            else:
                got[key] = (worker, payload[0], payload[1])
        assert {k: v[1][0] for k, v in got.items()} == {"a": 9, "b": 16}
        assert {v[1][1] for v in got.values()}.isdisjoint({os.getpid()})  # not run here
        assert sorted(progress) == [("a", ("working on", 3)), ("b", ("working on", 4))]
        assert all(u["cpu_s"] >= 0 and u["peak_rss"] > 0 for _, _, u in got.values())
        pool.send(1, "c", "last")
        assert _value(pool) == 4  # worker 1 still holds what its job left


def test_a_failure_in_a_worker_is_raised_here_as_the_same_one_line_error():
    with Workers(2, _handler) as pool:
        pool.send(0, "x", "fail", 7)
        with pytest.raises(ProcedureError, match=r"^thermal: step 7: the soak did not settle$"):
            pool.receive()
        pool.send(0, "y", "square", 2)  # the worker goes on after a failed job
        assert _value(pool)[0] == 4


def test_a_worker_that_dies_is_named():
    with Workers(1, _handler) as pool:
        pool.send(0, "z", "die")
        with pytest.raises(WorkbenchError, match=r"worker process 0 stopped \(exit code 3\) during job z"):
            pool.receive()


def test_usable_workers(monkeypatch):
    monkeypatch.setenv("WORKBENCH_WORKERS", "1")
    assert usable_workers(5) == 1
    monkeypatch.setenv("WORKBENCH_WORKERS", "8")
    assert usable_workers(3) == 3  # never more than the jobs
    monkeypatch.setenv("WORKBENCH_WORKERS", "two")
    with pytest.raises(WorkbenchError, match="WORKBENCH_WORKERS='two'"):
        usable_workers(2)
