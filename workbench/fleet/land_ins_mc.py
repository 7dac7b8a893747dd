"""Sampled Monte Carlo of paper 001 tables 4-1 / 4-2, distributed with Dask, resumable.

One run = one unit drawn from the grade (``draw_unit``: every deterministic error of table 3-1,
bias, scale factor, misalignment, sampled from its 1-sigma), one simulated drive
(:func:`workbench.sim.roads.constant_rate_drive`: pre-calibration, then the cruise at 20 m/s and
a constant heading rate) through the virtual IMU, and one filter run on the raw samples
(:func:`workbench.nav.land_ins.run_land_ins`, told the grade's bias sigmas and noise); its
outcome is the horizontal error at the end against the drive's truth. The paper: 200 runs per
case, CEP = the median of the final horizontal errors.

Each outcome is written to ``out_dir/<grade>/<rate>/run_<k>.json`` as soon as it is known; a
task whose file exists is not run again, so an interrupted Monte Carlo resumes where it stopped.
:func:`monte_carlo` runs the tasks on a Dask client (``workbench.fleet.batch.cluster_client``:
a LocalCluster on 127.0.0.1 or ``tcp://HOST:PORT``) or serially, with a progress callback.

Public: :class:`McCase`, :func:`run_one`, :func:`monte_carlo`, :func:`cep_table`.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterable
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np


@dataclass(frozen=True)
class McCase:
    """One Monte Carlo run: ``grade`` name, ``rate_dps`` heading rate, ``run`` index (the seed),
    ``cruise_s`` and ``precalibration`` of the drive, ``states`` of the filter (20: paper 001's;
    29 / 38 with the scale-factor and misalignment states, :mod:`workbench.nav.land_ins_model`);
    ``in_run_bias_s``: the grade's bias is also drawn anew over that time, in the unit (a rate random
    walk) and in the filter (``grade_errors(..., in_run_bias_s)``); None = a turn-on constant."""

    grade: str
    rate_dps: float
    run: int
    cruise_s: float = 3600.0
    precalibration: bool = True
    states: int = 20
    in_run_bias_s: float | None = None

    def path(self, out_dir: Path) -> Path:
        """Where the outcome of this run is kept (a filter of other than 20 states, an in-run bias in its own folder)."""
        top = Path(out_dir) if self.states == 20 else Path(out_dir) / f"states_{self.states}"
        if self.in_run_bias_s is not None:
            top = top / f"in_run_bias_{self.in_run_bias_s:g}s"
        return top / self.grade / f"{self.rate_dps:g}" / f"run_{self.run:04d}.json"


def run_one(case: McCase) -> dict:
    """Simulate and filter one run; returns ``{case, final_error_m, final_sigma_m, distance_m}``."""
    from workbench.earth import radii
    from workbench.grades import draw_unit, load_spec
    from workbench.nav.compensate import imu_samples
    from workbench.nav.land_ins import LandInsConfig, grade_errors, run_land_ins
    from workbench.nav.land_ins_model import in_run_rrw
    from workbench.session import Site
    from workbench.sim.roads import constant_rate_drive
    from workbench.sim.vehicle import drive, drive_config

    spec = load_spec(case.grade)
    unit = draw_unit(spec, 1000 + case.run)
    if case.in_run_bias_s is not None:  # the in-run share of the bias: a rate random walk of the unit
        unit = replace(unit, **{f"{t}_noise": replace(unit.noise_of(t), rrw=np.hypot(
            unit.noise_of(t).rrw, in_run_rrw(spec.specs[t].bias, case.in_run_bias_s))) for t in ("gyro", "accel")})
    legs = constant_rate_drive(case.rate_dps, 20.0, case.cruise_s, case.precalibration)
    site = Site(40.0, 33.0, 900.0)
    session, truth = drive(drive_config(legs, site, 0.0), unit, 1000 + case.run)
    tr = truth["trajectory"]
    res = run_land_ins(imu_samples(session.samples, session.sample_rate_hz), site.latitude,
                       float(np.radians(site.longitude_deg)), site.height_m, 0.0, grade_errors(spec, in_run_bias_s=case.in_run_bias_s),
                       LandInsConfig(states=case.states))
    k = int(np.searchsorted(tr["t"].to_numpy(), res.t[-1]))
    k = min(k, len(tr) - 1)
    rm, rn = radii(tr["lat"].iloc[k])
    dn = (res.lat[-1] - tr["lat"].iloc[k]) * rm
    de = (res.lon[-1] - tr["lon"].iloc[k]) * rn * np.cos(res.lat[-1])
    return {"case": asdict(case), "final_error_m": float(np.hypot(dn, de)),
            "final_sigma_m": float(np.hypot(res.sigma[-1, 0], res.sigma[-1, 1])),
            "distance_m": float(tr["distance"].iloc[k]),
            "nhc_rejected": float(np.mean(res.weights_min[res.mode == "nhc"] < 1.0)) if np.any(res.mode == "nhc")
            else 0.0}


def _save(case: McCase, out_dir: Path, outcome: dict) -> None:
    from workbench.calset import atomic_write_text

    path = case.path(out_dir)
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_text(path, json.dumps(outcome))


def monte_carlo(cases: Iterable[McCase], out_dir: str | Path, client=None,
                progress: Callable[[int, int], None] | None = None) -> list[dict]:
    """Run every case not yet in ``out_dir`` (on the Dask ``client``, else here) and return all outcomes.

    ``progress(done, total)`` is called after each outcome (the ones found on disk count as done).
    """
    out_dir = Path(out_dir)
    cases = list(cases)
    todo = [c for c in cases if not c.path(out_dir).exists()]
    done = len(cases) - len(todo)
    if progress:
        progress(done, len(cases))
    if client is None:
        for c in todo:
            _save(c, out_dir, run_one(c))
            done += 1
            if progress:
                progress(done, len(cases))
    else:
        from distributed import as_completed

        futures = {client.submit(run_one, c, pure=False): c for c in todo}
        for fut in as_completed(futures):
            _save(futures[fut], out_dir, fut.result())
            done += 1
            if progress:
                progress(done, len(cases))
    return [json.loads(c.path(out_dir).read_text()) for c in cases]


def cep_table(outcomes: list[dict]) -> dict:
    """CEP (median final horizontal error, m), median filter sigma (m) and the number of runs per
    (grade, rate, states, in-run bias); keys ``"<grade> <rate>"`` (20 states, constant bias), with
    ``" s<states>"`` for another filter and ``" b<in_run_bias_s>"`` for an in-run bias."""
    groups: dict = {}
    for o in outcomes:
        c = o["case"]
        key = (c["grade"], c["rate_dps"], int(c.get("states", 20)), c.get("in_run_bias_s"))
        groups.setdefault(key, []).append((o["final_error_m"], o["final_sigma_m"]))
    return {f"{g} {r:g}" + ("" if n == 20 else f" s{n}") + ("" if b is None else f" b{b:g}"):
            {"cep_m": float(np.median([e for e, _ in v])), "sigma_m": float(np.median([s for _, s in v])),
             "runs": len(v)}
            for (g, r, n, b), v in sorted(groups.items(), key=lambda kv: (kv[0][:3], kv[0][3] or 0.0))}
