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
    with pytest.raises(ProcedureError, match=r"; did you mean 'magnetometer'\?"):
        registry.procedure("magnetomter")
    with pytest.raises(ExportError, match=r"unknown export format 'xml' \(known: .*kalibr"):
        registry.exporter("xml")


def test_procedure_names_read_without_import_are_the_registered_ones():
    assert registry.procedure_names() == sorted(registry.procedures())


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


def test_campaign_procedures_imports_only_the_campaign_and_finds_what_a_full_scan_finds():
    import subprocess
    import sys
    from pathlib import Path

    code = ("import sys; from workbench.registry import campaign_procedures, procedures; "
            "found = [m.NAME for m in campaign_procedures({'accel', 'gyro', 'mag'})]; "
            "loaded = sorted(n for n in sys.modules if n.startswith('procedures.')); "
            "full = [m.NAME for m in sorted((m for m in procedures().values() if m.CAMPAIGN_ORDER is not None), "
            "key=lambda m: m.CAMPAIGN_ORDER)]; print(found, loaded, full, sep='|')")
    root = Path(__file__).resolve().parents[2]
    out = subprocess.run([sys.executable, "-c", code], cwd=root, capture_output=True, text=True, check=True,
                         env={**__import__("os").environ, "PYTHONPATH": str(root)}).stdout.strip()
    found, loaded, full = out.split("|")
    assert found == full  # the same procedures in the same order as importing every module
    assert "procedures.allan" in loaded and "procedures.ahrs_table" not in loaded and "procedures.land_ins" not in loaded
