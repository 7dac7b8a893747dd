"""Road-vehicle aiding data of a drive session: the odometer column and the GPS fixes file.

A drive session (``docs/formats.md``) holds, beside the IMU samples, the odometer's cumulative
distance ``odo_distance`` (m, a samples column) and GPS fixes in ``gps.parquet`` (or
``gps.csv``): ``t`` s (the samples' clock), ``lat``, ``lon`` rad, ``h`` m, optional ``vn``, ``ve``,
``vd`` m/s. Imported drive recordings provide the same files.

Public: ``GPS_FILE``, :func:`gps_fixes`, :func:`odometer_distance`, :func:`thin`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from workbench.errors import SessionError
from workbench.session import Session

GPS_FILE = "gps.parquet"
_GPS_COLUMNS = ("t", "lat", "lon", "h")


def gps_fixes(session: Session) -> pd.DataFrame | None:
    """The session's GPS fixes (t, lat, lon, h[, vn, ve, vd]) sorted by time, or None if it has none."""
    if session.path is None:
        return None
    for name in (GPS_FILE, "gps.csv"):
        p = Path(session.path) / name
        if not p.exists():
            continue
        try:
            df = pd.read_parquet(p) if p.suffix == ".parquet" else pd.read_csv(p)
        except Exception as exc:  # pyarrow / pandas raise many types for unreadable files
            raise SessionError(f"{p}: cannot read GPS fixes ({type(exc).__name__})") from None
        missing = [c for c in _GPS_COLUMNS if c not in df.columns]
        if missing:
            raise SessionError(f"{p}: missing column(s) {', '.join(missing)}")
        values = df[list(_GPS_COLUMNS)].to_numpy(float)
        bad = ~np.isfinite(values)
        if bad.any():
            row, col = np.argwhere(bad)[0]
            raise SessionError(f"{p}: column {_GPS_COLUMNS[col]}: NaN or infinite value at row {row}")
        if np.abs(df["lat"]).max() > np.pi / 2 or np.abs(df["lon"]).max() > 2 * np.pi:
            raise SessionError(f"{p}: columns lat, lon: not radians")
        return df.sort_values("t").reset_index(drop=True)
    return None


def odometer_distance(session: Session) -> np.ndarray:
    """The odometer's cumulative distance (N,) m, or SessionError naming the missing column."""
    if session.samples is None or "odo_distance" not in session.samples.columns:
        raise SessionError(f"{session.name}: samples have no odo_distance column (odometer distance, m)")
    return session.samples["odo_distance"].to_numpy(float)


def thin(x, n: int = 300) -> list:
    """At most ``n`` evenly spaced values of ``x`` as a JSON list (None for non-finite values): the
    series a stored result keeps for the dashboard."""
    x = np.asarray(x, float)
    idx = np.unique(np.linspace(0, len(x) - 1, min(n, len(x))).astype(int)) if len(x) else np.zeros(0, int)
    return [None if not np.isfinite(v) else float(v) for v in x[idx]]
