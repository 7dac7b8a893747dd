"""Order selection of the thermal polynomials against the truth (slow; not a test).

Seven soaks at -10..50 °C (the campaign's sweep), ``--units`` simulated scale-factor curves:
per axis a linear and a quadratic term drawn at the industrial-MEMS spread (100 ppm/°C,
1 ppm/°C²), plus a cubic 2e-7 /°C³ on x (5400 ppm at the ends), and ``--sigma`` ppm of white
noise on each soak value. ``fit_thermal_poly`` chooses each axis's order; printed: the
orders chosen on the quadratic axes (y, z), how often the cubic x axis is under-fitted, the
rms error of the fitted curve against the truth over -10..50 °C (mean and 95th percentile
over the units), and the rms z-score of the value at t_ref (estimate - truth over its sigma).

Usage: python benchmarks/thermal_order.py [--units 300] [--sigma 40] [--seed 5]
"""

from __future__ import annotations

import argparse

import numpy as np

from workbench.analysis.thermal_poly import fit_thermal_poly

TEMPS = np.arange(-10.0, 51.0, 10.0)  # °C, the campaign's soak setpoints
T_REF, T_FIT_REF = 25.0, 23.0  # °C, the truth's and the fit's reference temperatures


def main() -> None:
    """Run the sweep and print the table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--units", type=int, default=300)
    ap.add_argument("--sigma", type=float, default=40.0, help="soak noise, ppm")
    ap.add_argument("--seed", type=int, default=5)
    a = ap.parse_args()
    rng = np.random.default_rng(a.seed)
    sigma = a.sigma * 1e-6
    grid = np.linspace(-10.0, 50.0, 61)
    counts: dict[int, int] = {}
    under, errors, z = 0, [], []
    for _ in range(a.units):
        coef = np.column_stack([rng.normal(0, 1e-4, 3), rng.normal(0, 1e-6, 3), [2e-7, 0.0, 0.0]])

        def truth(t: np.ndarray) -> np.ndarray:
            d = (t - T_REF)[:, None]
            return coef[:, 0] * d + coef[:, 1] * d**2 + coef[:, 2] * d**3

        y = truth(TEMPS) + rng.normal(0.0, sigma, (len(TEMPS), 3))
        fit = fit_thermal_poly(TEMPS, y, np.full(y.shape, sigma), t_ref_c=T_FIT_REF, quantity="accel.scale")
        for k in fit.orders[1:]:
            counts[int(k)] = counts.get(int(k), 0) + 1
        under += int(fit.orders[0] < 3)
        errors.append(np.sqrt(np.mean((fit.predict(grid) - truth(grid)) ** 2, axis=0)))
        z.append((fit.coeffs[:, 0] - truth(np.array([T_FIT_REF]))[0]) / fit.coeffs_sigma[:, 0])
    e, z = np.array(errors) * 1e6, np.array(z)
    print(f"{a.units} units, 7 soaks, {a.sigma:g} ppm per soak")
    print("orders chosen on the quadratic axes (y, z):",
          ", ".join(f"{k}: {n}" for k, n in sorted(counts.items())),
          f"(above 2: {sum(n for k, n in counts.items() if k > 2)} of {2 * a.units})")
    print(f"cubic x axis under-fitted: {under} of {a.units}")
    print("curve error vs truth over -10..50 °C, ppm rms per axis x y z: mean",
          " ".join(f"{v:.1f}" for v in e.mean(0)), "| 95th percentile",
          " ".join(f"{v:.1f}" for v in np.percentile(e, 95, axis=0)))
    print("value at t_ref: rms z-score x y z", " ".join(f"{v:.2f}" for v in np.sqrt(np.mean(z**2, axis=0))))


if __name__ == "__main__":
    main()
