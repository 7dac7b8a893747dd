"""3D magnetometer fits from field magnitudes alone: sphere, ellipsoid, and the plain algebraic baseline.

The raw samples lie on the ellipsoid ``|inv(I + M) (m - b)| = F``. Fitted here:

- :func:`fit_ellipsoid`: a convex algebraic fit guaranteed to be an ellipsoid (the quadric's
  matrix constrained positive definite with cvxpy, on data centred and scaled first), then a
  refinement by least squares on the calibrated field's norm error ``(|B x| - 1) F`` (µT, ``x = m - b``,
  ``B = inv(G)`` symmetric, ``F = det(G)^(1/3)``: the error the quality figures report, every field
  direction weighted alike; the raw-space distance ``(|B x| - 1) / |grad |B x||`` differs from it by
  the local radius over ``F``, i.e. by the soft iron) that
  gives the estimates their covariance; ``robust=True`` rejects outliers first. The
  refinement carries a weak Gaussian prior (1-sigma 10 % per element) on the shape of ``B``
  (``B / det(B)^(1/3) - I``) and, with a reference field norm, on its scale
  (``det(I + M)^(1/3) = 1``): negligible with coverage (data sigma ~0.03 %), it keeps a
  partial-sphere fit from sliding to a huge flat ellipsoid; elements the prior rather than
  the data sets are reported as not observed. Without a reference norm the radius of a
  small cap is not observable and the fit says so through its sigmas.
- :func:`fit_sphere`: hard iron and field norm only (4 parameters), soft iron not observed.
- :func:`fit_algebraic_plain`: the unconstrained 9-parameter algebraic quadric fit of the
  common tools, used as the baseline in tests and benchmarks (no uncertainty).

An ellipsoid fixes ``I + M`` only up to a rotation (``(I + M) R`` fits the same points for
any rotation ``R``): the fits here return the symmetric ``I + M`` (polar factor ``P``). The
attitude-aided fits of :mod:`workbench.analysis.mag_attitude` recover the rotation.

References: paper 004 (shared/seeds/004_...) sec. 4.1-4.3 for hard/soft iron; the ellipsoid
model ``m = (I + M) h + b`` is the workbench error model (``workbench/model.py``).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from workbench.analysis.mag_fit import MagFit, build_fit, gain_to_model, nan33, solve
from workbench.errors import AnalysisError

_IU = np.triu_indices(3)
SOFT_IRON_PRIOR = 0.1  # 1-sigma of each element of the shape of I+M about identity (a few % is typical)


def _centre_scale(mag: np.ndarray) -> tuple[np.ndarray, float, np.ndarray]:
    """Data centred on their mean and scaled to unit RMS radius: (centre µT, scale µT, x)."""
    c = mag.mean(axis=0)
    s = float(np.sqrt(np.mean(np.sum((mag - c) ** 2, axis=1))))
    return c, s, (mag - c) / s


def _quadric_design(x: np.ndarray) -> np.ndarray:
    """Columns x², y², z², 2xy, 2xz, 2yz, x, y, z, 1 of the quadric ``x^T Q x + v^T x + d``."""
    return np.column_stack([x[:, 0]**2, x[:, 1]**2, x[:, 2]**2, 2 * x[:, 0] * x[:, 1], 2 * x[:, 0] * x[:, 2],
                            2 * x[:, 1] * x[:, 2], x, np.ones(len(x))])


def _quadric_to_ellipsoid(q: np.ndarray, v: np.ndarray, d: float) -> tuple[np.ndarray, np.ndarray]:
    """Centre and shape matrix ``E`` (``(x - c)^T E (x - c) = 1``) of a quadric; raises if not an ellipsoid."""
    w = np.linalg.eigvalsh(q)
    if w.min() <= 0:
        raise AnalysisError("ellipsoid fit: the fitted quadric is not an ellipsoid (matrix not positive definite)")
    c = -0.5 * np.linalg.solve(q, v)
    k = float(c @ q @ c - d)
    if k <= 0:
        raise AnalysisError("ellipsoid fit: the fitted quadric is empty (no real points)")
    return c, q / k


def _ellipsoid_to_gain(e: np.ndarray) -> np.ndarray:
    """Symmetric ``G`` with ``G^-T G^-1 = E`` (so ``|inv(G)(x - c)| = 1`` on the ellipsoid)."""
    w, v = np.linalg.eigh(e)
    return (v / np.sqrt(w)) @ v.T


def _sym(p6: np.ndarray) -> np.ndarray:
    s = np.zeros((3, 3))
    s[_IU] = p6
    return s + np.triu(s, 1).T


def algebraic_pd(mag: np.ndarray, robust: bool | str = False) -> tuple[np.ndarray, np.ndarray]:
    """Convex algebraic ellipsoid fit: (centre µT (3,), symmetric gain ``G`` µT (3, 3)).

    Minimises the algebraic residual ``x^T Q x + v^T x + d`` on centred and scaled data
    subject to ``Q >= 1e-3 I`` (positive definite: always an ellipsoid) and ``trace Q = 3``
    (removes the trivial solution); ``robust`` uses the Huber loss.
    """
    import cvxpy as cp  # here, not at import: 0.3-0.5 s (with scipy.stats) that only this fit needs

    c0, s0, x = _centre_scale(mag)
    design = _quadric_design(x)
    q = cp.Variable((3, 3), symmetric=True)
    v = cp.Variable(3)
    d = cp.Variable()
    theta = cp.hstack([q[0, 0], q[1, 1], q[2, 2], q[0, 1], q[0, 2], q[1, 2], v[0], v[1], v[2], d])
    res = design @ theta
    loss = cp.sum(cp.huber(res, 0.05)) if robust else cp.sum_squares(res)
    prob = cp.Problem(cp.Minimize(loss), [q >> 1e-3 * np.eye(3), cp.trace(q) == 3])
    try:
        prob.solve(solver=cp.CLARABEL)
    except cp.SolverError as exc:
        raise AnalysisError(f"ellipsoid fit: the convex solver failed ({exc})") from None
    if q.value is None:
        raise AnalysisError(f"ellipsoid fit: the convex problem is {prob.status}")
    c, e = _quadric_to_ellipsoid(q.value, v.value, float(d.value))
    return c0 + s0 * c, s0 * _ellipsoid_to_gain(e)


def fit_ellipsoid(mag: np.ndarray, field_norm_ut: float | None = None, robust: bool | str = False,
                  warnings: tuple[str, ...] = ()) -> MagFit:
    """Hard iron, symmetric soft iron and field norm from samples on a (part of an) ellipsoid.

    Parameters
    ----------
    mag : (N, 3) µT, raw magnetometer samples (magnetometer axes)
    field_norm_ut : reference field magnitude µT (fixes the common scale of ``I + M``), or None
    robust : reject outliers (spikes) before the final least-squares fit
    """
    c, g = algebraic_pd(mag, robust)
    b_inv = np.linalg.inv(g)
    p0 = np.concatenate([c, b_inv[_IU]])

    def resid(p, idx):
        b = _sym(p[3:])
        u = (mag[idx] - p[:3]) @ b  # B symmetric: u = B (m - c)
        nu = np.linalg.norm(u, axis=1)
        # the calibrated field's norm error in µT: (|u| - 1) F, F = det(G)^(1/3) = det(B)^(-1/3)
        return ((nu - 1.0) / np.cbrt(np.linalg.det(b)))[:, None]

    def prior(p):
        b = _sym(p[3:])
        scale = np.cbrt(np.linalg.det(b))
        shape = (b / scale - np.eye(3))[_IU] / SOFT_IRON_PRIOR
        if field_norm_ut is None:
            return shape
        return np.append(shape, (scale * field_norm_ut - 1.0) / SOFT_IRON_PRIOR)  # det(I+M)^(1/3) ~ 1

    sol = solve(resid, p0, len(mag), robust, prior=prior)
    notes = list(warnings)
    if robust and (~sol.inliers).any():
        notes.append(f"robust fit: {int((~sol.inliers).sum())} of {len(mag)} points rejected as outliers")
    fit = build_fit("ellipsoid", sol, lambda p: (p[:3], np.linalg.inv(_sym(p[3:]))), field_norm_ut,
                    observes_rotation=False, warnings=notes)
    weak = fit.soft_iron_sigma > 0.5 * SOFT_IRON_PRIOR  # the prior, not the data, sets these elements
    if weak.any():
        return replace(fit, soft_iron_sigma=np.where(weak, np.nan, fit.soft_iron_sigma),
                       warnings=(*fit.warnings, f"{int(weak.sum())} soft-iron element(s) not observed by the data "
                                                "(held near identity by the prior)"))
    return fit


def fit_sphere(mag: np.ndarray, field_norm_ut: float | None = None, robust: bool | str = False,
               warnings: tuple[str, ...] = ()) -> MagFit:
    """Hard iron and field norm only (``|m - b| = F``); soft iron is not observed (NaN sigma).

    With a reference ``field_norm_ut`` the fitted radius becomes a common scale ``I + M = (F_fit / F_ref) I``.
    """
    c0 = mag.mean(axis=0)
    p0 = np.concatenate([c0, [np.mean(np.linalg.norm(mag - c0, axis=1))]])

    def resid(p, idx):
        return (np.linalg.norm(mag[idx] - p[:3], axis=1) - p[3])[:, None]

    sol = solve(resid, p0, len(mag), robust)
    fit = build_fit("sphere", sol, lambda p: (p[:3], p[3] * np.eye(3)), field_norm_ut,
                    observes_rotation=False, warnings=[*warnings, "sphere model: soft iron not estimated"])
    sig = nan33()
    if field_norm_ut is not None:
        np.fill_diagonal(sig, np.sqrt(sol.cov[3, 3]) / field_norm_ut)
    return replace(fit, soft_iron_sigma=sig)


def fit_algebraic_plain(mag: np.ndarray, field_norm_ut: float | None = None) -> MagFit:
    """Baseline: unconstrained algebraic quadric fit ``x^T Q x + v^T x = 1`` (9 parameters, linear least squares).

    What common tools do; no positive-definite guarantee (raises AnalysisError if the result
    is not an ellipsoid) and no uncertainty (NaN sigmas).
    """
    c0, s0, x = _centre_scale(mag)
    design = _quadric_design(x)[:, :9]
    theta = np.linalg.lstsq(design, np.ones(len(x)), rcond=None)[0]
    c, e = _quadric_to_ellipsoid(_sym(theta[[0, 3, 4, 1, 5, 2]]), theta[6:9], -1.0)
    g = s0 * _ellipsoid_to_gain(e)
    a, f, how = gain_to_model(g, field_norm_ut)
    b = c0 + s0 * c
    h = (mag - b) @ np.linalg.inv(a).T
    rms = float(np.sqrt(np.mean((np.linalg.norm(h, axis=1) - f) ** 2)))
    return MagFit("algebraic", b, np.full(3, np.nan), a, nan33(), f, float("nan"), rms, len(mag), how,
                  warnings=("plain algebraic baseline: no uncertainty estimated",))
