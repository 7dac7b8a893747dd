"""The Allan analysis result of one record (:class:`AllanAnalysis`) and its result protocol.

:class:`AllanAnalysis` holds the OADEV curve with intervals and the IEEE 952 noise terms per
channel (:mod:`workbench.analysis.allan_fit` makes it); :meth:`AllanAnalysis.to_dict` is its
JSON form (SI: taus s, deviations and terms in the quantity's SI unit), :meth:`AllanAnalysis.summary`
its lines in lab units (:func:`workbench.analysis.allan_terms.term_text`),
:meth:`AllanAnalysis.noise_block` the calibration set's ``noise.<triad>`` block
(names :data:`CALSET_NAMES`). Follows :class:`workbench.result.AnalysisResult`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from workbench.analysis.allan_terms import TERMS, term_text

if TYPE_CHECKING:
    from workbench.analysis.allan_ci import DeviationCI
    from workbench.analysis.allan_fit import ChannelNoise

CALSET_NAMES = {
    "gyro": {"quantization": "quantization", "white": "arw", "bias_instability": "bias_instability", "rrw": "rrw",
             "rate_ramp": "rate_ramp"},
    "accel": {"quantization": "quantization", "white": "vrw", "bias_instability": "bias_instability", "rrw": "rrw",
              "rate_ramp": "rate_ramp"},
}


@dataclass(frozen=True)
class AllanAnalysis:
    """Allan analysis of one record: the OADEV curve with intervals and the noise terms per channel.

    ``quantity`` is ``"gyro"``, ``"accel"`` or None (units then the input's SI unit).
    """

    ci: DeviationCI
    fits: tuple[ChannelNoise, ...]
    quantity: str | None
    warnings: tuple[str, ...] = ()

    def noise_block(self) -> dict:
        """The calibration set's ``noise.<triad>`` block: per term a (3,) list (None = not observed)
        and ``<name>_ci95`` a (3,) list of [lo, hi] (for a term not observed, [0, upper bound])."""
        if self.quantity not in CALSET_NAMES or len(self.fits) != 3:
            raise ValueError("noise_block needs a gyro or accel triad (three channels)")
        block: dict = {}
        for term, name in CALSET_NAMES[self.quantity].items():
            block[name] = [t.value if t.observed else None for t in (f.terms[term] for f in self.fits)]
            block[name + "_ci95"] = [list(f.terms[term].ci95) for f in self.fits]
        return block

    def to_dict(self) -> dict:
        """JSON-ready content, SI: ``tau_s`` (K,) s; ``adev``, ``adev_lo``, ``adev_hi`` (95 %), ``edf``,
        ``alpha`` (noise exponent) per channel (C, K) in the quantity's SI unit (rad/s, m/s²);
        ``terms`` the :meth:`noise_block`; ``tau_range_s`` per term the dominating tau range of each
        channel (s, None = not observed); ``read_off`` the classic read-offs per channel (None where
        the curve shows no such slope); ``chi2_red`` per channel."""
        c = self.ci.curve
        return {
            "tau_s": c.tau.tolist(), "adev": c.dev.T.tolist(), "adev_lo": self.ci.lo.T.tolist(),
            "adev_hi": self.ci.hi.T.tolist(), "edf": self.ci.edf.T.tolist(), "alpha": self.ci.alpha.T.tolist(),
            "terms": self.noise_block(),
            "tau_range_s": {t: [f.terms[t].tau_range for f in self.fits] for t in TERMS},
            "read_off": {k: [f.read_off[k] if np.isfinite(f.read_off[k]) else None for f in self.fits]
                         for k in self.fits[0].read_off},
            "chi2_red": [f.chi2_red for f in self.fits],
        }

    def summary(self) -> list[str]:
        """One line per channel in lab units: each observed term with its 95 % interval, then the 95 %
        upper bounds of the terms not observed (``gyro gx: N 0.201 °/√h [0.198 °/√h .. 0.202 °/√h]; ...``)."""
        lines = []
        for f in self.fits:
            parts = []
            for t in TERMS:
                term = f.terms[t]
                if term.observed:
                    lo, hi = (term_text(self.quantity, t, v).split(" ", 1)[1] for v in term.ci95)
                    parts.append(f"{term_text(self.quantity, t, term.value)} [{lo} .. {hi}]")
            bounds = [f"{term_text(self.quantity, t, f.terms[t].ci95[1])}" for t in TERMS if not f.terms[t].observed]
            lines.append(f"{self.quantity} {f.column}: " + "; ".join(parts)
                         + (f"; not observed (95 % upper bound): {', '.join(bounds)}" if bounds else ""))
        return lines
