"""Navigation page section: land navigation on the road (AXD-LNS, paper 001 land INS).

Drawn from stored results only (``Store.list_results``: the ``result.json`` of
``lns-dead-reckoning`` and ``land-ins`` runs, whose ``series`` block holds thinned tracks and
error curves): the trajectory, the error growth after the GPS loss beside the seed's table
values (thesis tables 2.8 / 2.9, Fig. 2.18), the odometer scale-factor estimate, and for the
land INS the horizontal error against the filter's own sigma. Lab units: %, m, km.
"""

from __future__ import annotations

import pandas as pd
import streamlit as st

from dashboard import ui

SEED_NOTE = {"sf_state": "thesis table 2.9 (SF state): max < 1.3 %, mean < 0.6 %",
             "no_sf_state": "thesis table 2.8 (no SF state): max ≈ 5.5 %, mean ≈ 4 %"}


def lns_table(result: dict) -> pd.DataFrame:
    """Seed beside measured: error statistics in % of the distance without GPS, per run and variant."""
    seed = result.get("seed_tables", {})
    rows = []
    for variant, key in (("no_sf_state", "table_2_8_no_sf_state_pct"), ("sf_state", "table_2_9_sf_state_pct")):
        s = seed.get(key, {})
        rows.append({"run": f"seed ({key.split('_pct')[0].replace('_', ' ')})", "variant": variant,
                     **{k: s.get(k) for k in ("max", "mean", "std", "rms", "one_sigma")}})
        for mode in ("raw", "calibrated", "wrong_bias"):
            e = result.get(mode, {}).get(variant, {}).get("error_pct", {})
            rows.append({"run": mode, "variant": variant, **{k: e.get(k) for k in ("max", "mean", "std", "rms",
                                                                                   "one_sigma")}})
    return pd.DataFrame(rows)


def _lns(result: dict) -> None:
    st.dataframe(lns_table(result), hide_index=True, width="stretch")
    series = result.get("series") or {}
    if "track" in series:
        track = pd.DataFrame({"lon_deg": series["track"]["lon_deg"], "lat_deg": series["track"]["lat_deg"],
                              "source": "AXD-LNS (calibrated, SF state)"})
        gps = pd.DataFrame({"lon_deg": series["gps"]["lon_deg"], "lat_deg": series["gps"]["lat_deg"],
                            "source": "GPS (reference after the loss)"})
        st.caption("Trajectory (thesis Fig. 2.16 / 2.19)")
        st.scatter_chart(pd.concat([gps, track]), x="lon_deg", y="lat_deg", color="source", height=320)
    curves = []
    for name, c in series.get("error_pct", {}).items():
        curves.append(pd.DataFrame({"distance_km": [None if d is None else d / 1000 for d in c["distance_m"]],
                                    "error_pct": c["pct"], "run": name}))
    if curves:
        st.caption("Error in % of the distance since the GPS loss (thesis Fig. 2.17 / 2.20); "
                   + "; ".join(SEED_NOTE.values()))
        df = pd.concat(curves).dropna()
        st.line_chart(df[df["error_pct"] < 20], x="distance_km", y="error_pct", color="run", height=300)
    sf = [pd.DataFrame({"t_s": c["t"], "odo_scale_pct": [None if v is None else 100 * v for v in c["value"]],
                        "run": name}) for name, c in series.get("odo_scale", {}).items()]
    if sf:
        st.caption("Odometer scale-factor estimate (thesis Fig. 2.18: ~3.5 % within seconds of the restart; "
                   "the simulated odometer reads +4 %)")
        st.line_chart(pd.concat(sf).dropna(), x="t_s", y="odo_scale_pct", color="run", height=260)


def _land_ins(result: dict) -> None:
    rows = [{"run": m, "final error (m)": b.get("final_error_m"), "% of distance": b.get("final_error_pct_dt"),
             "filter 1-sigma (m)": b.get("final_sigma_m"), "heading change (°)": b.get("heading_change_deg"),
             "ZUPT steps (%)": 100 * b.get("zupt_fraction", 0.0), "NHC steps (%)": 100 * b.get("nhc_fraction", 0.0)}
            for m, b in result.items() if m in ("raw", "calibrated")]
    st.dataframe(pd.DataFrame(rows), hide_index=True, width="stretch")
    st.caption("Paper 001 table 4-1 (CEP after 1 h, 20 m/s): tactical 29 720 m (straight) to 43 m, navigation "
               "grade 1 478 m to 10 m; `benchmarks/seed_tables.py` reproduces the table by covariance analysis.")
    curves = []
    for mode, s in (result.get("series") or {}).items():
        curves.append(pd.DataFrame({"t_s": s["t"], "m": s["sigma_m"], "curve": f"{mode}: filter 1-sigma"}))
        if "error_m" in s:
            curves.append(pd.DataFrame({"t_s": s["t_ref"], "m": s["error_m"], "curve": f"{mode}: error"}))
    if curves:
        st.line_chart(pd.concat(curves).dropna(), x="t_s", y="m", color="curve", height=300)


ROAD = {"lns-dead-reckoning": _lns, "land-ins": _land_ins}  # procedure -> its figures from a result dict


def land_navigation_section() -> None:
    """The land-navigation section of the Navigation page (stored results of both road procedures)."""
    st.header("Land navigation on the road")
    st.caption("Runs: `workbench run lns-dead-reckoning --unit quasi_tactical --rig sim` (thesis ch. 2) and "
               "`workbench run land-ins --unit tactical_low_noise --rig sim` (paper 001).")
    results = []
    with ui.guarded("store"):
        for proc in ("lns-dead-reckoning", "land-ins"):
            results += ui.store().list_results(procedure=proc)
    if not results:
        st.info("No stored land-navigation result yet.")
        return
    labels = {f"{r['procedure']} · {r['serial']} · {r['created']}": r for r in results}
    pick = labels[st.selectbox("Result", list(labels), key="nav.land.result")]
    ROAD[pick["procedure"]](pick["result"])
