"""Truth-free quality of a hand-held magnetometer fit, and sigmas from the record's structure along time.

- :func:`holdout_quality`: the figures printed with every hand-held fit (:class:`FreeQuality`): the RMS
  of the calibrated field norm (% of the fitted norm, over all points) and the spread (standard
  deviation, rad) of the field-to-gravity angle (over the points whose specific force is gravity), in
  sample and held out (fitted on the first half in time, judged on the second), for the fit and for a
  plain 10-coefficient algebraic ellipsoid on the same points; and how far the hard iron of the second
  half is from the first's (a board whose field moves during the record is worse held out than any
  constant calibration can help: ``benchmarks/mag_holdout_causes.py`` tests the causes).
- :func:`jackknife_sigmas`: the fit refitted without each of :data:`JACKKNIFE_BLOCKS` contiguous blocks
  in time; each sigma covers the refits' spread (delete-a-block jackknife) and how much the coefficient
  moves from one block to the next beyond the noise (model misfit: a hand-held record's residuals depend
  on where the hand took the unit). The halves of a record are left to validate the sigmas
  (``benchmarks/split_half_z.py``), never to scale them.

Used by :mod:`workbench.analysis.mag_free`. Public: :class:`FitFigures`, :class:`FreeQuality`,
:func:`point_values`, :func:`figures_of`, :func:`halves`, :func:`held_out`, :func:`holdout_quality`,
:func:`own_hard_iron_rms`, :data:`MOVE_Z`, :data:`JACKKNIFE_BLOCKS`, :func:`jackknife_sigmas`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from workbench.analysis import mag_ellipsoid
from workbench.analysis.effective_n import block_jackknife, block_refits
from workbench.analysis.mag_attitude import down_direction
from workbench.analysis.mag_fit import MagFit
from workbench.errors import AnalysisError
from workbench.json_values import json_value


@dataclass(frozen=True)
class FitFigures:
    """Truth-free figures of one calibration on a set of points: field-norm RMS (fraction of the norm)
    and the standard deviation of the field-to-gravity angle (rad), in sample and held out."""

    norm_rms: float
    angle_spread: float
    norm_rms_held_out: float
    angle_spread_held_out: float
    dip: float = float("nan")  # rad, mean of 90° - field-to-gravity angle in sample (> 0: the field points down)

    def to_dict(self) -> dict:
        return {"field_norm_rms_pct": 100 * self.norm_rms, "angle_spread_deg": float(np.degrees(self.angle_spread)),
                "field_norm_rms_pct_held_out": 100 * self.norm_rms_held_out,
                "angle_spread_deg_held_out": float(np.degrees(self.angle_spread_held_out)),
                "dip_deg": float(np.degrees(self.dip)) if np.isfinite(self.dip) else None}


@dataclass(frozen=True)
class FreeQuality:
    """The figures of the fit and of the plain algebraic ellipsoid on the same points (``baseline``,
    None if it fails), the number of points and where the halves split (``split_t`` s)."""

    fit: FitFigures
    baseline: FitFigures | None
    n_points: int
    split_t: float
    notes: tuple[str, ...] = ()
    series: dict | None = None  # per point: t s; norm (fraction) and angle rad (NaN without gravity) per fit
    hard_iron_move: np.ndarray | None = None  # (3,) µT: the second half's hard iron minus the first's (each fitted alone)
    hard_iron_move_sigma: np.ndarray | None = None  # (3,) µT: the halves' sigmas in quadrature
    norm_rms_own_hard_iron: float | None = None  # held-out norm RMS (fraction) with the second half's own hard iron

    def to_dict(self) -> dict:
        move = None if self.hard_iron_move is None else {
            "ut": json_value(self.hard_iron_move), "sigma_ut": json_value(self.hard_iron_move_sigma),
            "field_norm_rms_pct_held_out_own_hard_iron": json_value(100 * self.norm_rms_own_hard_iron)
            if self.norm_rms_own_hard_iron is not None else None}
        return {"fit": self.fit.to_dict(), "plain_ellipsoid": None if self.baseline is None else self.baseline.to_dict(),
                "n_points": self.n_points, "split_t_s": self.split_t, "notes": list(self.notes),
                "hard_iron_move_between_halves": move}

    def lines(self, method: str) -> list[str]:
        """Lines for people (%, °)."""
        def row(name, f):
            return (f"{name}: field-norm RMS {100 * f.norm_rms:.2f} % (held out {100 * f.norm_rms_held_out:.2f} %), "
                    f"field-to-gravity angle spread {np.degrees(f.angle_spread):.2f}° "
                    f"(held out {np.degrees(f.angle_spread_held_out):.2f}°), dip {np.degrees(f.dip):+.1f}°")
        out = [f"hand-held quality, no truth needed ({self.n_points} points fitted; held out = fitted before "
               f"t = {self.split_t:.1f} s, judged after):", "  " + row(method, self.fit)]
        out.append("  " + (row("plain 10-coefficient ellipsoid", self.baseline) if self.baseline is not None
                           else "plain 10-coefficient ellipsoid: " + "; ".join(self.notes)))
        if self.hard_iron_move is not None:
            z = np.abs(self.hard_iron_move) / self.hard_iron_move_sigma
            line = (f"  hard iron of the second half minus the first's (each fitted alone): "
                    f"({', '.join(f'{v:+.2f}' for v in self.hard_iron_move)}) ± "
                    f"({', '.join(f'{v:.2f}' for v in self.hard_iron_move_sigma)}) µT")
            if np.nanmax(z, initial=0.0) > MOVE_Z:
                line += (f", over {MOVE_Z:g} sigma: the field the board carries moved during the record; a calibration "
                         "holds one hard iron, and the held-out figures include the move")
                if self.norm_rms_own_hard_iron is not None:
                    line += (f" (held out with the second half's own hard iron, the first half's soft iron kept: "
                             f"field-norm RMS {100 * self.norm_rms_own_hard_iron:.2f} %, against "
                             f"{100 * self.fit.norm_rms_held_out:.2f} %)")
            out.append(line)
        return out


def point_values(fit: MagFit, mag: np.ndarray, down: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per point: calibrated field norm relative to the fitted norm minus 1 (N,), and the angle (N,) rad
    between the calibrated field and the down direction, for raw points ``mag`` (N, 3) µT and unit down
    directions ``down`` (N, 3), IMU frame."""
    h = fit.compensate(mag)
    hn = np.linalg.norm(h, axis=1)
    return hn / fit.field_norm_ut - 1.0, np.arccos(np.clip(np.sum(h * down, axis=1) / hn, -1.0, 1.0))


