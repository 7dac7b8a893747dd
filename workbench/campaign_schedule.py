"""Running a campaign's procedures: in order in this process, or in parallel in worker processes.

A campaign (:class:`workbench.jobs.CampaignPlan`) is a few procedures, each three steps:
record its session, analyse it, save its figures. Recordings are independent (each procedure
has its own rig and seed); an analysis needs its own session and the noise terms of the
procedures before it that give them (the Allan record's B and K for the static and thermal
fits: :func:`workbench.jobs.noise_options_known`); figures need their result. With two or more
workers (:mod:`workbench.workers`) the recordings start at once, longest planned first; an
analysis runs, as soon as its noise terms are known, in the worker that holds its session
(which draws its figures there and then); figures are saved last, one job per figure, each
worker first saving the figures it holds. A worker with none left takes over figures of a
procedure with at least :data:`SPLIT_FIGURES` still to save, draws that procedure's figures
once and saves them one by one alongside the holder, so both workers finish within about a
figure of each other. Every step depends
only on its arguments, so the files are the same as in order in one process. On a real rig
(one turntable) everything runs in order in this process.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field

from workbench.workers import Workers, usable_workers, usage_since

SPLIT_FIGURES = 3  # a worker draws another's procedure again only to share this many figures or more


@dataclass(frozen=True)
class SessionInfo:
    """What the store records of a campaign session (the samples stay in the session folder)."""

    id: str
    serial: str
    model: str
    path: str
    sha256: str
    n_steps: int

    @classmethod
    def of(cls, session) -> SessionInfo:
        """The record of a :class:`workbench.session.Session`."""
        return cls(session.id, session.unit.serial, session.unit.model, str(session.path),
                   session.samples_sha256() or "", len(session.steps))


@dataclass
class Done:
    """What :func:`run_plan` returns, per procedure index."""

    results: list = field(default_factory=list)
    options: dict[int, dict] = field(default_factory=dict)  # the analysis options each ran with
    sessions: list[SessionInfo | None] = field(default_factory=list)
    usage: dict[int, dict[str, dict]] = field(default_factory=dict)
    busy_s: list[float] = field(default_factory=list)  # per worker process: wall s spent in jobs (none in order)


def run_plan(plan, progress_for: Callable[[str], Callable | None] | None = None, workers: int | None = None) -> Done:
    """Record, analyse and draw every procedure of ``plan``; ``workers`` processes (default: usable CPUs)."""
    n = len(plan.procs)
    workers = usable_workers(n) if workers is None else max(1, min(int(workers), n))
    if plan.cfg.driver != "sim":  # one real turntable: its recordings follow one another
        workers = 1
    return _in_order(plan, progress_for) if workers == 1 else _in_parallel(plan, progress_for, workers)


def _in_order(plan, progress_for) -> Done:
    n = len(plan.procs)
    done = Done([None] * n, {}, [None] * n, {k: {} for k in range(n)})
    for k in range(n):
        progress = progress_for(plan.name(k)) if progress_for else None
        wall, cpu = time.perf_counter(), time.process_time()
        session = plan.record(k, progress)
        done.usage[k]["record"] = usage_since(wall, cpu)
        wall, cpu = time.perf_counter(), time.process_time()
        done.options[k] = plan.analysis_options(k, done.results[:k])
        done.results[k] = plan.analyse(k, session, done.options[k])
        done.sessions[k] = SessionInfo.of(session)
        done.usage[k]["analyse"] = usage_since(wall, cpu)
        del session
        wall, cpu = time.perf_counter(), time.process_time()
        plan.save(k, plan.draw(k, done.results[k]))
        done.usage[k]["figures"] = usage_since(wall, cpu)
    return done


def _handler(plan) -> Callable:
    """The jobs a worker runs for ``plan`` (memory: the sessions and figures it holds)."""

    def handle(memory: dict, kind: str, args: tuple, emit: Callable) -> object:
        if kind == "record":
            (k,) = args
            memory[("session", k)] = plan.record(k, lambda i, total, rec: emit((i, total, rec)))
            return None
        if kind == "analyse":
            k, options = args
            session = memory.pop(("session", k))
            result = plan.analyse(k, session, options)
            figures = plan.draw(k, result)
            memory[("figures", k)] = figures
            return result, SessionInfo.of(session), list(figures)
        if kind == "figures":
            k, result, names = args
            figures = memory.get(("figures", k))
            if figures is None:  # another worker's procedure: drawn here once, for this and the next jobs
                figures = memory[("figures", k)] = plan.draw(k, result)
            plan.save(k, {name: figures.pop(name) for name in names}, workers=1)
            return None
        raise ValueError(f"unknown job {kind!r}")
    return handle


def _in_parallel(plan, progress_for, n_workers: int) -> Done:
    n = len(plan.procs)
    done = Done([None] * n, {}, [None] * n, {k: {} for k in range(n)}, [0.0] * n_workers)
    to_record = deque(sorted(range(n), key=lambda k: -plan.planned_s(k)))  # the longest first
    held: dict[int, int] = {}  # procedure -> worker holding its recorded session
    to_save: dict[int, list[str]] = {}  # procedure -> its figures not saved yet, in order
    drawn: dict[int, set[int]] = {w: set() for w in range(n_workers)}  # worker -> procedures whose figures it holds
    trackers: dict[int, Callable | None] = {}

    def figure_job(w: int) -> tuple | None:
        mine = [k for k in to_save if k in drawn[w]]
        if mine:
            k = mine[0]
        else:  # the others' figures, where enough are left to be worth drawing again
            shared = [k for k in to_save if len(to_save[k]) >= SPLIT_FIGURES]
            if not shared:
                return None
            k = max(shared, key=lambda k: len(to_save[k]))
            drawn[w].add(k)
        name = to_save[k].pop()
        if not to_save[k]:
            del to_save[k]
        return ("figures", k, name), "figures", k, done.results[k], [name]

    def next_job(w: int) -> tuple | None:
        for k in sorted(k for k, holder in held.items() if holder == w):
            if plan.ready(k, done.results[:k]):
                done.options[k] = plan.analysis_options(k, done.results[:k])
                del held[k]
                return ("analyse", k), "analyse", k, done.options[k]
        if to_record:
            k = to_record.popleft()
            trackers[k] = progress_for(plan.name(k)) if progress_for else None
            return ("record", k), "record", k
        return figure_job(w)

    plan.preload()  # imported once here, not once per worker
    with Workers(n_workers, _handler(plan)) as pool:
        while True:
            for w in pool.idle:
                job = next_job(w)
                if job is not None:
                    pool.send(w, *job)
            if not pool.busy:
                break
            kind, w, key, payload = pool.receive()
            k = key[1]
            if kind == "progress":
                if trackers.get(k) is not None:
                    trackers[k](*payload)
                continue
            value, usage = payload
            done.busy_s[w] += usage["wall_s"]
            phase = key[0]
            if phase == "record":
                held[k] = w
            elif phase == "analyse":
                done.results[k], done.sessions[k], names = value
                if names:
                    to_save[k] = list(reversed(names))  # popped from the end: saved in the order drawn
                    drawn[w].add(k)
            if phase == "figures" and "figures" in done.usage[k]:  # another of its figures: add it up
                first = done.usage[k]["figures"]
                usage = {"wall_s": first["wall_s"] + usage["wall_s"], "cpu_s": first["cpu_s"] + usage["cpu_s"],
                         "peak_rss": max(first["peak_rss"], usage["peak_rss"])}
            done.usage[k][phase] = usage
    missing = [plan.name(k) for k in range(n) if done.results[k] is None]
    if missing:  # cannot happen: the first procedure not analysed is always ready
        raise RuntimeError(f"campaign: {', '.join(missing)} not analysed")
    return done
