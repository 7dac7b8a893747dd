"""The magnetometer fit result shared by every estimator, and the helpers they share.

All estimators model the magnetometer as (``workbench.model`` convention)::

    m = (I + M) h + b + noise          m, b in µT (body/sensor frame), |h| = F (field norm, µT)

``b`` is the hard iron, ``A = I + M`` the soft-iron distortion. A fit to field magnitudes
alone observes ``A`` only up to a common scale (``A -> sA`` with ``F -> F/s``). The scale is
fixed either by a reference field norm (the site's field, when the caller gives it) or, by
convention, by ``det(I + M) = 1`` (volume-preserving soft iron, ``F`` the geometric-mean
radius of the ellipsoid); :attr:`MagFit.scale_fixed_by` says which.

Sigmas: ``s^2 inv(J^T J)`` scaled per parameter by the integrated autocorrelation time of its
score series, at least the residuals' own (:mod:`workbench.analysis.effective_n`: 1 for white
residuals, the points' time order).

Robustness (every estimator goes through :func:`solve`): ``robust=True`` fits with a Cauchy
loss whose scale is the residuals' noise (MAD), rejects points beyond 5 robust sigma and refits
by least squares on the rest; ``robust="auto"`` (the procedure's default) fits by least squares
and switches to the robust fit only when the residuals are heavy-tailed (:func:`heavy_tails`).
The rejected points are in :attr:`MagFit.rejected`.

Public: :class:`MagFit`, :func:`gain_to_model`, :func:`lsq_covariance`, :func:`propagate`,
:func:`polar_rotation`, :func:`heavy_tails`, :func:`solve`, :data:`FIELD_RANGE_UT`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import polar
from scipy.spatial.transform import Rotation

from workbench.analysis.effective_n import honest_covariance
from workbench.errors import AnalysisError
from workbench.model import TriadModel

FIELD_RANGE_UT = (15.0, 80.0)  # µT, range of the geomagnetic field magnitude at the Earth's surface
_NAN33 = np.full((3, 3), np.nan)


@dataclass(frozen=True)
class MagFit:
    """A magnetometer calibration: estimates, 1-sigma uncertainties (NaN = not observed), diagnostics.

    Attributes
    ----------
    method : estimator name (``2d``, ``2d-minmax``, ``sphere``, ``ellipsoid``, ``dip``, ``attitude``)
    bias, bias_sigma : (3,) µT, hard iron in the magnetometer axes
    soft_iron, soft_iron_sigma : (3, 3) ``I + M``, dimensionless
    field_norm_ut, field_norm_sigma : fitted field magnitude, µT
    dip, dip_sigma : rad, inclination of the field below the horizontal (None if not estimated)
    declination, declination_sigma : rad, azimuth of the horizontal field clockwise from the
        attitude reference's x axis (true north when the table zero azimuth is known), or None
    alignment, alignment_sigma : (3,) rad, rotation vector of ``U`` in the polar decomposition
        ``I + M = P U`` (``P`` symmetric): the rotation from the IMU axes to the magnetometer
        axes; None when the method cannot observe it (symmetric soft iron by convention)
    residual_rms_ut : RMS of the fit residuals, µT
    n_points : number of points fitted
    scale_fixed_by : ``"reference"`` (given field norm) or ``"det"`` (``det(I + M) = 1``)
    warnings : what the data could not support
    rejected : indices of the points the robust fit left out as outliers
    """

    method: str
    bias: np.ndarray
    bias_sigma: np.ndarray
    soft_iron: np.ndarray
    soft_iron_sigma: np.ndarray
    field_norm_ut: float
    field_norm_sigma: float
    residual_rms_ut: float
    n_points: int
    scale_fixed_by: str
    dip: float | None = None
    dip_sigma: float | None = None
    declination: float | None = None
    declination_sigma: float | None = None
    alignment: np.ndarray | None = None
    alignment_sigma: np.ndarray | None = None
    warnings: tuple[str, ...] = field(default_factory=tuple)
    rejected: tuple[int, ...] = ()

    @property
    def scale_misalignment(self) -> np.ndarray:
        """``M = soft_iron - I`` (3, 3), the calibration-set convention."""
        return self.soft_iron - np.eye(3)

    @property
    def model(self) -> TriadModel:
        """The fit as a :class:`TriadModel` (hard iron = bias, soft iron = I + M)."""
        return TriadModel(bias=self.bias, scale_misalignment=self.scale_misalignment)

    def compensate(self, mag: np.ndarray) -> np.ndarray:
        """Calibrated field (N, 3) µT from raw samples (N, 3) µT: ``inv(I + M) (m - b)``."""
        return self.model.compensate(mag)

    def to_dict(self) -> dict:
        """JSON-ready dict (SI: µT, rad; NaN -> None)."""
        def arr(x):
            if x is None:
                return None
            a = np.asarray(x, float)
            return np.where(np.isfinite(a), a, None).tolist()

        def num(x):
            return None if x is None or not np.isfinite(x) else float(x)

        return {"method": self.method, "bias_ut": arr(self.bias), "bias_sigma_ut": arr(self.bias_sigma),
                "soft_iron": arr(self.soft_iron), "soft_iron_sigma": arr(self.soft_iron_sigma),
                "field_norm_ut": num(self.field_norm_ut), "field_norm_sigma_ut": num(self.field_norm_sigma),
                "dip_rad": num(self.dip), "dip_sigma_rad": num(self.dip_sigma),
                "declination_rad": num(self.declination), "declination_sigma_rad": num(self.declination_sigma),
                "alignment_rotvec_rad": arr(self.alignment), "alignment_sigma_rad": arr(self.alignment_sigma),
                "residual_rms_ut": num(self.residual_rms_ut), "n_points": self.n_points,
                "scale_fixed_by": self.scale_fixed_by, "warnings": list(self.warnings),
                "rejected_points": list(self.rejected)}


def gain_to_model(gain: np.ndarray, field_norm_ut: float | None) -> tuple[np.ndarray, float, str]:
    """Split a unit-field gain ``G`` (``m = G u + b``, ``|u| = 1``) into ``I + M`` and ``F``.

    ``G = F (I + M)``; with a reference ``field_norm_ut`` (µT) ``F`` is that value, otherwise
    ``det(I + M) = 1`` fixes it. Returns ``(I + M, F µT, scale_fixed_by)``.
    """
    if field_norm_ut is not None:
        f = float(field_norm_ut)
        return gain / f, f, "reference"
    f = float(np.cbrt(np.linalg.det(gain)))
    return gain / f, f, "det"


def lsq_covariance(jac: np.ndarray, residuals: np.ndarray, n_fixed: int = 0) -> np.ndarray:
    """Parameter covariance ``s^2 inv(J^T J)`` of a least-squares fit, ``s^2`` from the residuals.

    ``n_fixed`` counts gauge directions (exact degeneracies) removed by the pseudo-inverse.
    Parameters with no information get an infinite variance (reported as not observed).
    """
    dof = max(residuals.size - jac.shape[1] + n_fixed, 1)
    s2 = float(residuals @ residuals) / dof
    jtj = jac.T @ jac
    u, sv, vt = np.linalg.svd(jtj)
    keep = sv > sv[0] * 1e-12
    inv = (vt[keep].T / sv[keep]) @ u[:, keep].T
    cov = s2 * inv
    dead = ~keep
    if dead.any():
        # a direction the data do not constrain: every parameter touching it is unobserved
        touched = np.abs(vt[dead]).max(axis=0) > 1e-6
        cov[touched, :] = np.nan
        cov[:, touched] = np.nan
    return cov


def propagate(fun: Callable[[np.ndarray], np.ndarray], p: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """First-order covariance of ``fun(p)`` (central differences), ``cov`` the covariance of ``p``."""
    y0 = np.asarray(fun(p), float)
    jac = np.empty((y0.size, p.size))
    for i in range(p.size):
        h = 1e-6 * max(1.0, abs(p[i]))
        dp = np.zeros_like(p)
        dp[i] = h
        jac[:, i] = (np.asarray(fun(p + dp), float) - np.asarray(fun(p - dp), float)) / (2 * h)
    with np.errstate(invalid="ignore"):
        out = jac @ np.nan_to_num(cov, nan=0.0) @ jac.T
    unobserved = np.isnan(cov).any(axis=0)
    if unobserved.any():
        bad = np.abs(jac[:, unobserved]).max(axis=1) > 1e-9
        out[bad, :] = np.nan
        out[:, bad] = np.nan
    return out


def polar_rotation(soft_iron: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Polar decomposition ``I + M = P U``: returns (``P`` symmetric (3, 3), rotation vector of ``U`` rad)."""
    u, p = polar(soft_iron, side="left")
    return p, Rotation.from_matrix(u).as_rotvec()


