"""The virtual IMU: true body motion, field and temperature -> sensor samples.

For each triad, in this order (all SI, body frame)::

    clean  = TriadModel.apply(true, f, T)         deterministic errors (workbench/model.py);
                                                   the gyro g-sensitivity is fed the true specific force
    clean += gap / 2 * s(T)                       optional thermal bias hysteresis (grades.Hysteresis)
    y      = clean + white + flicker + rate RW    workbench/sim/noise.py (IEEE 952 terms)
    y      = quantize(y)                          integrated-output quantization, then output LSB
    y      = clip(y, -range, +range)              saturation at the full scale

With :class:`~workbench.sim.imperfections.Imperfections` (off by default), before the noise:
``clean = (I + dM_on + r t) clean + b_on + b_w exp(-t / tau)`` (turn-on scale factor, its drift
within the run, turn-on bias, warm-up transient), and the noise is scaled by ``1 + c (T - t_ref)``.

The unit's thermometer reads ``T + N(0, temp_sensor_noise_c²)``.

:class:`VirtualIMU` is stateful: consecutive :meth:`VirtualIMU.measure` calls continue the
noise processes, so a recording made step by step is sample-for-sample identical to one
made in a single call with the same seed.
"""

from __future__ import annotations

import numpy as np

from workbench.errors import WorkbenchError
from workbench.grades import Hysteresis, UnitTruth
from workbench.sim.noise import IntegratedQuantizer, NoiseProcess, round_to_resolution

_BLOCK = 1 << 15  # samples per internal block (cache-friendly; the output does not depend on it)


class _PlayOperator:
    """Stateful play (backlash) operator of width ``width_c`` on the temperature (°C)."""

    def __init__(self, width_c: float) -> None:
        self.width_c = width_c
        self.point: float | None = None

    def branch(self, temp_c: np.ndarray) -> np.ndarray:
        """Branch variable s in [-1, 1] for each temperature sample (N,)."""
        w = self.width_c
        p = float(temp_c[0]) if self.point is None else self.point
        points = np.empty(temp_c.size)
        for k, t in enumerate(temp_c.tolist()):
            p = min(max(p, t - w), t + w)
            points[k] = p
        self.point = p
        return (temp_c - points) / w


