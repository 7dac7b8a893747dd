"""Batch analysis of many sessions on a Dask cluster.

The work unit is :func:`analyze_one`, the same analysis the single-session path runs
(``procedure.analyze`` plus provenance); it never raises, so a bad session is reported and the
rest go on. Results stream into the store from the submitting process as they complete, the
ones that arrive together in one transaction.
:func:`cluster_client` makes a ``LocalCluster`` on 127.0.0.1 (dashboard off unless asked) or
connects to a running scheduler, failing fast when the address does not answer.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

from workbench.errors import WorkbenchError


def analyze_one(procedure: str, session_dir: str, options: Mapping | None = None) -> dict:
    """Analyse one session: the outcome dict ``session_dir``, ``procedure``, ``ok``, and ``error`` or
    ``result`` (JSON-ready), ``calibration`` (a validated :class:`CalibrationSet` or None) and ``session``.

    Runs in a worker process. Exceptions become ``ok: False`` with a one-line ``error``. The set
    travels as an object: the store serialises it once, in the submitting process.
    """
    from workbench.procedure import analysed, result_json
    from workbench.registry import procedure as get_procedure
    from workbench.session import load_session

    outcome: dict = {"session_dir": str(session_dir), "procedure": procedure, "ok": False}
    try:
        proc = get_procedure(procedure)
        # procedures that stream long records (LAZY_OK) get the samples left on disk: bounded memory
        session = load_session(session_dir, lazy=bool(getattr(proc, "LAZY_OK", False)))
        result = analysed(proc, session, options)  # through the plausibility gate: a wrong set is an error
        if result.calibration is not None:
            result.calibration.to_dict()  # validates here: an invalid set fails this session, store or not
        outcome.update(
            ok=True, result=json.loads(result_json(result)), calibration=result.calibration,
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
    """Write one successful outcome (session record, result and its calibration set) in one transaction."""
    s = outcome["session"]
    with store.batch():
        store.add_session(s["id"], s["serial"], s["model"], outcome["procedure"], s["path"], s["sha256"],
                          s["n_steps"])
        store.add_result(outcome["procedure"], s["id"], s["serial"], outcome["result"], outcome["calibration"])


def store_outcomes(store, outcomes: Sequence[dict]) -> None:
    """Write the successful ``outcomes`` in one store transaction (one commit for all).

    If that transaction fails (an invalid set, a conflict with another writer), each outcome is
    written again on its own, so only the bad one is marked failed (``ok: False``, ``error``).
    """
    ok = [o for o in outcomes if o["ok"]]
    if len(ok) > 1:  # (one outcome is one transaction already)
        try:
            with store.batch():
                for o in ok:
                    store_outcome(store, o)
            return
        except WorkbenchError:
            pass  # rolled back as a whole: isolate the failure below
    for o in ok:
        try:
            store_outcome(store, o)
        except WorkbenchError as exc:
            o.update(ok=False, error=str(exc))


def warm_up(client, procedure: str) -> dict[str, float]:
    """Import ``procedure`` and the libraries its analysis needs on every worker; seconds per worker.

    Optional: the first task on a worker would pay the same import. It lets the start-up be
    timed apart from the analysis, and starts no task.
    """
    return client.run(_import_procedure, procedure)


def _import_procedure(procedure: str) -> float:
    import time

    t0 = time.perf_counter()
    from workbench.registry import procedure as get_procedure

    get_procedure(procedure)  # the procedure module imports the session and analysis libraries
    return time.perf_counter() - t0


# environment of a local worker process, set before it starts (None: not set, the library default)
WORKER_ENV = {"OMP_NUM_THREADS": 1, "MKL_NUM_THREADS": 1, "OPENBLAS_NUM_THREADS": 1, "MALLOC_TRIM_THRESHOLD_": None}


@contextmanager
def cluster_client(scheduler: str = "local", workers: int = 2, dashboard: bool = False) -> Iterator:
    """A ``distributed.Client``: a LocalCluster on 127.0.0.1, or the scheduler at ``tcp://HOST:PORT``.

    The local cluster runs one single-threaded process per worker (the analyses hold the GIL in
    pandas/Python code) with OMP/MKL/OPENBLAS_NUM_THREADS=1, so numeric libraries do not
    oversubscribe the cores, and with glibc's default allocator settings: Dask's default
    ``MALLOC_TRIM_THRESHOLD_=65536`` also freezes the mmap threshold at 128 KiB, so every array of
    a session is a fresh mmap, page-faulted in (a multi-position analysis: 4-6x the page faults,
    ~15 % more CPU).
    """
    import dask
    from distributed import Client, LocalCluster

    if scheduler == "local":
        env = {f"distributed.nanny.pre-spawn-environ.{k}": v for k, v in WORKER_ENV.items()}
        with dask.config.set(env):  # read when the nannies are made; a restarted worker keeps it
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
        raise WorkbenchError(f"--scheduler {scheduler!r}: expected 'local', 'serial' or tcp://HOST:PORT")
    try:
        client = Client(scheduler, timeout="5s")
    except (OSError, TimeoutError) as exc:
        raise WorkbenchError(f"scheduler {scheduler} does not answer ({type(exc).__name__}); nothing started") from None
    try:
        yield client
    finally:
        client.close()


STORE_BATCH = 32  # outcomes per store transaction at most


def run_batch(procedure: str, session_dirs: Iterable[str | Path], client=None, store=None,
              options: Mapping | None = None, progress: Callable[[int, int, dict], None] | None = None,
              keep_results: bool = True) -> BatchReport:
    """Analyse every session; on ``client`` (Dask) in parallel, else serially in this process.

    Outcomes go to ``store`` as they complete: serially one transaction each; from the cluster,
    the outcomes that arrived together (while the previous ones were written) share one
    transaction of at most ``STORE_BATCH``. Failures (an analysis error, a worker that died, a
    store write refused) are reported in the returned :class:`BatchReport` and the batch
    continues. A result leaves its worker as soon as it is fetched; with ``keep_results=False``
    the report keeps only ``session_dir``, ``procedure``, ``ok`` and ``error`` of each outcome, so the
    submitting process's memory does not grow with the results either.
    """
    from workbench.options import split
    from workbench.registry import procedure as get_procedure

    # an unknown procedure or option, or a bad value: fail before anything starts
    split(get_procedure(procedure), options)
    dirs = [str(d) for d in session_dirs]
    report = BatchReport()

    def handle(outcomes: list[dict]) -> None:
        if store is not None:
            store_outcomes(store, outcomes)
        for outcome in outcomes:
            report.outcomes.append(outcome if keep_results else
                                   {k: outcome[k] for k in ("session_dir", "procedure", "ok", "error") if k in outcome})
            if progress is not None:
                progress(len(report.outcomes), len(dirs), outcome)

    if client is None:
        for d in dirs:
            handle([analyze_one(procedure, d, options)])
        return report
    from distributed import as_completed

    futures = client.map(analyze_one, [procedure] * len(dirs), dirs, options=dict(options or {}), pure=False)
    dir_of = {f.key: d for f, d in zip(futures, dirs)}
    completed = as_completed(futures, with_results=True, raise_errors=False)
    del futures  # as_completed holds the only references: a result is released once fetched
    for ready in completed.batches():
        outcomes = [result if f.status == "finished" else
                    _lost(procedure, dir_of[f.key], result[1] if f.status == "error" else result)
                    for f, result in ready]
        del ready
        for i in range(0, len(outcomes), STORE_BATCH):
            handle(outcomes[i:i + STORE_BATCH])
    return report


def _lost(procedure: str, session_dir: str, exc: BaseException) -> dict:
    """The outcome of a task that produced no result (it raised, its worker died, or it was cancelled)."""
    message = str(exc).splitlines()[0] if str(exc) else ""
    return {"session_dir": session_dir, "procedure": procedure, "ok": False,
            "error": f"{type(exc).__name__}: {message}"[:300]}
