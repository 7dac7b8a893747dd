"""The virtual lab's recursive filters, run by scipy.signal's own compiled kernels.

The simulator filters with two of scipy.signal's kernels: the cascade of second-order sections
behind :func:`scipy.signal.sosfilt` (the bias-instability noise, :mod:`workbench.sim.noise`) and
the direct-form filter behind :func:`scipy.signal.lfilter` (the unit's thermal lag,
:mod:`workbench.sim.rig`). Importing the ``scipy.signal`` package costs about 0.5 s of CPU
(it loads scipy.stats, scipy.interpolate and more), longer than most recordings take to
simulate, and nothing else in a simulated campaign needs it; so the two compiled extension
modules are loaded here on their own, and the numbers are scipy.signal's bit for bit. Where they
cannot be loaded that way (a scipy whose files are laid out otherwise), the public functions are
used, with the same numbers.

Public: :func:`sosfilt_rows`, :func:`first_order_lag`, :func:`load_kernels`.
"""

from __future__ import annotations

import importlib.machinery
import importlib.util
from functools import lru_cache
from pathlib import Path

import numpy as np


@lru_cache(maxsize=None)
def _kernel(module: str, name: str):
    """Function ``name`` of scipy.signal's extension module ``module``, loaded without the package; None
    if it is not there."""
    import scipy

    folder = Path(scipy.__file__).parent / "signal"
    for suffix in importlib.machinery.EXTENSION_SUFFIXES:
        path = folder / f"{module}{suffix}"
        if path.exists():
            spec = importlib.util.spec_from_file_location(f"scipy.signal.{module}", path)
            try:
                mod = importlib.util.module_from_spec(spec)
                spec.loader.exec_module(mod)
            except ImportError:
                return None
            return getattr(mod, name, None)
    return None


def load_kernels() -> None:
    """Load both kernels now (e.g. before worker processes fork: they share them)."""
    _kernel("_sosfilt", "_sosfilt")
    _kernel("_sigtools", "_linear_filter")


def sosfilt_rows(sos: np.ndarray, x: np.ndarray, zi: np.ndarray) -> None:
    """Filter every row of ``x`` through the cascade ``sos``, in place, carrying the state ``zi``.

    Parameters
    ----------
    sos : (P, 6) float64, second-order sections (``sos[:, 3] == 1``), as for :func:`scipy.signal.sosfilt`
    x : (C, n) float64, C-contiguous: C signals, replaced by their filtered values
    zi : (C, P, 2) float64, C-contiguous: each signal's section states, updated to the end of ``x``

    The same numbers as ``sosfilt(sos, x, axis=-1, zi=zi.transpose(1, 0, 2))``.
    """
    kernel = _kernel("_sosfilt", "_sosfilt")
    if kernel is not None:
        kernel(sos, x, zi)
        return
    from scipy.signal import sosfilt

    y, zf = sosfilt(sos, x, axis=-1, zi=zi.transpose(1, 0, 2))
    x[...] = y
    zi[...] = zf.transpose(1, 0, 2)


def first_order_lag(x: np.ndarray, alpha: float, y0: float) -> np.ndarray:
    """First-order lag ``y[k] = (1 - alpha) x[k] + alpha y[k - 1]`` of ``x`` (n,), from ``y[-1] = y0``.

    E.g. a unit's temperature (°C) following the air's with time constant tau at sample period dt:
    ``alpha = exp(-dt / tau)``. The same numbers as
    ``lfilter([1 - alpha], [1, -alpha], x, zi=[alpha * y0])[0]``.
    """
    b, a = np.array([1.0 - alpha]), np.array([1.0, -alpha])
    x, zi = np.asarray(x, float), np.array([alpha * y0])
    kernel = _kernel("_sigtools", "_linear_filter")
    if kernel is not None:
        return kernel(b, a, x, -1, zi)[0]
    from scipy.signal import lfilter

    return lfilter(b, a, x, zi=zi)[0]
