"""Split-half z-scores of every coefficient on a recorded session: are the sigmas honest on real data?

The session is cut in two halves in time: every step whose data can be cut (static holds,
free motion) keeps its first half in A and its second half in B; a step that must stay whole
(a turn, an index move) goes whole into both (its coefficients are then not independent between
A and B and are left out: ``--shared``). Both halves are analysed by the same procedure and
each coefficient that both observe gives ``z = (x_A - x_B) / sqrt(s_A² + s_B²)``. With honest
sigmas z is N(0, 1): rms z ~ 1 (target <= 1.5 on real recordings, issue 21 item 6).

    python benchmarks/split_half_z.py SESSION_DIR --procedure ferraris
    python benchmarks/split_half_z.py runs/imucal --procedure ferraris -o position_sigma_deg=auto

Prints one row per coefficient (value in lab units, both halves, z) and the rms per triad and
over all.
"""

from __future__ import annotations

import argparse
import json
from dataclasses import replace

import numpy as np

CUTTABLE = ("static", "free", "soak")
# coefficients fitted from steps that stay whole in both halves (turns): not independent
SHARED = {"ferraris": ("gyro.scale_misalignment", "gyro.nonlinearity"),
          "multiposition": (), "magnetometer": ()}


def halves(session):
    """Two sessions: the first and the second half in time of every cuttable step (others whole in both)."""
    df = session.samples
    keep_a = np.zeros(len(df), bool)
    keep_b = np.zeros(len(df), bool)
    steps_a, steps_b = [], []
    t = df["t"].to_numpy(float)
    lab = df["step"].to_numpy()
    for st in session.steps:
        rows = lab == st.index
        if st.kind not in CUTTABLE:
            keep_a |= rows
            keep_b |= rows
            steps_a.append(st)
            steps_b.append(st)
            continue
        tt = t[rows]
        if len(tt) < 4:
            continue
        mid = 0.5 * (tt[0] + tt[-1])
        keep_a |= rows & (t < mid)
        keep_b |= rows & (t >= mid)
        steps_a.append(replace(st, t_end=float(mid)))
        steps_b.append(replace(st, t_start=float(mid)))
    a = replace(session, steps=steps_a, samples=df[keep_a].reset_index(drop=True), id=session.id + "-A")
    b = replace(session, steps=steps_b, samples=df[keep_b].reset_index(drop=True), id=session.id + "-B")
    return a, b


def coefficients(cal):
    """(triad, field, index, value SI, sigma SI) of every observed coefficient of a set."""
    out = []
    for triad, tc in cal.triads.items():
        m = tc.model
        fields = {"bias": m.bias, "scale_misalignment": m.scale_misalignment, "nonlinearity": m.nonlinearity,
                  "g_sensitivity": m.g_sensitivity}
        for name, arr in fields.items():
            if arr is None:
                continue
            sig = tc.sigma_of(name)
            for idx in np.ndindex(np.shape(arr)):
                if np.isfinite(sig[idx]) and sig[idx] > 0:
                    out.append((triad, name, idx, float(arr[idx]), float(sig[idx])))
        if tc.field_norm_ut is not None and tc.field_norm_ut_sigma is not None and np.isfinite(tc.field_norm_ut_sigma):
            out.append((triad, "field_norm", (), float(tc.field_norm_ut), float(tc.field_norm_ut_sigma)))
    return out


def split_half_z(session, proc, options: dict, shared=()) -> list[tuple]:
    """Rows (name, unit, value_A, value_B, sigma_A, sigma_B, z) of the coefficients both halves observe."""
    from workbench import units

    a, b = halves(session)
    ca = {(t, f, i): (v, s) for t, f, i, v, s in coefficients(proc.analyze(a, **options).calibration)}
    cb = {(t, f, i): (v, s) for t, f, i, v, s in coefficients(proc.analyze(b, **options).calibration)}
    rows = []
    for key in ca.keys() & cb.keys():
        triad, field, idx = key
        if f"{triad}.{field}" in shared:
            continue
        (va, sa), (vb, sb) = ca[key], cb[key]
        q = "field_norm" if field == "field_norm" else units.field_quantity(field, idx)
        unit = units.unit_of(triad, q)
        rows.append((f"{triad} {field}{list(idx) if idx else ''}", unit, va, vb, sa, sb,
                     (va - vb) / np.hypot(sa, sb)))
    return sorted(rows)


def main(argv: list[str] | None = None) -> int:
    from workbench.registry import procedure
    from workbench.session import load_session

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("session")
    ap.add_argument("--procedure", required=True)
    ap.add_argument("-o", "--option", action="append", default=[], help="analysis option key=value (JSON value)")
    ap.add_argument("--json", action="store_true", help="print the rows as JSON")
    args = ap.parse_args(argv)
    options = {}
    for item in args.option:
        k, v = item.split("=", 1)
        try:
            options[k] = json.loads(v)
        except json.JSONDecodeError:
            options[k] = v
    proc = procedure(args.procedure)
    session = load_session(args.session)
    rows = split_half_z(session, proc, options, SHARED.get(proc.NAME, ()))
    if args.json:
        print(json.dumps([dict(zip(("name", "unit", "a", "b", "sigma_a", "sigma_b", "z"), r)) for r in rows]))
        return 0
    from workbench import units

    print(f"{'coefficient':28s} {'first half':>24s} {'second half':>24s} {'z':>7s}")
    for name, unit, va, vb, sa, sb, z in rows:
        f = units.factor(unit)
        lab = units.label(unit)
        print(f"{name:28s} {va / f:11.4g} ± {sa / f:<9.2g} {vb / f:11.4g} ± {sb / f:<9.2g} {z:+7.2f}  {lab}")
    z = np.array([r[-1] for r in rows])
    for triad in sorted({r[0].split()[0] for r in rows}):
        zt = np.array([r[-1] for r in rows if r[0].startswith(triad + " ")])
        print(f"{triad}: {len(zt)} coefficients, rms z {np.sqrt(np.mean(zt ** 2)):.2f}, max |z| {np.abs(zt).max():.2f}")
    shared = SHARED.get(proc.NAME, ())
    print(f"all: {len(z)} coefficients, rms z {np.sqrt(np.mean(z ** 2)):.2f}, max |z| {np.abs(z).max():.2f}"
          + (f" (left out, shared whole steps: {', '.join(shared)})" if shared else ""))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
