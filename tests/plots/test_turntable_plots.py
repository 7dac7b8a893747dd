"""Turntable figures: every bar inside the axes."""

from __future__ import annotations

import dataclasses

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from workbench.analysis.gyro_fit import TurnCheck  # noqa: E402
from workbench.plots.turntable import plot_turn_checks  # noqa: E402


def _check(label: str, backward_deg: float) -> TurnCheck:
    fields = {f.name: np.nan for f in dataclasses.fields(TurnCheck)}
    nominal = np.array([0.0, 0.0, 2 * np.pi])
    fields.update(step=0, label=label, nominal=nominal, integral=nominal, angle=2 * np.pi,
                  closure=np.radians(0.05), wobble_rms=np.radians(2.0), backward=np.radians(backward_deg),
                  axis_tilt=np.radians(0.2), gravity_change=np.radians(0.04), motion_before=np.radians(0.01),
                  motion_after=np.radians(0.07))
    return TurnCheck(**fields)


def test_turn_checks_y_limit_holds_the_largest_bar():
    """The imucal example's z turn went 6.74° backward: that bar must end below the top of the axes."""
    fig = plot_turn_checks([_check("x_rot", 0.21), _check("z_rot", 6.74)])
    ax = fig.axes[0]
    tallest = max(p.get_height() for p in ax.patches)
    assert abs(tallest - 6.74) < 1e-9  # drawn in degrees
    assert ax.get_ylim()[1] > tallest and ax.get_ylim()[0] <= 0.0
    plt.close(fig)