class VirtualIMU:
    """A simulated unit producing samples at ``truth.sample_rate_hz``.

    Parameters
    ----------
    truth : UnitTruth, the unit's true error model, noise terms and ranges
    seed : seed of the noise (independent of the seed the unit was drawn with)
    imperfections : :class:`~workbench.sim.imperfections.Imperfections` or None (none)
    """

    def __init__(self, truth: UnitTruth, seed: int, imperfections=None) -> None:
        self.truth = truth
        self.imperfections = imperfections
        self._k = 0  # samples produced since power-on
        if imperfections is not None:
            self._on_bias, self._on_scale, self._scale_rate = imperfections.draw(tuple(truth.triads), seed)
            self._warm = imperfections.vector("warm_up_bias", tuple(truth.triads))
            self._noise_tc = imperfections.vector("noise_temp_coeff", tuple(truth.triads))
        self.dt = 1.0 / truth.sample_rate_hz
        noise_seed, temp_seed = np.random.SeedSequence(seed).spawn(2)
        noises = [truth.noise_of(t) for t in truth.triads]
        stack = {name: np.concatenate([getattr(n, name) for n in noises])
                 for name in ("white", "bias_instability", "rrw", "quantization", "resolution")}
        self._noise = NoiseProcess(stack["white"], stack["bias_instability"], stack["rrw"], self.dt, noise_seed)
        self._quantizer = IntegratedQuantizer(stack["quantization"], self.dt)
        self._resolution = stack["resolution"]
        self._range = np.repeat([truth.range_of(t) for t in truth.triads], 3)
        self._temp_rng = np.random.default_rng(temp_seed)
        self._play: dict[str, tuple[Hysteresis, _PlayOperator]] = {
            t: (h, _PlayOperator(h.width_c)) for t in truth.triads if (h := truth.hysteresis_of(t)) is not None}

    def measure(self, omega_b: np.ndarray, f_b: np.ndarray, m_b: np.ndarray | None,
                temp_c: np.ndarray) -> dict[str, np.ndarray | None]:
        """Samples for the next ``N`` sample instants.

        Parameters
        ----------
        omega_b : (N, 3) true angular rate of the body w.r.t. inertial space, body frame, rad/s
        f_b : (N, 3) true specific force, body frame, m/s^2
        m_b : (N, 3) true magnetic field, body frame, µT, or None (required if the unit has a mag)
        temp_c : (N,) true unit temperature, °C

        Returns
        -------
        dict with ``gyro`` (N, 3) rad/s, ``accel`` (N, 3) m/s^2, ``mag`` (N, 3) µT or None,
        ``temp`` (N,) °C (the unit's own thermometer).
        """
        omega_b = np.asarray(omega_b, float)
        n = omega_b.shape[0]
        temp_c = np.broadcast_to(np.asarray(temp_c, float), (n,))
        inputs = {"gyro": omega_b, "accel": np.asarray(f_b, float), "mag": m_b}
        for name in self.truth.triads:
            value = inputs[name]
            if value is None:
                raise WorkbenchError(f"VirtualIMU.measure: {name}: the unit has a {name} triad but no true input")
            if np.shape(value) != (n, 3):
                raise WorkbenchError(f"VirtualIMU.measure: {name}: expected shape ({n}, 3), got {np.shape(value)}")
        y, thermometer = np.empty((n, 3 * len(self.truth.triads))), np.empty(n)
        for a in range(0, n, _BLOCK):
            y[a:a + _BLOCK], thermometer[a:a + _BLOCK] = self._measure_block(
                {k: None if v is None else v[a:a + _BLOCK] for k, v in inputs.items()}, temp_c[a:a + _BLOCK])
        result: dict[str, np.ndarray | None] = {"mag": None}
        for i, name in enumerate(self.truth.triads):
            result[name] = y[:, 3 * i:3 * i + 3]
        result["temp"] = thermometer
        return result

    def _measure_block(self, inputs: dict, temp_c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Outputs (n, 3 * triads) and thermometer readings (n,) of one block of samples."""
        n = temp_c.size
        clean = []
        for name in self.truth.triads:
            force = inputs["accel"] if name == "gyro" else None
            out = self.truth.model_of(name).apply(inputs[name], force, temp_c)
            if name in self._play:
                hyst, play = self._play[name]
                out = out + 0.5 * play.branch(temp_c)[:, None] * hyst.gap
            clean.append(out)
        clean = np.hstack(clean)
        noise = self._noise.generate(n)
        imp = self.imperfections
        if imp is not None:
            t = (self._k + np.arange(n)) * self.dt
            scale = 1.0 + self._on_scale + (t[:, None] * self._scale_rate if self._scale_rate.any() else 0.0)
            clean = clean * scale + self._on_bias + np.exp(-t / imp.warm_up_tau_s)[:, None] * self._warm
            noise = noise * (1.0 + np.outer(temp_c - imp.noise_t_ref_c, self._noise_tc))
        self._k += n
        noise += clean  # the output before quantization and saturation
        y = round_to_resolution(self._quantizer.apply(noise), self._resolution)
        np.clip(y, -self._range, self._range, out=y)
        return y, temp_c + self.truth.temp_sensor_noise_c * self._temp_rng.standard_normal(n)

    def state(self) -> dict:
        """JSON-ready state of every noise process and memory, so a resumed recording can
        continue exactly where an interrupted one stopped (:meth:`restore`)."""
        return {"noise": self._noise.state(), "quantizer": self._quantizer.state(),
                "temp_rng": self._temp_rng.bit_generator.state,
                "play": {t: play.point for t, (_, play) in self._play.items()}, "k": self._k}

    def restore(self, state: dict) -> None:
        """Continue from a :meth:`state` of a VirtualIMU of the same unit."""
        try:
            self._noise.restore(state["noise"])
            self._quantizer.restore(state["quantizer"])
            self._temp_rng.bit_generator.state = state["temp_rng"]
            for triad, point in state["play"].items():
                self._play[triad][1].point = point
            self._k = int(state.get("k", 0))
        except (KeyError, ValueError, TypeError) as exc:
            raise WorkbenchError(f"VirtualIMU.restore: state does not match unit {self.truth.serial} ({exc})") from None