def nan33() -> np.ndarray:
    """A (3, 3) array of NaN (not observed)."""
    return _NAN33.copy()


@dataclass(frozen=True)
class Solution:
    """A least-squares solution: parameters, covariance, residuals (N, k) of the kept points, kept mask."""

    p: np.ndarray
    cov: np.ndarray
    residuals: np.ndarray
    inliers: np.ndarray


REJECT_SIGMA = 5.0  # robust standard deviations beyond which a point is an outlier


def _outliers(r: np.ndarray, reject_sigma: float) -> np.ndarray:
    """Mask (N,) of the points whose residual norm exceeds ``reject_sigma`` robust sigma (MAD) times sqrt(k)."""
    k = r.shape[1]
    sig = 1.4826 * float(np.median(np.abs(r))) if k > 1 else 1.4826 * float(np.median(np.abs(r - np.median(r))))
    return np.linalg.norm(r, axis=1) > reject_sigma * max(sig, 1e-6) * np.sqrt(k)


def heavy_tails(r: np.ndarray, reject_sigma: float = REJECT_SIGMA) -> bool:
    """Whether residuals (N, k) µT have more points beyond ``reject_sigma`` robust sigma than Gaussian
    noise would give: at least 2 points and 0.1 % of them (Gaussian: ~6e-7 of the points at 5 sigma)."""
    n_out = int(_outliers(r, reject_sigma).sum())
    return n_out >= max(2, int(np.ceil(1e-3 * len(r))))


