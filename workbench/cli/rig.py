"""``workbench rig check CONFIG`` and ``workbench rig hil CONFIG``: real rigs and their loopback simulator."""

from __future__ import annotations

import time
from pathlib import Path

import typer
from rich.table import Table

from workbench.cli import out

rig_app = typer.Typer(no_args_is_help=True, help="Real rigs: check a connection; run the hardware-in-the-loop "
                                                 "simulator.")


@rig_app.command("check")
def check(config: str = typer.Argument(..., help="Rig configuration (fixtures/rigs/*.yaml).")) -> None:
    """Query identity, table position and rate, interlock, chamber and unit temperature; moves nothing."""
    from workbench.drivers.rig import open_real_rig
    from workbench.rigconfig import load_rig_config

    cfg = load_rig_config(config)
    if cfg.driver == "sim":
        out.print(f"rig {cfg.name}: simulated (driver sim), no hardware to check")
        return
    rig = open_real_rig(cfg)
    try:
        info = rig.identify()
    finally:
        rig.close()
    t = Table("item", "value", title=f"rig {cfg.name}: connection check (nothing moved)")
    for key, value in info.items():
        t.add_row(key, f"{value:.4f}" if isinstance(value, float) else str(value))
    out.print(t)


@rig_app.command("hil")
def hil(config: str = typer.Argument(..., help="Rig configuration on 127.0.0.1 (e.g. fixtures/rigs/hil.yaml)."),
        speed: float = typer.Option(None, "--speed", help="Simulated seconds per wall-clock second "
                                                          "(default: hil.speed of the configuration)."),
        seconds: float = typer.Option(None, "--seconds", help="Stop after this many wall-clock seconds "
                                                              "(default: run until Ctrl-C).")) -> None:
    """Serve the table, chamber and IMU stream of CONFIG on 127.0.0.1 from the simulated lab."""
    import math

    from workbench.sim.hil import HilLab
    from workbench.rigconfig import load_rig_config

    if seconds is not None and not (math.isfinite(seconds) and seconds > 0):  # -5 stopped at once, NaN never
        raise typer.BadParameter(f"--seconds {seconds:g}: expected a positive number of seconds")
    cfg = load_rig_config(config)
    lab = HilLab(cfg, speed=speed).start()
    o = lab.config.options
    out.print(f"hardware-in-the-loop rig {cfg.name}: unit {lab.truth.serial}, {lab.fs:g} Hz, speed x{lab.speed:g}")
    out.print(f"  table   {o['table_controller']['resource']}")
    if o.get("chamber_controller"):
        ch = o["chamber_controller"]
        where = ch["address"] if "address" in ch else f"modbus {ch['host']}:{ch['port']}"
        out.print(f"  chamber {where}")
    out.print(f"  stream  {o['imu_stream']['address']}")
    out.print("Ctrl-C to stop")
    try:
        t_end = None if seconds is None else time.monotonic() + seconds
        while t_end is None or time.monotonic() < t_end:
            time.sleep(0.2)
    except KeyboardInterrupt:
        pass
    finally:
        lab.stop()
        out.print("simulator stopped")


def register(app: typer.Typer) -> None:
    app.add_typer(rig_app, name="rig")
