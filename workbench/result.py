"""The result protocol every analysis result follows, learnt once (as scipy's result objects).

An analysis result has ``to_dict()`` (JSON-ready, SI unless a key names its unit),
``summary()`` (lines for people, in lab units), ``warnings`` (one-line strings) and, when it
yields coefficients, ``to_calibration(unit)`` (a :class:`~workbench.calset.CalibrationSet`
for the unit under test). :class:`AnalysisResult` and :class:`CoefficientResult` are
structural protocols (``isinstance`` checks the methods);
:class:`workbench.procedure.ProcedureResult` satisfies both.
:class:`SummaryLines` is the list of summary lines that is also callable, so a result may hold
its lines in an attribute named ``summary`` and still offer ``summary()``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol, runtime_checkable


@runtime_checkable
class AnalysisResult(Protocol):
    """What every analysis result offers."""

    warnings: Sequence[str]

    def to_dict(self) -> dict:
        """JSON-ready content, SI (a key that is not SI names its unit, e.g. ``azimuth_deg``)."""
        ...

    def summary(self) -> list[str]:
        """Lines for people, in lab units, each labelled."""
        ...


@runtime_checkable
class CoefficientResult(AnalysisResult, Protocol):
    """An analysis result that yields calibration coefficients."""

    def to_calibration(self, unit):
        """The (partial) calibration set of ``unit`` (a :class:`workbench.calset.Unit`) these coefficients make."""
        ...


class SummaryLines(list):
    """Summary lines (a list of str) that ``summary()`` also returns: ``r.summary`` and ``r.summary()`` agree."""

    def __call__(self) -> list[str]:
        """The lines, as a plain list."""
        return list(self)
