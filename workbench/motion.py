"""Motion state shared by the simulated rig and the real-rig driver.

:class:`RigState`: where the rig is between steps (sample counter, table angle and rate,
mount, chamber and unit temperatures, noise and generator states), saved in the session so
that ``workbench run --resume`` continues exactly. Neither ``workbench.sim`` nor
``workbench.drivers`` owns it: both import it from here.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass
class RigState:
    """Where the rig is between steps (saved in the session for ``--resume``)."""

    sample: int = 0  # index of the next sample (t = sample / fs)
    table_angle: float = 0.0  # rad, wrapped to [0, 2 pi)
    table_rate: float = 0.0  # rad/s
    mount: list | None = None
    air_c: float = 23.0
    unit_c: float = 23.0
    chamber_target_c: float = 23.0
    chamber_rate_c_per_min: float = 5.0
    imu: dict | None = None  # VirtualIMU noise state, so a resumed run continues the same noise
    rng: dict | None = None  # fixture-error generator state

    def to_dict(self) -> dict:
        """The state as a JSON-ready dict (the session's saved rig state)."""
        return dict(self.__dict__)
