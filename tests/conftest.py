"""Shared test setup: the repository root on sys.path (tests import helpers as ``tests.*``); the
figures a test leaves open are closed after it."""

import sys
from pathlib import Path

import matplotlib
import pytest

matplotlib.use("Agg")
ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))


@pytest.fixture(autouse=True)
def _close_figures():
    """Close every figure a test left open: pyplot keeps them (and the forked campaign workers inherit
    them), and more than 20 open figures warn in whichever test opens the next one."""
    yield
    pyplot = sys.modules.get("matplotlib.pyplot")
    if pyplot is not None:
        pyplot.close("all")
