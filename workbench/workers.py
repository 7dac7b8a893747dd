"""Forked worker processes for the independent jobs of one command (a campaign's procedures, figures).

:class:`Workers` forks ``n`` processes. Each inherits the parent's memory as it was at the fork
(the modules already imported, the context a job needs), so a job is sent as a small message
(a kind and a few arguments), not as pickled data. Every worker has its own inbox, so the
parent decides which worker runs which job (a job that needs what an earlier job left in a
worker's memory, such as a recorded session, goes to that worker), and all of them answer in
one outbox: a job's value, its failure, or a progress message on the way.

A failure in a worker is raised again in the parent as the same exception (a one-line
:class:`~workbench.errors.WorkbenchError` stays one line); a worker that dies is reported as a
WorkbenchError naming its exit code. Ctrl-C reaches the workers too (one process group): each
stops where it is (a recording makes its rig safe first) and the parent stops them all.
:func:`usable_workers` says how many processes are worth starting (the CPUs this process may
run on; ``WORKBENCH_WORKERS`` overrides, 1 means everything runs in the calling process).

In a worker the cyclic garbage collector leaves the objects inherited from the parent alone
(frozen at the fork: collecting them would touch, and so copy, their pages in every worker) and
collects its youngest generation every :data:`GC_YOUNG_THRESHOLD` allocations: in a campaign's two
workers (measured at load 9) about 0.25 s of collector CPU instead of 0.6 s.
"""

from __future__ import annotations

import gc
import multiprocessing as mp
import os
import pickle
import queue
import resource
import sys
import time
from collections.abc import Callable
from typing import Any

from workbench.errors import WorkbenchError

# a job handler: (worker memory, job kind, job arguments, emit) -> value; emit(message) sends a
# progress message to the parent while the job runs
Handler = Callable[[dict, str, tuple, Callable[[Any], None]], Any]
# allocations between two collections of the youngest generation in a worker (Python's default: 700);
# a campaign's jobs make many short-lived containers (figure artists, analysis results)
GC_YOUNG_THRESHOLD = 10_000


def usable_workers(jobs: int) -> int:
    """Worker processes worth starting for ``jobs`` independent jobs (1: run them in this process)."""
    env = os.environ.get("WORKBENCH_WORKERS", "").strip()
    if env:
        try:
            n = int(env)
        except ValueError:
            raise WorkbenchError(f"WORKBENCH_WORKERS={env!r}: expected a whole number of processes") from None
    else:
        n = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    if "fork" not in mp.get_all_start_methods():
        return 1
    return max(1, min(n, jobs))


def usage_since(wall: float, cpu: float) -> dict:
    """Wall and CPU seconds since ``time.perf_counter()`` = ``wall`` and ``time.process_time()`` = ``cpu``,
    and this process's peak resident memory (bytes) so far."""
    return {"wall_s": time.perf_counter() - wall, "cpu_s": time.process_time() - cpu,
            "peak_rss": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024}


def _portable(exc: BaseException) -> BaseException:
    """``exc`` if it survives pickling, else a WorkbenchError with its one-line message."""
    try:
        pickle.loads(pickle.dumps(exc))
        return exc
    except Exception:  # an exception type whose arguments do not round-trip
        return WorkbenchError(f"{type(exc).__name__}: {' '.join(str(exc).split())}")


def fresh_std_streams() -> None:
    """Give a forked process its own ``sys.stdout``/``sys.stderr`` objects on the same files.

    A thread of the parent (a progress bar refreshing itself) may have held a stream's lock at
    the fork; the child's copy of that lock would never be released.
    """
    for name, fd in (("stdout", 1), ("stderr", 2)):
        old = getattr(sys, name)
        try:
            setattr(sys, name, open(fd, "w", buffering=1, encoding=getattr(old, "encoding", None) or "utf-8",
                                    errors=getattr(old, "errors", None) or "backslashreplace", closefd=False))
        except (OSError, ValueError):  # no such file descriptor: keep the object
            pass


