"""Batch analysis of many sessions on a Dask cluster.

The work unit is :func:`analyze_one`, the same analysis the single-session path runs
(``procedure.analyze`` plus provenance); it never raises, so a bad session is reported and the
rest go on. Results stream into the store from the submitting process as they complete.
:func:`cluster_client` makes a ``LocalCluster`` on 127.0.0.1 (dashboard off unless asked) or
connects to a running scheduler, failing fast when the address does not answer.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Callable, Iterable, Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

from workbench.calset import CalibrationSet
from workbench.errors import WorkbenchError


def analyze_one(procedure: str, session_dir: str, options: Mapping | None = None) -> dict:
    """Analyse one session; returns a JSON-ready outcome (``ok``, ``error``, ``result``, ``calibration``).

    Runs in a worker process. Exceptions become ``ok: False`` with a one-line ``error``.
    """
    from workbench.procedure import result_json, with_session_provenance
    from workbench.registry import procedure as get_procedure
    from workbench.session import load_session

    outcome: dict = {"session_dir": str(session_dir), "procedure": procedure, "ok": False}
    try:
        proc = get_procedure(procedure)
        # procedures that stream long records (LAZY_OK) get the samples left on disk: bounded memory
        session = load_session(session_dir, lazy=bool(getattr(proc, "LAZY_OK", False)))
        result = with_session_provenance(proc.analyze(session, **dict(options or {})), session)
        outcome.update(
            ok=True, result=json.loads(result_json(result)),
            calibration=None if result.calibration is None else result.calibration.to_json(),
            session={"id": session.id, "serial": session.unit.serial, "model": session.unit.model,
                     "path": str(session.path), "sha256": session.samples_sha256() or "",
                     "n_steps": len(session.steps)})
    except WorkbenchError as exc:
        outcome["error"] = str(exc)
    except Exception as exc:  # a worker must report, not die: the batch goes on
        outcome["error"] = f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}"
    return outcome


@dataclass
class BatchReport:
    """What a batch did: outcomes in completion order, and the failures."""

    outcomes: list[dict] = field(default_factory=list)

    @property
    def failures(self) -> list[dict]:
        return [o for o in self.outcomes if not o["ok"]]

    @property
    def succeeded(self) -> list[dict]:
        return [o for o in self.outcomes if o["ok"]]


def store_outcome(store, outcome: Mapping) -> None:
    """Write one successful outcome (session record, result and its calibration set) to the store."""
    s = outcome["session"]
    store.add_session(s["id"], s["serial"], s["model"], outcome["procedure"], s["path"], s["sha256"], s["n_steps"])
    cal = None if outcome["calibration"] is None else CalibrationSet.from_json(outcome["calibration"])
    store.add_result(outcome["procedure"], s["id"], s["serial"], outcome["result"], cal)


@contextmanager
def cluster_client(scheduler: str = "local", workers: int = 2, dashboard: bool = False) -> Iterator:
    """A ``distributed.Client``: a LocalCluster on 127.0.0.1, or the scheduler at ``tcp://HOST:PORT``."""
    from distributed import Client, LocalCluster

    if scheduler == "local":
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, host="127.0.0.1",
                               dashboard_address="127.0.0.1:8787" if dashboard else None,
                               silence_logs=logging.ERROR)
        client = Client(cluster)
        try:
            yield client
        finally:
            client.close()
            cluster.close()
        return
    if not scheduler.startswith("tcp://"):
        raise WorkbenchError(f"--scheduler {scheduler!r}: expected 'local' or tcp://HOST:PORT")
    try:
        client = Client(scheduler, timeout="5s")
    except (OSError, TimeoutError) as exc:
        raise WorkbenchError(f"scheduler {scheduler} does not answer ({type(exc).__name__}); nothing started") from None
    try:
        yield client
    finally:
        client.close()


def run_batch(procedure: str, session_dirs: Iterable[str | Path], client=None, store=None,
              options: Mapping | None = None, progress: Callable[[int, int, dict], None] | None = None) -> BatchReport:
    """Analyse every session; on ``client`` (Dask) in parallel, else serially in this process.

    Each successful outcome goes to ``store`` as soon as it completes; failures are reported
    in the returned :class:`BatchReport` and the batch continues.
    """
    from workbench.registry import procedure as get_procedure

    get_procedure(procedure)  # unknown procedure: fail before anything starts
    dirs = [str(d) for d in session_dirs]
    report = BatchReport()

    def handle(outcome: dict) -> None:
        if outcome["ok"] and store is not None:
            try:
                store_outcome(store, outcome)
            except WorkbenchError as exc:
                outcome.update(ok=False, error=str(exc))
        report.outcomes.append(outcome)
        if progress is not None:
            progress(len(report.outcomes), len(dirs), outcome)

    if client is None:
        for d in dirs:
            handle(analyze_one(procedure, d, options))
        return report
    from distributed import as_completed

    futures = [client.submit(analyze_one, procedure, d, dict(options or {}), pure=False) for d in dirs]
    for fut in as_completed(futures):
        handle(fut.result())
    return report
