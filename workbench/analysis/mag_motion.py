"""A hand-held unit's motion from its own gyro: the magnetometer's time offset, the gyro bias, and gravity
tracked through the motion.

Two things block means of the raw sensors get wrong on a unit tumbled by hand:

1. **Time offset.** The magnetometer's instants are known only up to a constant relative to the IMU's
   (arrival stamps fix each stream's clock up to its smallest latency, :mod:`workbench.importers.clock`;
   a magnetometer value was sensed before the read that delivers it). A late label turns into an angle
   error ``|w| tau`` between field and gravity while the unit turns. The field is constant in the
   navigation frame, so in the body frame ``dh/dt = -(w - b) x h`` (``w`` the gyro, ``b`` its bias; the
   Earth rate, 4e-3 °/s, is left in ``b``). With ``h`` the field of a rough calibration (a plain
   ellipsoid: only the direction matters) and the gyro taken at ``t - tau`` (the value labelled ``t`` was
   sensed at the IMU's ``t - tau``), :func:`fit_timing` finds ``tau`` and ``b`` by least squares on sums
   over non-overlapping :data:`WINDOW_S` windows of ``dh/dt + w x h - b x h`` (linear in ``b``; ``tau``
   by a scan then a bounded search; sigmas from the Gauss-Newton covariance, scaled by the residuals'
   correlation time, :func:`workbench.analysis.effective_n.ess_scale`). Samples whose gyro saturated
   or whose field the import flagged are left out.
2. **Gravity during motion.** The accelerometer sees gravity plus the hand's accelerations (the lever
   arm's centripetal term alone is ``|w|^2 r``: 1.6 m/s^2, 9°, at 4 rad/s and 10 cm). :func:`track_down`
   carries the down direction with the bias-corrected gyro (``dd/dt = -w x d``) and pulls it towards the
   accelerometer's with time constant ``tc`` (a complementary filter), once forward and once backward in
   time; the two are averaged, each weighted by ``1 - exp(-age / tc)`` (``age`` the time since the pass
   started or last restarted). Accelerations that average out over ``tc`` are suppressed; a residual
   gyro bias ``db`` tilts the forward pass by ``+db tc`` and the backward one by ``-db tc``, so it
   cancels to first order in the mean. A pass restarts from the accelerometer at a saturated gyro
   sample (the rate there is not known) and at a gap; a sample counts as tracked when both passes have
   run :data:`SETTLE_TC` time constants since.

Public: :data:`WINDOW_S`, :data:`TRACK_TC_S`, :data:`SETTLE_TC`, :class:`Timing`, :func:`fit_timing`,
:func:`track_down`, :func:`shift`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import polar
from scipy.optimize import minimize_scalar
from scipy.spatial.transform import Rotation

from workbench.analysis.effective_n import ess_scale
from workbench.errors import AnalysisError
from workbench.json_values import json_value

WINDOW_S = 0.1  # s, the windows whose sums carry the rotation constraint
MAX_DELAY_S = 0.08  # s, the offsets searched (either way): several magnetometer periods
TRACK_TC_S = 1.0  # s, time constant of the gravity tracker: hand accelerations average out over it
SETTLE_TC = 1.0  # time constants both passes must have run since a restart for a sample to count as tracked
MIN_WINDOWS = 30  # windows with a valid rotation constraint needed for a timing fit
MAX_GAIN_SIGMA = 0.01  # the gyro's gain matrix is fitted when the field's turns fix every element to 1 %
MAX_BIAS_SIGMA = float(np.radians(2.0))  # rad/s: a bias less well determined than this is not used (x tc: 2° a pass, cancelling in the mean)
GAP_PERIODS = 2.5  # an interval over this many sample periods restarts the tracker


@dataclass(frozen=True)
class Timing:
    """The magnetometer's time offset and the gyro bias seen by the field's rotation.

    ``delay_s`` s: the magnetometer value labelled ``t + delay_s`` was sensed at the IMU's ``t``
    (> 0: the labels are late); ``bias`` (3,) rad/s the gyro bias as the field saw it (in the rough field
    calibration's axes; :meth:`gyro_bias` in the gyro's own); ``gain`` (3, 3) ``K``: the field turns at
    ``K w - b`` for gyro samples ``w`` (identity with NaN ``gain_sigma`` when not fitted); sigmas alike;
    ``n_windows`` the windows fitted; ``rms`` µT/s the rms window residual."""

    delay_s: float
    delay_sigma: float
    bias: np.ndarray
    bias_sigma: np.ndarray
    n_windows: int
    rms: float
    gain: np.ndarray = field(default_factory=lambda: np.eye(3))
    gain_sigma: np.ndarray = field(default_factory=lambda: np.full((3, 3), np.nan))

    @property
    def observes_gain(self) -> bool:
        """Whether the gyro's gain matrix was fitted (else identity, not observed)."""
        return bool(np.isfinite(self.gain_sigma).all())

    def rotation(self) -> np.ndarray:
        """(3, 3) ``R`` of the polar split ``K = R S`` of the gain matrix: the rotation from the gyro's axes to the
        rough field calibration's (its symmetric soft iron leaves the magnetometer-to-IMU rotation in ``R``)."""
        return polar(self.gain, side="right")[0]

    def rate(self, gyro: np.ndarray) -> np.ndarray:
        """Body rate (N, 3) rad/s in the gyro's axes from gyro samples (N, 3) rad/s: the field saw ``K w - b`` in
        its own axes; rotated back by ``R^T``: ``S w - R^T b`` (``S`` the gyro's symmetric gain)."""
        r = self.rotation()
        return gyro @ (r.T @ self.gain).T - self.bias @ r

    def gyro_bias(self) -> np.ndarray:
        """(3,) rad/s the gyro's bias in its own axes, ``K^-1 b``."""
        return np.linalg.solve(self.gain, self.bias)

    @property
    def significant(self) -> bool:
        """Whether the offset differs from zero by more than 3 of its sigmas (then it is corrected)."""
        return abs(self.delay_s) > 3.0 * self.delay_sigma

    def _rotation_deg(self) -> np.ndarray:
        return np.degrees(Rotation.from_matrix(self.rotation()).as_rotvec())

    def describe(self) -> str:
        """One phrase: the offset, bias and gain found and whether the offset was corrected."""
        bias = ", ".join(f"{v:.2f}" for v in np.degrees(self.gyro_bias()))
        sig = ", ".join(f"{v:.2f}" for v in np.degrees(self.bias_sigma))
        act = "corrected" if self.significant else "not significant, left"
        gain = "gyro gain not observed"
        if self.observes_gain:
            s = np.diag(polar(self.gain, side="right")[1])
            gain = (f"gyro scale ({', '.join(f'{100 * (v - 1):+.1f}' for v in s)}) % ± "
                    f"{100 * float(np.nanmax(self.gain_sigma)):.1f} %, field turned against the gyro by "
                    f"({', '.join(f'{v:+.2f}' for v in self._rotation_deg())})° (rotation vector)")
        return (f"magnetometer time offset {1e3 * self.delay_s:+.1f} ± {1e3 * self.delay_sigma:.1f} ms against the "
                f"gyro ({act}), gyro bias ({bias}) ± ({sig}) °/s, {gain}, from the field's rotation "
                f"({self.n_windows} windows of {WINDOW_S * 1e3:g} ms)")

    def to_dict(self) -> dict:
        """JSON-ready: ms, °/s, the gain matrix (None where not observed) and the rotation vector °."""
        return {"mag_delay_ms": 1e3 * self.delay_s, "mag_delay_sigma_ms": 1e3 * self.delay_sigma,
                "corrected": self.significant, "gyro_bias_dps": np.degrees(self.gyro_bias()).tolist(),
                "gyro_bias_sigma_dps": np.degrees(self.bias_sigma).tolist(), "windows": self.n_windows,
                "gyro_gain": self.gain.tolist(), "gyro_gain_sigma": json_value(self.gain_sigma),
                "field_to_gyro_rotation_deg": self._rotation_deg().tolist() if self.observes_gain else None}