def figures_of(fit: MagFit, mag: np.ndarray, down: np.ndarray, gravity_ok: np.ndarray | None = None) -> tuple[float, float]:
    """(field-norm RMS as a fraction of the fitted norm over all points, std of the field-to-gravity angle rad
    over the points whose specific force is gravity, ``gravity_ok`` (N,) bool, default all) of ``fit`` on raw
    points ``mag`` (N, 3) µT with unit down directions ``down`` (N, 3), IMU frame."""
    norm, angle = point_values(fit, mag, down)
    ok = np.ones(len(mag), bool) if gravity_ok is None else gravity_ok
    return float(np.sqrt(np.mean(norm**2))), float(np.std(angle[ok])) if ok.any() else float("nan")


def mean_dip(fit: MagFit, mag: np.ndarray, down: np.ndarray, gravity_ok: np.ndarray) -> float:
    """Dip (rad, > 0 where the field points below the horizontal) of the field ``fit`` calibrates from raw
    points ``mag`` (N, 3) µT: 90° minus the mean angle to the unit down directions ``down`` (N, 3) over the
    points ``gravity_ok`` (N,) bool whose specific force is gravity; NaN without such points."""
    angle = point_values(fit, mag, down)[1][gravity_ok]
    return float(np.pi / 2 - np.mean(angle)) if angle.size else float("nan")


Fitter = Callable[[np.ndarray], MagFit]  # fits the points selected by a (N,) bool mask
MOVE_Z = 4.0  # the halves' hard irons differ "beyond their sigmas" over this many (the tests' 4-sigma level)


