"""Compiled (numba) solver of the IEEE 952 fit's small problems: non-negative IRLS of a gamma likelihood.

The fit of :mod:`workbench.analysis.allan_fit` solves a few thousand non-negative weighted least-squares
problems per channel (K ~ 10-30 AVAR points, at most 5 unknowns): every grid point of the quantization-ratio
search, at every profile point of every term's interval and in every model of the selection. In numpy each
IRLS step costs ~100 us of call overhead for a few hundred flops; here the whole IRLS runs compiled
(about 1-3 us a step). The algorithms are those the numpy version used, step for step:

* :func:`nnls`: Lawson & Hanson, *Solving Least Squares Problems* (1974), ch. 23 (active set, columns
  scaled to unit peak), tested against scipy.optimize.nnls (tests/analysis/test_small_solvers.py);
* each passive-set solve by Householder QR of the column-equilibrated matrix (:func:`lstsq`; the
  problems are full rank, condition numbers up to ~4e9 measured over the fit's tests);
* :func:`irls`: the identity-link gamma GLM by iteratively reweighted NNLS, each step warm-started on
  the last step's passive set (accepted when it satisfies the Kuhn-Tucker conditions).

Public: :func:`lstsq`, :func:`nnls`, :func:`deviance`, :func:`irls`.
"""

from __future__ import annotations

import numba
import numpy as np

import workbench.analysis.allan_kernels  # noqa: F401  (numba's array registry without scipy's BLAS probe)

_EPS = float(np.finfo(float).eps)


@numba.njit(cache=True, nogil=True)
def _unit_columns(a):  # pragma: no cover - compiled
    """(a with each column divided by its largest magnitude, those magnitudes (n,); 1 for a zero column)."""
    m, n = a.shape
    scale = np.ones(n)
    out = np.empty((m, n))
    for j in range(n):
        peak = 0.0
        for i in range(m):
            peak = max(peak, abs(a[i, j]))
        if peak > 0:
            scale[j] = peak
        for i in range(m):
            out[i, j] = a[i, j] / scale[j]
    return out, scale


@numba.njit(cache=True, nogil=True)
def lstsq(a, b):  # pragma: no cover - compiled
    """argmin ||a x - b||_2 (x (n,)) of a full-rank ``a`` (m, n), m >= n, by Householder QR with the columns
    scaled to unit peak; a column with no component beyond the previous ones gets x = 0."""
    m, n = a.shape
    x = np.zeros(n)
    if n == 0:
        return x
    r, scale = _unit_columns(a)
    peak = 0.0
    for i in range(m):
        peak = max(peak, abs(b[i]))
    if peak == 0.0:
        return x
    qb = b / peak
    v = np.empty(m)
    diag_max = 0.0
    for j in range(n):
        norm = 0.0
        for i in range(j, m):
            norm += r[i, j] * r[i, j]
        norm = np.sqrt(norm)
        if norm == 0.0:
            continue
        alpha = -norm if r[j, j] >= 0 else norm
        vnorm = 0.0
        for i in range(j, m):
            v[i] = r[i, j]
        v[j] -= alpha
        for i in range(j, m):
            vnorm += v[i] * v[i]
        r[j, j] = alpha
        for i in range(j + 1, m):
            r[i, j] = 0.0
        diag_max = max(diag_max, abs(alpha))
        if vnorm == 0.0:
            continue
        for col in range(j + 1, n):
            s = 0.0
            for i in range(j, m):
                s += v[i] * r[i, col]
            s *= 2.0 / vnorm
            for i in range(j, m):
                r[i, col] -= s * v[i]
        s = 0.0
        for i in range(j, m):
            s += v[i] * qb[i]
        s *= 2.0 / vnorm
        for i in range(j, m):
            qb[i] -= s * v[i]
    tiny = _EPS * max(m, n) * diag_max
    for j in range(n - 1, -1, -1):
        if abs(r[j, j]) <= tiny:
            x[j] = 0.0
            continue
        s = qb[j]
        for col in range(j + 1, n):
            s -= r[j, col] * x[col]
        x[j] = s / r[j, j]
    for j in range(n):
        x[j] = x[j] / scale[j] * peak
    return x


@numba.njit(cache=True, nogil=True)
def _solve_on(a, b, passive):  # pragma: no cover - compiled
    """x (n,) with the least-squares solution of ``a[:, passive]`` in the passive entries, 0 elsewhere."""
    idx = np.flatnonzero(passive)
    x = np.zeros(a.shape[1])
    sub = np.empty((a.shape[0], idx.shape[0]))
    for k in range(idx.shape[0]):
        sub[:, k] = a[:, idx[k]]
    z = lstsq(sub, b)
    for k in range(idx.shape[0]):
        x[idx[k]] = z[k]
    return x


