"""The table as the reference: true attitude, true body rate and reference gyro bias of a session.

The turntable is the truth of a validation run: the body-to-NED attitude of a sample is
``Rz(table_zero_azimuth + table_angle) @ mount`` (``Session.attitude``) with the table angle
from the encoder column ``table_angle`` (else the step record's start angle plus its rate times
the elapsed time); its angular rate is the Earth rate plus the table rate about the down axis.
Samples between steps (``step = -1``: remounting, moving) belong to the next step's mount.

Public: :class:`TableTruth`, :func:`table_truth`, :func:`reference_gyro_bias`,
:func:`mount_segments`. (The site's declination from the rig configurations is
:func:`workbench.rigsites.declination`: this module reads no fixture file.)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from workbench.earth import earth_rate_ned, rz
from workbench.errors import SessionError
from workbench.session import Session


@dataclass(frozen=True)
class TableTruth:
    """Per-sample truth of rows ``rows`` of a session's samples.

    ``attitude`` Rotation (N,) body-to-NED; ``table_rate`` (N,) rad/s about the down axis;
    ``in_step`` (N,) bool, True for samples labelled with a step (not a transition).
    """

    rows: np.ndarray
    attitude: Rotation
    table_rate: np.ndarray
    in_step: np.ndarray


def _step_of_rows(session: Session, rows: np.ndarray) -> np.ndarray:
    """Step index owning each row: its label, or the next labelled step for transitions (-1)."""
    labels = session.samples["step"].to_numpy()[rows]
    out = labels.copy()
    nxt = -1
    for i in range(len(out) - 1, -1, -1):  # backwards fill of the -1 transitions
        if out[i] >= 0:
            nxt = out[i]
        else:
            out[i] = nxt
    if np.any(out < 0):
        raise SessionError(f"{session.name}: samples after the last step carry no step label")
    return out


def table_truth(session: Session, rows: np.ndarray | slice | None = None,
                table_zero_azimuth: float | None = None) -> TableTruth:
    """True attitude and table rate of the samples ``rows`` (default all).

    ``table_zero_azimuth`` rad overrides the site's (e.g. a north-finding result); SessionError
    when neither is known.
    """
    df = session.samples
    rows = np.arange(len(df))[rows if rows is not None else slice(None)]
    az = session.site.table_zero_azimuth if table_zero_azimuth is None else table_zero_azimuth
    if az is None:
        raise SessionError(f"{session.name}: site.table_zero_azimuth_deg is unknown: pass table_zero_azimuth_deg")
    owner = _step_of_rows(session, rows)
    t = df["t"].to_numpy(float)[rows]
    has_angle, has_rate = "table_angle" in df.columns, "table_rate" in df.columns
    quat = np.empty((len(rows), 4))
    rate = df["table_rate"].to_numpy(float)[rows] if has_rate else np.empty(len(rows))
    for idx in np.unique(owner):
        sel = owner == idx
        st = session.step(int(idx))
        if not has_rate:
            rate[sel] = st.table_rate if st.kind in ("rate", "carousel") else 0.0
        angle = (df["table_angle"].to_numpy(float)[rows[sel]] if has_angle
                 else st.table_angle + rate[sel] * (t[sel] - st.t_start))
        quat[sel] = (rz(az) * session.table_attitude(st, np.asarray(angle)[:, None])).as_quat()
    return TableTruth(rows, Rotation.from_quat(quat), rate, df["step"].to_numpy()[rows] >= 0)


def reference_gyro_bias(gyro: np.ndarray, truth: TableTruth, latitude: float) -> tuple[np.ndarray, np.ndarray]:
    """Gyro bias (3,) rad/s measured against the table, and its 1-sigma (3,).

    The mean over the samples of ``gyro - C_n^b (w_ie + table_rate * down)``: what remains of
    the (compensated or raw) output once the known input is removed. Its sigma is the standard
    error of the mean of 1 s averages (so it holds for white and slowly varying noise alike).
    """
    w_n = earth_rate_ned(latitude) + np.outer(truth.table_rate, [0.0, 0.0, 1.0])
    resid = np.asarray(gyro) - truth.attitude.inv().apply(w_n)
    n = len(resid)
    k = max(1, min(n // 10, 100))  # block means of ~1 s (100 samples), at least 10 blocks
    blocks = resid[: n - n % k].reshape(-1, k, 3).mean(axis=1)
    return resid.mean(axis=0), blocks.std(axis=0, ddof=1) / np.sqrt(len(blocks))


def mount_segments(session: Session) -> list[np.ndarray]:
    """Row indices of the contiguous runs of samples with one mount (transitions join the next step)."""
    rows = np.arange(len(session.samples))
    owner = _step_of_rows(session, rows)
    mounts = {s.index: np.asarray(s.mount) for s in session.steps}
    cuts = [0]
    for i in np.nonzero(np.diff(owner))[0] + 1:
        if not np.allclose(mounts[owner[i]], mounts[owner[i - 1]], atol=1e-9):
            cuts.append(int(i))
    cuts.append(len(rows))
    return [rows[a:b] for a, b in zip(cuts, cuts[1:]) if b > a]
