"""Speed of the error-model compensation (``TriadModel.compensate``) on long records.

Prints, for 1e6 samples of one triad, the best wall time of the exact inverse of the full
model (bias, ``M``, quadratic nonlinearity; then with a thermal bias and scale polynomial from
a ``temp`` column) and of the plain linear inverse ``(I + M)^-1 (y - b)`` as a matrix product
(what tools that keep only bias and ``M`` do), and the ratio between them. The foundation
issue asks for compensation "well under a second" per 1e6 samples.

    /work/venv/bin/python benchmarks/compensation_speed.py [--samples 1000000] [--repeat 5]
"""

from __future__ import annotations

import argparse
import timeit

import numpy as np

from workbench.model import ThermalModel, TriadModel


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=1_000_000)
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    y = rng.normal(size=(args.samples, 3))
    temp = rng.uniform(-40.0, 85.0, args.samples)
    bias, m = np.array([0.1, 0.2, 0.3]), np.full((3, 3), 1e-3)
    full = TriadModel(bias=bias, scale_misalignment=m, nonlinearity=[1e-4, 0, 0])
    thermal = TriadModel(bias=bias, scale_misalignment=m, nonlinearity=[1e-4, 0, 0],
                         thermal=ThermalModel(25.0, bias_poly=np.full((3, 2), 1e-4),
                                              scale_poly=np.full((3, 1), 1e-6)))
    inv = np.linalg.inv(np.eye(3) + m)

    def best(fn) -> float:
        return min(timeit.repeat(fn, number=1, repeat=args.repeat))

    linear = best(lambda: (y - bias) @ inv.T)
    rows = [("linear inverse (reference)", linear),
            ("full model, exact inverse", best(lambda: full.compensate(y))),
            ("full model + thermal", best(lambda: thermal.compensate(y, temperature_c=temp)))]
    print(f"{args.samples:.0e} samples, best of {args.repeat}")
    print(f"{'path':30s} {'wall s':>8s} {'Msamples/s':>11s} {'x linear':>9s}")
    for name, s in rows:
        print(f"{name:30s} {s:8.3f} {args.samples / s / 1e6:11.1f} {s / linear:9.1f}")


if __name__ == "__main__":
    main()