@numba.njit(cache=True, nogil=True)
def _matvec(a, x):  # pragma: no cover - compiled
    """a x (a (m, n) or its transpose), without BLAS (numba's matrix products would load scipy's)."""
    out = np.zeros(a.shape[0])
    for i in range(a.shape[0]):
        for j in range(a.shape[1]):
            out[i] += a[i, j] * x[j]
    return out


@numba.njit(cache=True, nogil=True)
def _all_finite(a):  # pragma: no cover - compiled
    for v in a.ravel():
        if not np.isfinite(v):
            return False
    return True


@numba.njit(cache=True, nogil=True)
def nnls(a, b):  # pragma: no cover - compiled
    """argmin ||a x - b||_2 subject to x >= 0: (x (n,), residual norm), as scipy.optimize.nnls.

    ``a`` (m, n), ``b`` (m,), any consistent units; NaN x when ``a`` or ``b`` is not finite.
    """
    m, n = a.shape
    if not (_all_finite(a) and _all_finite(b)):
        return np.full(n, np.nan), np.nan
    # columns scaled to unit peak (x >= 0 is invariant under positive column scales): the noise
    # bases span 20 decades, which would otherwise swamp the gradient test
    an, scale = _unit_columns(a)
    x = np.zeros(n)
    passive = np.zeros(n, np.bool_)
    b_scale = 0.0
    for i in range(m):
        b_scale = max(b_scale, abs(b[i]))
    if b_scale == 0.0:
        return x, 0.0
    bn = b / b_scale  # the problem is homogeneous in b: solved at unit scale, no overflow
    tol = 10.0 * _EPS * max(m, n) ** 2
    w = _matvec(an.T, bn)
    for _ in range(3 * n):
        best, k_best = -np.inf, -1
        for j in range(n):
            if not passive[j] and w[j] > best:
                best, k_best = w[j], j
        if k_best < 0 or not best > tol:
            break
        passive[k_best] = True
        while True:
            z = _solve_on(an, bn, passive)
            ok = True
            for j in range(n):
                if passive[j] and not z[j] > 0:
                    ok = False
            if ok:
                break
            ratio, k_block = np.inf, -1
            for j in range(n):
                if passive[j] and z[j] <= 0:
                    rj = x[j] / (x[j] - z[j])
                    if k_block < 0 or rj < ratio or (np.isnan(rj) and not np.isnan(ratio)):
                        ratio, k_block = rj, j
            x = x + ratio * (z - x)
            for j in range(n):
                passive[j] = passive[j] and x[j] > 0
            passive[k_block] = False  # the blocking variable leaves (no rounding loop)
            for j in range(n):
                if not passive[j]:
                    x[j] = 0.0
        x = z
        w = _matvec(an.T, bn - _matvec(an, x))
    res = (bn - _matvec(an, x))
    return x / scale * b_scale, np.sqrt(np.sum(res * res)) * b_scale


@numba.njit(cache=True, nogil=True)
def deviance(model, avar, edf, correlation):  # pragma: no cover - compiled
    """Gamma deviance sum edf_k (r_k - 1 - ln r_k), r_k = avar_k / model_k, divided by ``correlation``
    (inf unless every model AVAR is > 0): minus twice the log-likelihood, up to a constant, of AVAR points
    ``avar`` (K,) that are scaled chi-squared variables with ``edf`` (K,) degrees of freedom."""
    total = 0.0
    for k in range(model.shape[0]):
        if not model[k] > 0:
            return np.inf
        r = avar[k] / model[k]
        total += edf[k] * (r - 1.0 - np.log(r))
    return total / correlation


@numba.njit(cache=True, nogil=True)
def _nnls_warm(a, b, passive):  # pragma: no cover - compiled
    """argmin ||a x - b||, x >= 0, and its passive set: the unconstrained solution on ``passive`` (the
    last IRLS step's set) when it satisfies the Kuhn-Tucker conditions, else :func:`nnls`."""
    n = a.shape[1]
    if passive.any() and _all_finite(a) and _all_finite(b):
        x = _solve_on(a, b, passive)
        grad = _matvec(a.T, b - _matvec(a, x))
        b_norm = np.sqrt(np.sum(b * b))
        ok = True
        for j in range(n):
            if passive[j]:
                ok = ok and x[j] > 0
            else:
                ok = ok and grad[j] <= 1e-10 * np.sqrt(np.sum(a[:, j] * a[:, j])) * b_norm
        if ok:
            return x, passive
    x = nnls(a, b)[0]
    return x, x > 0


