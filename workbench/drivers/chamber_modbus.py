"""Climatic-chamber driver over Modbus TCP (Weiss/Vötsch, Watlow F4-style); register map in the configuration.

``chamber_controller`` of the rig configuration::

    driver: modbus
    host: 192.168.1.50
    port: 502
    device_id: 1
    timeout_s: 1.0
    retries: 2
    registers:
      temperature: {address: 100, kind: input, scale: 0.1, signed: true}   # measured air, °C = raw * scale
      setpoint:    {address: 300, kind: holding, scale: 0.1, signed: true}  # written with function 6
      run:         {address: 2000, value: 1}                               # optional: written after a setpoint

A Modbus exception reply to a setpoint write (e.g. *illegal data value*) is a refused
setpoint. Failures are :class:`RigError` naming the chamber, host:port and the register.
"""

from __future__ import annotations

from collections.abc import Mapping

from pymodbus.client import ModbusTcpClient
from pymodbus.exceptions import ModbusException

from workbench.drivers.transport import short_error
from workbench.errors import RigError

_KINDS = ("holding", "input")


class ModbusChamber:
    """A chamber controller behind Modbus TCP; temperatures in °C."""

    def __init__(self, settings: Mapping, name: str = "chamber") -> None:
        for key in ("host", "registers"):
            if key not in settings:
                raise RigError(f"{name}: missing field 'chamber_controller.{key}'")
        self.host, self.port = str(settings["host"]), int(settings.get("port", 502))
        self.where = f"{name} (modbus {self.host}:{self.port})"
        self.device_id = int(settings.get("device_id", 1))
        self.timeout_s, self.retries = float(settings.get("timeout_s", 1.0)), int(settings.get("retries", 2))
        regs = settings["registers"] or {}
        for key in ("temperature", "setpoint"):
            if key not in regs or "address" not in (regs[key] or {}):
                raise RigError(f"{name}: missing field 'chamber_controller.registers.{key}.address'")
        for key, reg in regs.items():
            if reg.get("kind", "holding") not in _KINDS:
                raise RigError(f"{name}: registers.{key}.kind {reg.get('kind')!r} (expected holding or input)")
        self.registers = regs
        self._client: ModbusTcpClient | None = None

    def open(self) -> None:
        """Connect; RigError if the address does not answer."""
        self.close()
        self._client = ModbusTcpClient(self.host, port=self.port, timeout=self.timeout_s, retries=self.retries,
                                       reconnect_delay=0.1, reconnect_delay_max=1.0)
        if not self._client.connect():
            self.close()
            raise RigError(f"{self.where}: cannot connect")

    def close(self) -> None:
        """Release the connection."""
        if self._client is not None:
            self._client.close()
            self._client = None

    def _call(self, what: str, fn, *args, **kwargs):
        if self._client is None:
            self.open()
        try:
            reply = fn(self._client, *args, device_id=self.device_id, **kwargs)
        except ModbusException as exc:
            self.close()
            raise RigError(f"{self.where}: no valid answer to {what} ({short_error(exc)})") from None
        if reply.isError():
            raise RigError(f"{self.where}: {what} refused by the controller ({reply})")
        return reply

    def _read(self, key: str) -> float:
        reg = self.registers[key]
        fn = ModbusTcpClient.read_input_registers if reg.get("kind") == "input" \
            else ModbusTcpClient.read_holding_registers
        reply = self._call(f"read of register {key} ({reg['address']})", fn, int(reg["address"]), count=1)
        if not getattr(reply, "registers", None):
            raise RigError(f"{self.where}: malformed reply to the read of register {key} ({reg['address']})")
        raw = int(reply.registers[0])
        if reg.get("signed", True) and raw >= 0x8000:
            raw -= 0x10000
        return raw * float(reg.get("scale", 1.0))

    def _write(self, key: str, raw: int, what: str) -> None:
        reg = self.registers[key]
        self._call(f"{what} (register {key} {reg['address']} <- {raw})", ModbusTcpClient.write_register,
                   int(reg["address"]), raw & 0xFFFF)

    def identify(self) -> str:
        """A description of the link (Modbus chambers rarely answer an identity request)."""
        return f"modbus device {self.device_id} at {self.host}:{self.port}"

    def temperature(self) -> float:
        """Measured air temperature, °C."""
        return self._read("temperature")

    def set_setpoint(self, setpoint_c: float) -> None:
        """Write the air setpoint ``setpoint_c`` °C (then the ``run`` register, if mapped)."""
        reg = self.registers["setpoint"]
        raw = int(round(float(setpoint_c) / float(reg.get("scale", 1.0))))
        if not (-0x8000 <= raw <= 0x7FFF if reg.get("signed", True) else 0 <= raw <= 0xFFFF):
            raise RigError(f"{self.where}: setpoint {setpoint_c:.2f} °C does not fit register {reg['address']}")
        self._write("setpoint", raw, f"setpoint {setpoint_c:.2f} °C")
        if "run" in self.registers:
            self._write("run", int(self.registers["run"].get("value", 1)), "run command")
