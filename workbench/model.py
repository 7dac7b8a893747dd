"""The triad error model: one convention for gyro, accelerometer and magnetometer triads.

For a triad with true input ``x`` (rad/s, m/s^2 or µT, body frame), specific force ``f``
(m/s^2, body frame; used by the gyro g-sensitivity only) and unit temperature ``T`` (°C)::

    u        = (I + M(T)) @ x                       linear response (scale factor + misalignment)
    measured = u + n * u**2 + b(T) + G @ f + noise  per-axis quadratic nonlinearity, bias, g-sensitivity

    b(T) = bias + sum_k bias_poly[:, k]  * (T - t_ref)**k        (k = 0, 1, ...)
    M(T) = M    + diag(sum_k scale_poly[:, k] * (T - t_ref)**k)

``M`` holds scale-factor errors on its diagonal and misalignment / non-orthogonality off it.
The nonlinearity acts on the sensor axis's own linear response ``u_i``, so the model has a
closed-form exact inverse (:meth:`TriadModel.compensate`)::

    r = measured - b(T) - G @ f
    u = 2 r / (1 + sqrt(1 + 4 n r))                 (the root of n u^2 + u = r near r)
    x = inv(I + M(T)) @ u

Everything here is SI; the module knows nothing of lab units.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from workbench.errors import CalibrationFormatError

_ZERO3 = np.zeros(3)
# the coefficient arrays of a TriadModel (besides its thermal block), in file and display order
COEFFICIENT_FIELDS = ("bias", "scale_misalignment", "nonlinearity", "g_sensitivity")


def frozen_finite(arr: np.ndarray, name: str, error: type[Exception], what: str = "value") -> np.ndarray:
    """``arr`` made read-only after checking every element is finite; else ``error`` naming ``name``."""
    if not np.all(np.isfinite(arr)):
        raise error(f"{name}: NaN or infinite {what}")
    arr.setflags(write=False)
    return arr


def _array(value, shape: tuple[int, ...], name: str) -> np.ndarray:
    arr = np.array(value, dtype=float)
    if arr.shape != shape:
        raise CalibrationFormatError(f"{name}: expected shape {shape}, got {arr.shape}")
    return frozen_finite(arr, name, CalibrationFormatError, "coefficient")


@dataclass(frozen=True)
class ThermalModel:
    """Temperature dependence of bias and scale factor, polynomials in ``(T - t_ref_c)``.

    ``bias_poly`` and ``scale_poly`` are (3, K) arrays, lowest power first (column k
    multiplies ``(T - t_ref_c)**k``); bias coefficients in the triad's SI unit per °C^k,
    scale-factor coefficients dimensionless per °C^k. Either may have K = 0.
    """

    t_ref_c: float
    bias_poly: np.ndarray = field(default_factory=lambda: np.zeros((3, 0)))
    scale_poly: np.ndarray = field(default_factory=lambda: np.zeros((3, 0)))

    def __post_init__(self) -> None:
        if not np.isfinite(self.t_ref_c):
            raise CalibrationFormatError("thermal.t_ref_c: NaN or infinite")
        for name in ("bias_poly", "scale_poly"):
            arr = np.array(getattr(self, name), dtype=float)
            if arr.ndim != 2 or arr.shape[0] != 3:
                raise CalibrationFormatError(f"thermal.{name}: expected shape (3, K), got {arr.shape}")
            object.__setattr__(self, name, _array(arr, arr.shape, f"thermal.{name}"))

    @staticmethod
    def _poly(coeffs: np.ndarray, dt: np.ndarray) -> np.ndarray:
        """Evaluate per-axis polynomials at temperature offsets ``dt`` (N,) -> (N, 3)."""
        out = np.zeros((3, dt.shape[0]))  # axis by axis: each product runs along the N samples
        for k in range(coeffs.shape[1] - 1, -1, -1):  # Horner, highest power first
            out *= dt
            out += coeffs[:, k, None]
        return out.T.copy()

    def bias_shift(self, temperature_c: np.ndarray) -> np.ndarray:
        """Bias change (N, 3), SI, at unit temperatures ``temperature_c`` (N,) °C."""
        return self._poly(self.bias_poly, np.asarray(temperature_c, float) - self.t_ref_c)

    def scale_shift(self, temperature_c: np.ndarray) -> np.ndarray:
        """Scale-factor change (N, 3), dimensionless, at ``temperature_c`` (N,) °C."""
        return self._poly(self.scale_poly, np.asarray(temperature_c, float) - self.t_ref_c)


@dataclass(frozen=True)
class TriadModel:
    """Deterministic error model of one triad (see the module docstring for the equations).

    Attributes
    ----------
    bias : (3,) SI unit of the triad (rad/s, m/s^2, µT)
    scale_misalignment : (3, 3) ``M``, dimensionless
    nonlinearity : (3,) per-axis quadratic coefficient, 1 / SI unit
    g_sensitivity : (3, 3) or None; gyro only, rad/s per m/s^2
    thermal : ThermalModel or None
    """

    bias: np.ndarray = field(default_factory=lambda: _ZERO3.copy())
    scale_misalignment: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    nonlinearity: np.ndarray = field(default_factory=lambda: _ZERO3.copy())
    g_sensitivity: np.ndarray | None = None
    thermal: ThermalModel | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "bias", _array(self.bias, (3,), "bias"))
        object.__setattr__(self, "scale_misalignment", _array(self.scale_misalignment, (3, 3), "scale_misalignment"))
        object.__setattr__(self, "nonlinearity", _array(self.nonlinearity, (3,), "nonlinearity"))
        if self.g_sensitivity is not None:
            object.__setattr__(self, "g_sensitivity", _array(self.g_sensitivity, (3, 3), "g_sensitivity"))
        a = np.eye(3) + self.scale_misalignment
        cond = np.linalg.cond(a)
        if not np.isfinite(cond) or cond > 1e8:
            raise CalibrationFormatError("scale_misalignment: I + M is singular")

    @property
    def gain(self) -> np.ndarray:
        """``I + M`` at the reference temperature, (3, 3)."""
        return np.eye(3) + self.scale_misalignment

    def _terms(self, n: int, specific_force, temperature_c):
        """Offset (N, 3) = b(T) + G f, and the thermal scale change (N, 3) or None."""
        offset = np.broadcast_to(self.bias, (n, 3)).copy()
        if self.g_sensitivity is not None and specific_force is not None:
            offset += np.asarray(specific_force, float) @ self.g_sensitivity.T
        scale_shift = None
        if self.thermal is not None and temperature_c is not None:
            temperature_c = np.broadcast_to(np.asarray(temperature_c, float), (n,))
            offset += self.thermal.bias_shift(temperature_c)
            if self.thermal.scale_poly.shape[1]:
                scale_shift = self.thermal.scale_shift(temperature_c)
        return offset, scale_shift

    def apply(self, true: np.ndarray, specific_force: np.ndarray | None = None,
              temperature_c: np.ndarray | float | None = None) -> np.ndarray:
        """Noise-free measured output (N, 3) from true input ``true`` (N, 3), body frame, SI.

        ``specific_force`` (N, 3) m/s^2 feeds the g-sensitivity; ``temperature_c`` (N,) or
        scalar °C feeds the thermal terms. Either may be None (term omitted).
        """
        x = np.atleast_2d(np.asarray(true, float))
        offset, scale_shift = self._terms(x.shape[0], specific_force, temperature_c)
        u = x @ self.gain.T
        if scale_shift is not None:
            u += scale_shift * x  # M(T) = M + diag(scale_shift)
        return u + self.nonlinearity * u**2 + offset

    def compensate(self, measured: np.ndarray, specific_force: np.ndarray | None = None,
                   temperature_c: np.ndarray | float | None = None) -> np.ndarray:
        """Exact inverse of :meth:`apply`: true input (N, 3) from measured output (N, 3), SI.

        For a gyro with g-sensitivity, ``specific_force`` should be the compensated
        accelerometer output (m/s^2, body frame).
        """
        y = np.atleast_2d(np.asarray(measured, float))
        offset, scale_shift = self._terms(y.shape[0], specific_force, temperature_c)
        r = y - offset
        n = self.nonlinearity
        if np.any(n):
            disc = 1.0 + 4.0 * n * r
            if np.any(disc < 0):
                raise CalibrationFormatError("nonlinearity: measured value outside the invertible range")
            r = 2.0 * r / (1.0 + np.sqrt(disc))
        if scale_shift is None:
            return np.linalg.solve(self.gain, r.T).T
        gain = np.broadcast_to(self.gain, (y.shape[0], 3, 3)).copy()
        gain[:, [0, 1, 2], [0, 1, 2]] += scale_shift
        return np.linalg.solve(gain, r[..., None])[..., 0]
