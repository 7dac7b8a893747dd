"""Loopback rigs for the driver tests: HIL configurations on free 127.0.0.1 ports, stopped at teardown."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest
import yaml

from workbench.sim.hil import HilLab, free_port
from workbench.drivers.turntable_visa import GPIB_BACKENDS
from workbench.rigconfig import RIGS_DIR, load_rig_config

FS = 50.0  # Hz: low sample rate keeps the loopback runs light
SPEED = 20.0  # simulated seconds per wall-clock second
GPIB_BACKEND = any(importlib.util.find_spec(m) for m in GPIB_BACKENDS)  # linux-gpib or gpib-ctypes installed


def hil_yaml(tmp_path: Path, base: str = "hil", **changes) -> Path:
    """A copy of ``fixtures/rigs/<base>.yaml`` on free 127.0.0.1 ports, with top-level sections updated."""
    d = yaml.safe_load((RIGS_DIR / f"{base}.yaml").read_text())
    d["table_controller"]["resource"] = f"TCPIP0::127.0.0.1::{free_port()}::SOCKET"
    ch = d.get("chamber_controller")
    if ch and ch["driver"] == "modbus":
        ch["port"] = free_port()
    elif ch:
        ch["address"] = f"socket://127.0.0.1:{free_port()}"
    scheme = d["imu_stream"]["address"].split("://")[0]
    d["imu_stream"].update(address=f"{scheme}://127.0.0.1:{free_port()}", sample_rate_hz=FS)
    d["hil"] = {**d.get("hil", {}), "speed": SPEED}
    for key, value in changes.items():
        d[key] = {**d.get(key, {}), **value} if isinstance(value, dict) else value
    path = tmp_path / f"{base}-{len(list(tmp_path.glob('*.yaml')))}.yaml"
    path.write_text(yaml.safe_dump(d))
    return path


@pytest.fixture
def start_lab():
    """Factory: start a HilLab for a configuration file; every lab is stopped at teardown."""
    labs = []

    def start(path: Path, **kwargs) -> HilLab:
        lab = HilLab(load_rig_config(path), **kwargs).start()
        labs.append(lab)
        return lab

    yield start
    for lab in labs:
        lab.stop()


@pytest.fixture
def closing():
    """Register drivers/rigs to close at teardown: ``closing(obj)`` returns ``obj``."""
    objs = []

    def add(obj):
        objs.append(obj)
        return obj

    yield add
    for obj in reversed(objs):
        obj.close()