def solve(resid: Callable[[np.ndarray, np.ndarray], np.ndarray], p0: np.ndarray, n_points: int,
          robust: bool | str = False, reject_sigma: float = REJECT_SIGMA,
          prior: Callable[[np.ndarray], np.ndarray] | None = None) -> Solution:
    """Least squares over points: ``resid(p, idx)`` returns the (len(idx), k) residuals (µT) of points ``idx``.

    With ``robust=True``, a Cauchy-loss fit (scale: the residuals' noise) first finds the
    outliers (per-point residual norm above ``reject_sigma`` robust standard deviations, from
    the median absolute deviation); the final fit is plain least squares on the inliers, so its
    covariance is the usual ``s^2 inv(J^T J)``. ``robust="auto"``: least squares, then the
    robust fit if the residuals are heavy-tailed (:func:`heavy_tails`). ``prior(p)`` returns
    residuals in units of their prior 1-sigma (a Gaussian prior); they are weighted against the
    points by the noise level of the residuals at ``p0``.
    """
    from scipy.optimize import least_squares

    if robust not in (True, False, "auto"):
        raise AnalysisError(f"robust={robust!r}: expected true, false or 'auto'")
    idx = np.arange(n_points)
    inliers = np.ones(n_points, bool)
    p = np.asarray(p0, float)
    r0 = resid(p, idx)
    noise = max(1.4826 * float(np.median(np.abs(r0 - np.median(r0)))), 1e-3)

    def full(q, keep):
        r = resid(q, keep).ravel()
        return r if prior is None else np.concatenate([r, noise * prior(q)])

    if robust == "auto":
        sol = least_squares(lambda q: full(q, idx), p, method="lm", x_scale="jac")
        r = resid(sol.x, idx)
        if not heavy_tails(r, reject_sigma):
            return Solution(sol.x, _covariance(sol.jac, r), r, inliers)
    if robust:
        sol = least_squares(lambda q: full(q, idx), p, loss="cauchy", f_scale=noise, x_scale="jac")
        p = sol.x
        inliers = ~_outliers(resid(p, idx), reject_sigma)
    keep = idx[inliers]
    sol = least_squares(lambda q: full(q, keep), p, method="lm", x_scale="jac")
    r = resid(sol.x, keep)
    return Solution(sol.x, _covariance(sol.jac, r), r, inliers)