def halves(t: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """(median time s, first-half mask, second-half mask) of point times ``t`` (N,) s."""
    split = float(np.median(t))
    return split, t <= split, t > split


def held_out(fitter: Fitter, mag: np.ndarray, down: np.ndarray, gravity_ok: np.ndarray, train: np.ndarray,
             test: np.ndarray) -> tuple[float, float]:
    """:func:`figures_of` on the ``test`` points of a fit to the ``train`` points (masks (N,))."""
    return figures_of(fitter(train), mag[test], down[test], gravity_ok[test])


def holdout_quality(fitter: Fitter, fit: MagFit, mag: np.ndarray, accel: np.ndarray, t: np.ndarray,
                    gravity_ok: np.ndarray) -> FreeQuality:
    """Figures of ``fit`` (fitted on all points) and of ``fitter`` refitted on the first half in time and
    judged on the second; the same for the plain algebraic ellipsoid (see the module docstring); and the hard
    iron of ``fitter`` on the second half minus the first's, with the halves' sigmas in quadrature (None when a
    half does not fit).
    ``mag`` (N, 3) µT, ``accel`` (N, 3) m/s^2, ``t`` (N,) s of the points, ``gravity_ok`` (N,) bool the
    points whose specific force is gravity (the angle is judged on them)."""
    down = down_direction(accel)
    split, first, second = halves(t)
    notes: list[str] = []
    series: dict = {"t": t}

    def figures(name: str, fit_all: MagFit, one: Fitter) -> FitFigures:
        a, b = figures_of(fit_all, mag, down, gravity_ok)
        c, d = held_out(one, mag, down, gravity_ok, first, second)
        norm, angle = point_values(fit_all, mag, down)
        series[f"{name}_norm"], series[f"{name}_angle"] = norm, np.where(gravity_ok, angle, np.nan)
        return FitFigures(a, b, c, d, mean_dip(fit_all, mag, down, gravity_ok))

    ours = figures("fit", fit, fitter)
    try:
        base = figures("plain", mag_ellipsoid.fit_algebraic_plain(mag),
                       lambda sel: mag_ellipsoid.fit_algebraic_plain(mag[sel]))
    except AnalysisError as exc:
        base = None
        notes.append(f"failed ({exc})")
    own = None
    try:
        one, two = fitter(first), fitter(second)
        move, move_sigma = two.bias - one.bias, np.hypot(one.bias_sigma, two.bias_sigma)
        own = own_hard_iron_rms(one, mag[second])
    except AnalysisError:
        move = move_sigma = None
    return FreeQuality(ours, base, len(mag), split, tuple(notes), series, move, move_sigma, own)


def own_hard_iron_rms(fit: MagFit, mag: np.ndarray) -> float:
    """Field-norm RMS (fraction of the fitted norm) of ``fit`` on raw points ``mag`` (N, 3) µT once its hard iron is
    refitted on them (soft iron and norm kept): what a calibration would leave there had its hard iron not moved
    (an oracle: it uses the points it judges)."""
    from scipy.optimize import least_squares

    inverse = np.linalg.inv(fit.field_norm_ut * fit.soft_iron)
    sol = least_squares(lambda b: np.linalg.norm((mag - b) @ inverse.T, axis=1) - 1.0, fit.bias)
    return float(np.sqrt(np.mean(sol.fun ** 2)))



JACKKNIFE_BLOCKS = 5  # contiguous blocks in time of the delete-a-block jackknife (see jackknife_sigmas)


def _vector(bias, soft_iron, field_norm, dip, alignment) -> np.ndarray:
    """Hard iron (3) µT, soft iron (9), field norm µT, dip rad, alignment (3) rad as one vector (NaN for None)."""
    def opt(x, size):
        return np.full(size, np.nan) if x is None else np.atleast_1d(np.asarray(x, float))
    return np.concatenate([bias, np.ravel(soft_iron), [field_norm], opt(dip, 1), opt(alignment, 3)])


def _outputs(fit: MagFit) -> np.ndarray:
    """The fit's coefficients that carry a sigma, as :func:`_vector`."""
    return _vector(fit.bias, fit.soft_iron, fit.field_norm_ut, fit.dip, fit.alignment)


def jackknife_sigmas(fitter: Fitter, fit: MagFit, n: int, blocks: int = JACKKNIFE_BLOCKS) -> MagFit:
    """``fit`` with sigmas from the structure of the record along time: refitted by ``fitter`` without each of
    ``blocks`` contiguous blocks of the ``n`` points (:func:`workbench.analysis.effective_n.block_jackknife`),
    each sigma becomes the largest of the noise model's, the jackknife's ``sigma_J`` and how much the
    coefficient moves from one block to the next beyond the noise ``sigma_B`` (the uncertainty of its value at
    any time of the record; not added to ``sigma_J``, which holds part of the same spread). A
    hand-held record's misfit depends on where the hand took the unit, one stretch of orientations after
    another, and a board's hard iron may move along it: the refits show both, the residuals' correlation
    alone does not. NaN sigmas (not observed) stay NaN; a refit that fails leaves the sigmas as they are."""
    sigma = _vector(fit.bias_sigma, fit.soft_iron_sigma, fit.field_norm_sigma, fit.dip_sigma, fit.alignment_sigma)
    try:
        refits = block_refits(lambda keep: _outputs(fitter(keep)), n, blocks)
    except AnalysisError:
        return fit
    jk, between = block_jackknife(_outputs(fit), refits, np.nan_to_num(sigma))
    new = np.where(np.isfinite(sigma) & np.isfinite(jk), np.fmax(np.fmax(sigma, jk), between), sigma)
    return replace(fit, bias_sigma=new[:3], soft_iron_sigma=new[3:12].reshape(3, 3), field_norm_sigma=float(new[12]),
                   dip_sigma=None if fit.dip_sigma is None else float(new[13]),
                   alignment_sigma=None if fit.alignment_sigma is None else new[14:17])