def shift(t: np.ndarray, values: np.ndarray, ok: np.ndarray, delay_s: float) -> tuple[np.ndarray, np.ndarray]:
    """``values`` (N, k) re-sampled at ``t + delay_s`` (linear, from the ``ok`` (N,) samples only); returns the
    values and the mask of instants inside the span of the ``ok`` samples."""
    ts = t[ok]
    out = np.column_stack([np.interp(t + delay_s, ts, values[ok, i]) for i in range(values.shape[1])])
    return out, ok & (t + delay_s >= ts[0]) & (t + delay_s <= ts[-1])


def _window_ids(t: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Window number of every sample (-1: a window with an invalid sample or a gap is left out)."""
    period = float(np.median(np.diff(t)))
    w = np.floor((t - t[0]) / WINDOW_S).astype(int)
    bad = ~valid.copy()
    bad[1:] |= np.diff(t) > GAP_PERIODS * period
    bad_w = np.unique(w[bad])
    w[np.isin(w, bad_w)] = -1
    return w


def _sums(x: np.ndarray, w: np.ndarray, n_w: int) -> np.ndarray:
    """Sums of the rows of ``x`` (N, ...) over each window ``w`` (N,) in 0..n_w-1 (rows with w < 0 left out)."""
    ok = w >= 0
    flat = x[ok].reshape(int(ok.sum()), -1)
    out = np.stack([np.bincount(w[ok], weights=flat[:, k], minlength=n_w) for k in range(flat.shape[1])], axis=1)
    return out.reshape((n_w,) + x.shape[1:])


def fit_timing(segments: list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]],
               direction) -> Timing:
    """Fit the magnetometer's time offset and the gyro bias (see the module docstring).

    ``segments``: per contiguous record (one step), ``(t (N,) s, mag (N, 3) µT raw, gyro (N, 3) rad/s,
    valid (N,) bool)``, ``valid`` the samples whose field and rate can be used; ``direction`` maps raw
    magnetometer values (N, 3) to calibrated field vectors (N, 3) µT (e.g. a plain ellipsoid's
    ``compensate``). Raises AnalysisError when too few windows remain or the field did not turn enough
    to determine the bias to :data:`MAX_BIAS_SIGMA`.
    """
    prepared = []
    for t, m, g, ok in segments:
        if len(t) < 10 or ok.sum() < 10:
            continue
        w = _window_ids(t, ok)
        n_w = int(w.max()) + 1 if (w >= 0).any() else 0
        h = direction(m)
        dt = np.gradient(t)[:, None]
        hd = _sums(np.gradient(h, t, axis=0) * dt, w, n_w)
        exh = np.stack([np.cross(np.broadcast_to(e, h.shape), h) * dt for e in np.eye(3)], axis=2)  # (N, 3, i)
        prepared.append((t, g, w, n_w, hd, _sums(exh, w, n_w), exh))
    if sum(p[3] for p in prepared) < MIN_WINDOWS:
        raise AnalysisError(f"magnetometer timing: fewer than {MIN_WINDOWS} windows of {WINDOW_S * 1e3:g} ms "
                            "with a usable field and rate")

    def system(tau: float) -> tuple[np.ndarray, np.ndarray]:
        # the gyro is re-sampled, not the field: interpolating the noisier field would smooth its noise by an
        # amount that depends on tau (least at whole samples) and pull the offset to half a sample
        ys, xs = [], []
        for t, g, w, n_w, hd, cols, exh in prepared:
            if n_w == 0:
                continue
            gs = np.column_stack([np.interp(t - tau, t, g[:, i]) for i in range(3)])
            # w x h = sum_i w_i (e_i x h); the gyro's gain error D (K = I + D) adds (D w) x h = sum_ij D_ij w_j (e_i x h)
            wexh = exh[:, :, :, None] * gs[:, None, None, :]  # (N, 3, i, j)
            sums = _sums(wexh, w, n_w)
            y = hd + np.einsum("nkii->nk", sums)  # µT over the window
            keep = np.any(cols != 0, axis=(1, 2))
            xs.append(np.concatenate([cols, -sums.reshape(n_w, 3, 9)], axis=2)[keep].reshape(-1, 12))
            ys.append(y[keep].ravel())
        return np.concatenate(ys), np.concatenate(xs)

    def solve_at(tau: float, n_par: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        y, x = system(tau)
        x = x[:, :n_par]
        return np.linalg.pinv(x.T @ x) @ (x.T @ y), y, x  # normal equations: at most 12 columns (µT)

    def cost(tau: float, n_par: int) -> float:
        p, y, x = solve_at(tau, n_par)
        return float(np.sum((y - x @ p) ** 2))

    for n_par in (12, 3):  # with the gyro's gain matrix when the field's turns determine it, else the bias alone
        grid = np.arange(-MAX_DELAY_S, MAX_DELAY_S + 1e-9, 0.01)
        k = int(np.argmin([cost(tau, n_par) for tau in grid]))
        lo, hi = grid[max(0, k - 1)], grid[min(len(grid) - 1, k + 1)]
        tau = float(minimize_scalar(cost, bounds=(lo, hi), args=(n_par,), method="bounded",
                                    options={"xatol": 1e-5}).x)
        p, y, x = solve_at(tau, n_par)
        r = y - x @ p
        step = 1e-3
        jt = (cost_residual(system, tau + step, p, n_par) - cost_residual(system, tau - step, p, n_par)) / (2 * step)
        jac = np.column_stack([x, -jt])  # d(residual)/d(p, tau) with residual = y - x p
        s2 = float(r @ r) / max(1, len(r) - n_par - 1)
        cov = s2 * np.linalg.pinv(jac.T @ jac) * float(ess_scale(r.reshape(-1, 3))) ** 2
        sig = np.sqrt(np.abs(np.diag(cov)))
        if n_par == 3 or (np.all(np.isfinite(sig)) and np.all(sig[3:12] < MAX_GAIN_SIGMA)):
            break
    if np.any(sig[:3] > MAX_BIAS_SIGMA) or not np.all(np.isfinite(sig)):
        raise AnalysisError("magnetometer timing: the field did not turn enough to fix the gyro bias "
                            f"(sigma ({', '.join(f'{v:.2f}' for v in np.degrees(sig[:3]))}) °/s)")
    gain = np.eye(3) + (p[3:12].reshape(3, 3) if n_par == 12 else 0.0)
    gain_sigma = sig[3:12].reshape(3, 3) if n_par == 12 else np.full((3, 3), np.nan)
    return Timing(tau, float(sig[-1]), p[:3], sig[:3], len(r) // 3, float(np.sqrt(s2) / WINDOW_S), gain, gain_sigma)


def cost_residual(system, tau: float, p: np.ndarray, n_par: int) -> np.ndarray:
    """Residual ``y - x p`` of ``system(tau)`` (the first ``n_par`` parameters) at fixed ``p``."""
    y, x = system(tau)
    return y - x[:, :n_par] @ p


def track_down(t: np.ndarray, accel: np.ndarray, rate: np.ndarray, restart: np.ndarray,
               tc: float = TRACK_TC_S) -> tuple[np.ndarray, np.ndarray]:
    """Down direction (N, 3) unit, body frame, tracked through the motion, and the (N,) bool mask of the
    samples tracked (see the module docstring).

    ``t`` (N,) s; ``accel`` (N, 3) m/s^2 specific force; ``rate`` (N, 3) rad/s the body rate (the gyro with
    its bias and gain corrected, :meth:`Timing.rate`); ``restart`` (N,) bool the samples whose rate is not known (saturated gyro): a pass
    restarts from the accelerometer there; ``tc`` s the time constant.
    """
    n = len(t)
    dacc = -accel / np.linalg.norm(accel, axis=1, keepdims=True)
    dt = np.diff(t)
    period = float(np.median(dt)) if n > 1 else 0.0
    # interval j (from sample j-1 to j) is not integrated across: a gap, or a rate not known at either end
    broken = np.r_[False, (dt > GAP_PERIODS * period) | restart[:-1] | restart[1:]]

    # rotation of a navigation-fixed vector in the body frame from k to k+1: d_{k+1} = R_k d_k
    steps = Rotation.from_rotvec(-0.5 * (rate[:-1] + rate[1:]) * dt[:, None]).as_matrix() if n > 1 else np.zeros((0, 3, 3))
    gain = np.r_[0.0, np.minimum(1.0, dt / tc)]

    def run(order: np.ndarray, forward: bool) -> tuple[np.ndarray, np.ndarray]:
        d = np.empty((n, 3))
        age = np.zeros(n)
        cur, a = dacc[order[0]].copy(), 0.0
        for i, k in enumerate(order):
            if i:
                j = k if forward else k + 1  # the sample at the end of the interval crossed
                if broken[j]:
                    cur, a = dacc[k].copy(), 0.0
                else:
                    cur = steps[k - 1] @ cur if forward else steps[k].T @ cur
                    a += dt[j - 1]
                    cur += gain[j] * (dacc[k] - cur)
                    cur /= np.linalg.norm(cur)
            d[k], age[k] = cur, a
        return d, age

    idx = np.arange(n)
    df, af = run(idx, True)
    db, ab = run(idx[::-1], False)
    wf, wb = 1.0 - np.exp(-af / tc), 1.0 - np.exp(-ab / tc)
    d = wf[:, None] * df + wb[:, None] * db + 1e-9 * dacc
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return d, (af >= SETTLE_TC * tc) & (ab >= SETTLE_TC * tc)