def _covariance(jac: np.ndarray, r: np.ndarray) -> np.ndarray:
    """:func:`lsq_covariance` scaled per parameter by the integrated autocorrelation time of its score series
    ``J_i r_i`` (at least the residuals' own, the largest of their k columns; 1 for white residuals), so that
    correlated residuals (a hand-held record, a drifting field) do not count as independent points and a smooth
    trajectory's regressors are counted too (:func:`workbench.analysis.effective_n.honest_covariance`). ``r``
    (N, k) in the points' time order."""
    cov = lsq_covariance(jac, r.ravel())
    return honest_covariance(cov, r, jac) if len(r) > 3 else cov


def build_fit(method: str, sol: Solution, unpack: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]],
              field_norm_ut: float | None, observes_rotation: bool, warnings: list[str],
              angles: Callable[[np.ndarray], np.ndarray] | None = None) -> MagFit:
    """Turn a solution into a :class:`MagFit`.

    ``unpack(p) -> (b µT (3,), G (3, 3))`` with ``m = G u + b``, ``|u| = 1``; ``angles(p)`` gives
    ``[dip, declination]`` rad (NaN for one not in the model) when the model has them.
    ``observes_rotation`` says whether the data fix the rotation part of ``I + M`` (attitude-aided
    fits) or it is fixed by convention (symmetric ``I + M``).
    """
    if np.linalg.det(unpack(sol.p)[1]) <= 0:
        raise AnalysisError(f"{method} fit: degenerate solution (I+M not orientation-preserving); "
                            "the data do not support this model")

    def outputs(p):
        b, g = unpack(p)
        a, f, _ = gain_to_model(g, field_norm_ut)
        extra = angles(p) if angles is not None else np.empty(0)
        rot = polar_rotation(a)[1] if observes_rotation else np.empty(0)
        return np.concatenate([b, a.ravel(), [f], extra, rot])

    y = outputs(sol.p)
    var = np.diag(propagate(outputs, sol.p, sol.cov))
    with np.errstate(invalid="ignore"):
        sig = np.sqrt(np.where(var >= 0, var, np.nan))
    b, a, f = y[:3], y[3:12].reshape(3, 3), float(y[12])
    sb, sa, sf = sig[:3], sig[3:12].reshape(3, 3), float(sig[12])
    if field_norm_ut is not None:
        sf = np.nan  # given, not estimated
    n_ang = 0 if angles is None else 2
    ang, sang = y[13:13 + n_ang], sig[13:13 + n_ang]
    rot, srot = (y[13 + n_ang:], sig[13 + n_ang:]) if observes_rotation else (None, None)
    _, _, how = gain_to_model(unpack(sol.p)[1], field_norm_ut)
    if how == "det":
        warnings = [*warnings, "no reference field norm given: the common scale of I+M is fixed by det(I+M) = 1"]

    def opt(i):
        return None if n_ang == 0 or not np.isfinite(ang[i]) else float(ang[i])

    def opt_s(i):
        return None if n_ang == 0 or not np.isfinite(ang[i]) else float(sang[i])

    rms = float(np.sqrt(np.mean(sol.residuals**2))) if sol.residuals.size else float("nan")
    return MagFit(method=method, bias=b, bias_sigma=sb, soft_iron=a, soft_iron_sigma=sa, field_norm_ut=f,
                  field_norm_sigma=sf, residual_rms_ut=rms, n_points=int(sol.inliers.sum()), scale_fixed_by=how,
                  dip=opt(0), dip_sigma=opt_s(0), declination=opt(1), declination_sigma=opt_s(1),
                  alignment=rot, alignment_sigma=srot, warnings=tuple(warnings),
                  rejected=tuple(int(i) for i in np.flatnonzero(~sol.inliers)))
