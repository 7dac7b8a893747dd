"""Discovery of procedures and export formats (workbench/registry.py)."""

import pytest

from workbench import registry
from workbench.errors import ExportError, ProcedureError


def test_every_procedure_module_is_found_by_its_command_name():
    procs = registry.procedures()
    assert {"multiposition", "earth-rate", "allan", "zupt-alignment"} <= set(procs)
    for name, module in procs.items():
        # the module name is the command name with '-' as '_' (docs/architecture.md)
        assert module.__name__ == f"procedures.{name.replace('-', '_')}"
        for attr in ("TITLE", "TRIADS", "CAMPAIGN_ORDER", "OPTIONS", "DEFAULTS", "sequence", "analyze"):
            assert hasattr(module, attr), (name, attr)
        assert registry.procedure(name) is module


def test_helpers_are_not_procedures_and_unknown_names_are_refused():
    assert not any(m.__name__.split(".")[-1].startswith("_") for m in registry.procedures().values())
    with pytest.raises(ProcedureError, match=r"unknown procedure 'multipos' \(known: .*multiposition"):
        registry.procedure("multipos")
    with pytest.raises(ExportError, match=r"unknown export format 'xml' \(known: .*kalibr"):
        registry.exporter("xml")


def test_campaign_order_and_triads():
    order = [m.NAME for m in registry.campaign_procedures({"gyro", "accel"})]
    assert order == sorted(order, key=lambda n: registry.procedure(n).CAMPAIGN_ORDER)
    assert "magnetometer" not in order  # needs the magnetometer triad
    assert "magnetometer" in [m.NAME for m in registry.campaign_procedures({"gyro", "accel", "mag"})]
    assert all(registry.procedure(n).CAMPAIGN_ORDER is not None for n in order)


def test_exporters_declare_their_format():
    for fmt, module in registry.exporters().items():
        assert module.FORMAT == fmt and module.SUFFIX.startswith(".") and module.DESCRIPTION
        assert callable(module.export)
