"""Sample plots of the dashboard: min/max envelopes of long records and triad charts in lab units.

- :func:`downsample` — min/max envelope of long sample series for responsive plots;
- :func:`samples_chart` — a triad (body frame, lab units) or one column against time.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import streamlit as st

from workbench import units

PLOT_UNITS = {"gyro": (["gx", "gy", "gz"], "deg/s"), "accel": (["ax", "ay", "az"], "mg"),
              "mag": (["mx", "my", "mz"], "uT")}  # sample columns per triad and the lab unit they are plotted in
_OTHER_LABELS = {"temp": "temp (°C)", "table_angle": "table_angle (rad)", "table_rate": "table_rate (rad/s)"}


def downsample(df: pd.DataFrame, x: str = "t", max_points: int = 3000) -> pd.DataFrame:
    """Min/max envelope of every numeric column in ``max_points // 2`` buckets of ``x``.

    Keeps the extremes (spikes, steps) visible while a multi-hour session plots in a fraction
    of a second; returns ``df`` unchanged when it is already short.
    """
    if len(df) <= max_points:
        return df
    n_buckets = max(max_points // 2, 1)
    bucket = (np.arange(len(df)) * n_buckets // len(df))
    num = df.select_dtypes("number")
    g = num.groupby(bucket)
    lo, hi = g.min(), g.max()
    lo[x], hi[x] = g[x].first(), g[x].last()
    return pd.concat([lo, hi]).sort_values(x, kind="stable").reset_index(drop=True)


def samples_chart(df: pd.DataFrame, what: str, height: int = 220) -> None:
    """Line chart of a triad (``gyro``/``accel``/``mag``, body frame, lab units) or a column vs ``t`` (s).

    ``df`` should already be downsampled (:func:`downsample`).
    """
    if what in PLOT_UNITS:
        cols, unit = PLOT_UNITS[what]
        if not all(c in df.columns for c in cols):
            return
        plot = pd.DataFrame(np.asarray(units.to_unit(df[cols].to_numpy(float), unit), float),
                            columns=[f"{c} ({units.label(unit)})" for c in cols])
        st.caption(f"{what} (body frame) vs t (s)")
    else:
        plot = df[[what]].rename(columns={what: _OTHER_LABELS.get(what, what)})
        st.caption(f"{what} vs t (s)")
    plot.index = df["t"].to_numpy()
    st.line_chart(plot, height=height)