def _serve(wid: int, inbox, outbox, handler: Handler) -> None:
    """A worker's loop: run each job of its inbox, answer in the outbox, stop at None (or Ctrl-C)."""
    fresh_std_streams()
    gc.set_threshold(GC_YOUNG_THRESHOLD, *gc.get_threshold()[1:])
    try:
        _jobs(wid, inbox, outbox, handler)
    except KeyboardInterrupt:  # Ctrl-C while waiting for a job: the parent stops too
        return


def _jobs(wid: int, inbox, outbox, handler: Handler) -> None:
    memory: dict = {}
    while True:
        job = inbox.get()
        if job is None:
            return
        key, kind, args = job
        wall, cpu = time.perf_counter(), time.process_time()
        try:
            value = handler(memory, kind, args, lambda message: outbox.put(("progress", wid, key, message)))
        except BaseException as exc:  # noqa: BLE001 - every failure goes to the parent, which raises it
            outbox.put(("failed", wid, key, _portable(exc)))
            if not isinstance(exc, Exception):  # Ctrl-C, exit: this worker stops
                return
            continue
        outbox.put(("done", wid, key, (value, usage_since(wall, cpu))))


class Workers:
    """``n`` forked worker processes running the jobs of ``handler`` (see the module docstring)."""

    def __init__(self, n: int, handler: Handler) -> None:
        ctx = mp.get_context("fork")
        self.outbox = ctx.Queue()
        self.inboxes = [ctx.Queue() for _ in range(n)]
        self.busy: dict[int, object] = {}  # worker -> key of the job it runs
        self.processes = [ctx.Process(target=_serve, args=(w, self.inboxes[w], self.outbox, handler),
                                      name=f"workbench-worker-{w}", daemon=True) for w in range(n)]
        gc.freeze()  # the objects inherited from this process are left out of the workers' collections
        try:  # (which would otherwise touch, and so copy, every page of them)
            for p in self.processes:
                p.start()
        finally:
            gc.unfreeze()

    @property
    def idle(self) -> list[int]:
        """Workers without a job, in order."""
        return [w for w in range(len(self.processes)) if w not in self.busy]

    def send(self, worker: int, key, kind: str, *args) -> None:
        """Give job ``key`` (``kind``, ``args``) to an idle ``worker``."""
        self.busy[worker] = key
        self.inboxes[worker].put((key, kind, args))

    def receive(self) -> tuple[str, int, object, Any]:
        """The next message: ``("progress", worker, key, message)`` or ``("done", worker, key, (value, usage))``.

        ``usage``: the job's ``wall_s`` and ``cpu_s`` in its worker and the worker's ``peak_rss``
        (bytes) so far. A failed job raises its exception here; a dead worker a WorkbenchError.
        """
        while True:
            try:
                kind, worker, key, payload = self.outbox.get(timeout=0.5)
            except queue.Empty:
                for w, p in enumerate(self.processes):
                    if not p.is_alive():
                        raise WorkbenchError(f"worker process {w} stopped (exit code {p.exitcode}) "
                                             f"during job {self.busy.get(w)}") from None
                continue
            if kind == "progress":
                return kind, worker, key, payload
            self.busy.pop(worker, None)
            if kind == "failed":
                raise payload
            return kind, worker, key, payload

    def close(self) -> None:
        """Stop every worker (at once if a job is still running)."""
        for w, p in enumerate(self.processes):
            if p.is_alive() and w not in self.busy:
                self.inboxes[w].put(None)
        deadline = time.monotonic() + 5.0
        for w, p in enumerate(self.processes):
            if w in self.busy:
                p.terminate()
            p.join(max(0.0, deadline - time.monotonic()))
            if p.is_alive():
                p.kill()
                p.join()
        for q in (self.outbox, *self.inboxes):
            q.close()
            q.cancel_join_thread()

    def __enter__(self) -> Workers:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
