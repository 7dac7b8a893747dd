"""GMWM of a whole record: every channel of a triad, its calibration-set noise block and summary.

:func:`analyze_gmwm` fits :func:`workbench.analysis.gmwm.fit_gmwm` to each channel of rate
samples (N, C) SI (gaps handled by :func:`workbench.analysis.allan.prepare_rate_data`; the
longest gap-free run is fitted) and returns a :class:`GmwmAnalysis`, whose
:meth:`~GmwmAnalysis.noise_block` has the layout of the IEEE 952 fit's
(:meth:`workbench.analysis.allan_fit.AllanAnalysis.noise_block`): per term a (3,) list (None
where the model has no such term) and ``<name>_ci95``; bias instability comes from the
Gauss-Markov sum;
a term not observed is None with the interval [0, upper limit].

Public: :class:`GmwmAnalysis`, :func:`analyze_gmwm`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from workbench.analysis.allan import prepare_rate_data
from workbench.analysis.allan_fit import CALSET_NAMES
from workbench.analysis.gmwm import GmwmFit, fit_gmwm, term_interval_text
from workbench.errors import AnalysisError


@dataclass(frozen=True)
class GmwmAnalysis:
    """GMWM fits of one record's channels (SI of the input rate unit); ``quantity`` gyro | accel | None."""

    fits: tuple[GmwmFit, ...]
    quantity: str | None
    model: str
    warnings: tuple[str, ...] = ()

    def noise_block(self) -> dict:
        """The calibration set's ``noise.<triad>`` block from the GMWM terms (None = not in the model)."""
        if self.quantity not in CALSET_NAMES or len(self.fits) != 3:
            raise ValueError("noise_block needs a gyro or accel triad (three channels)")
        block: dict = {}
        for term, name in CALSET_NAMES[self.quantity].items():
            vals = [f.terms.get(term) for f in self.fits]
            block[name] = [v[0] if v is not None and f.resolved[term] else None for v, f in zip(vals, self.fits)]
            block[name + "_ci95"] = [[v[1], v[2]] if v is not None else None for v in vals]
        return block

    def to_dict(self) -> dict:
        """SI: the model text and each channel's :meth:`GmwmFit.to_dict`."""
        return {"model": self.model, "channels": [f.to_dict() for f in self.fits]}

    def summary(self) -> list[str]:
        """One line per channel: the IEEE 952 equivalents with 95 % intervals, in lab units."""

        lines = []
        for f in self.fits:
            parts = [term_interval_text(self.quantity, k, *v, f.resolved[k]) for k, v in f.terms.items()]
            lines.append(f"{f.column} (GMWM {self.model}): " + ", ".join(parts))
        return lines


def analyze_gmwm(y: np.ndarray, rate: float, columns: tuple[str, ...] | list[str], quantity: str | None = None,
                 model: str = "wn+fl+rw", bootstrap: int = 100, gap_policy: str = "error", source: str = "data",
                 seed: int = 0) -> GmwmAnalysis:
    """GMWM fit of ``model`` to every channel of rate samples ``y`` (N, C) SI at ``rate`` Hz.

    ``gap_policy`` as :func:`workbench.analysis.allan.prepare_rate_data` (the longest gap-free run
    is fitted); ``bootstrap`` and ``seed`` as :func:`workbench.analysis.gmwm.fit_gmwm`.
    """
    segments, warnings = prepare_rate_data(y, tuple(columns), source, gap_policy, quantity)
    seg = max(segments, key=len)
    fits = []
    for j, col in enumerate(columns):
        try:
            fits.append(fit_gmwm(seg[:, j], rate, model, col, bootstrap=bootstrap, seed=seed + j))
        except AnalysisError as exc:
            raise AnalysisError(f"{source}: column {col}: {exc}") from None
    return GmwmAnalysis(tuple(fits), quantity, model, tuple(warnings))