@numba.njit(cache=True, nogil=True)
def irls(cols, offset, start, avar, edf, cutoff, max_iter, step_tol, correlation):  # pragma: no cover - compiled
    """Non-negative c minimising the :func:`deviance` of the model ``offset + cols @ c`` for the AVAR
    points ``avar`` (K,) with ``edf`` (K,), by IRLS from the weights of the model ``start`` (K,):
    (c (p,), model (K,), deviance). ``cols`` (K, p), ``offset`` (K,) in AVAR units.

    At most ``max_iter`` steps; stops when the model moves by less than ``step_tol`` of each point's own
    standard deviation, or when the deviance, extrapolated from its last two decreases (IRLS converges
    linearly), stays above ``cutoff``: such a model is no candidate, and its deviance is returned as it is.
    """
    k_pts, p = cols.shape
    model = start.copy()
    c = np.zeros(p)
    passive = np.zeros(p, np.bool_)
    d3, d2, d1, n_dev = np.inf, np.inf, np.inf, 1  # the last three deviances (the first: inf)
    lhs = np.empty((k_pts, p))
    rhs = np.empty(k_pts)
    for _ in range(max_iter):
        for k in range(k_pts):
            sw = np.sqrt(edf[k]) / max(model[k], 1e-300) if not np.isnan(model[k]) else np.nan
            for j in range(p):
                lhs[k, j] = cols[k, j] * sw
            rhs[k] = (avar[k] - offset[k]) * sw
        new, passive = _nnls_warm(lhs, rhs, passive)
        if not _all_finite(new):
            break
        new_model = offset + _matvec(cols, new)
        step = -np.inf
        lowest = np.inf
        for k in range(k_pts):
            lowest = min(lowest, new_model[k]) if not np.isnan(new_model[k]) else np.nan
            if np.isnan(lowest):
                break
        if lowest > 0:
            for k in range(k_pts):
                s = abs(new_model[k] - model[k]) / (new_model[k] * np.sqrt(2.0 / edf[k]))
                step = max(step, s) if not np.isnan(s) else np.nan
                if np.isnan(step):
                    break
        else:
            step = np.inf
        c, model = new, new_model
        d3, d2, d1 = d2, d1, deviance(model, avar, edf, correlation)
        n_dev += 1
        highest = -np.inf
        for k in range(k_pts):
            highest = max(highest, model[k]) if not np.isnan(model[k]) else np.nan
            if np.isnan(highest):
                break
        if step <= step_tol or not highest > 0:
            break
        if n_dev >= 4 and np.isfinite(d3):
            e1, e2 = d3 - d2, d2 - d1
            rate = e2 / e1 if e1 > 0 else 1.0
            if 0.0 <= rate < 0.9 and d1 - e2 * rate / (1.0 - rate) > cutoff:
                break
    return c, model, d1


@numba.njit(cache=True, nogil=True)
def irls_grid(lead, offsets, free_cols, start, avar, edf, cutoff, lowest, max_iter, step_tol,
              correlation):  # pragma: no cover - compiled
    """:func:`irls` of G models in order, model g with the columns ``lead[g]`` (none when ``lead`` is (G, 0))
    then ``free_cols`` (K, f) and the offset ``offsets[g]`` (K,), each stopped at ``min(cutoff, lowest)`` with
    ``lowest`` lowered to every deviance found: (deviances (G,), coefficients (G, p), models (G, K))."""
    n_grid, k_pts = offsets.shape
    n_lead = 1 if lead.shape[1] > 0 else 0
    p = n_lead + free_cols.shape[1]
    devs = np.empty(n_grid)
    coef = np.empty((n_grid, p))
    models = np.empty((n_grid, k_pts))
    cols = np.empty((k_pts, p))
    cols[:, n_lead:] = free_cols
    for g in range(n_grid):
        if n_lead:
            cols[:, 0] = lead[g]
        c, model, dev = irls(cols, offsets[g], start, avar, edf, lowest if lowest < cutoff else cutoff, max_iter,
                             step_tol, correlation)
        devs[g] = dev
        coef[g] = c
        models[g] = model
        if dev < lowest:
            lowest = dev
    return devs, coef, models
