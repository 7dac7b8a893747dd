"""One-way layers, read from the imports (ast; nothing is imported or run).

value types and file helpers <- analyses / nav <- procedures <- jobs / CLI / dashboard;
drivers never import the simulator; the simulator never calls the runner or anything above;
an analysis builds no ProcedureResult and reads no fixture (grades, rig configurations): it
gets noise terms and site data as arguments. Imports under ``if TYPE_CHECKING:`` (type hints
only) are not counted.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

# the bottom layer: value types, file helpers and small shared facts import (almost) nothing
VALUE_MODULES = ("workbench.values", "workbench.files", "workbench.json_values", "workbench.angles", "workbench.motion",
                 "workbench.units", "workbench.earth", "workbench.errors", "workbench.result", "workbench.allan_model")
VALUE_MAY_IMPORT = ("workbench.errors",)

ABOVE_ANALYSES = ("workbench.procedure", "workbench.registry", "workbench.jobs", "workbench.cli", "workbench.runner",
                  "workbench.drivers", "workbench.sim", "workbench.store", "workbench.fleet", "workbench.plots",
                  "procedures", "dashboard")
FIXTURE_READERS = ("workbench.grades", "workbench.rigconfig", "workbench.rigsites", "workbench.importer",
                   "workbench.importers")

RULES = [
    # (modules, forbidden imports, why)
    *[(m, ("workbench.calset",) + ABOVE_ANALYSES, "the session format is below calibration sets")
      for m in ("workbench.session", "workbench.session_types", "workbench.session_validate", "workbench.session_files")],
    ("workbench.analysis", ABOVE_ANALYSES + FIXTURE_READERS, "analyses are pure: arguments in, result out"),
    ("workbench.nav", ABOVE_ANALYSES + FIXTURE_READERS, "navigation estimators are pure like analyses"),
    ("workbench.model", ABOVE_ANALYSES + FIXTURE_READERS + ("workbench.calset", "workbench.session"),
     "the error model is a value type"),
    ("workbench.drivers", ("workbench.sim", "workbench.jobs", "workbench.cli", "workbench.procedure",
                           "workbench.registry", "workbench.analysis", "procedures", "dashboard"),
     "a real driver never imports the simulator"),
    ("workbench.sim", ("workbench.runner", "workbench.jobs", "workbench.cli", "workbench.procedure",
                       "workbench.registry", "workbench.analysis", "workbench.store", "procedures", "dashboard"),
     "the virtual lab is a rig: the runner drives it, not the reverse"),
    ("workbench.plots", ("workbench.jobs", "workbench.cli", "workbench.runner", "workbench.drivers", "workbench.sim",
                         "workbench.store", "procedures", "dashboard"), "figures are drawn from result objects"),
    # (a procedure may use the virtual lab's models, e.g. a simulated vehicle drive; never the runner)
    ("procedures", ("workbench.cli", "workbench.jobs", "workbench.store", "workbench.runner", "workbench.drivers",
                    "dashboard"), "procedures are adapters between analyses and jobs"),
]


def _module_name(path: Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _is_type_checking(node: ast.If) -> bool:
    t = node.test
    return (isinstance(t, ast.Name) and t.id == "TYPE_CHECKING") or \
        (isinstance(t, ast.Attribute) and t.attr == "TYPE_CHECKING")


def imports(path: Path) -> set[str]:
    """Every workbench / procedures / dashboard module a file imports (top level and inside functions)."""
    out: set[str] = set()

    def visit(node: ast.AST) -> None:
        if isinstance(node, ast.If) and _is_type_checking(node):
            for child in node.orelse:
                visit(child)
            return
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            out.add(node.module)
            out.update(f"{node.module}.{a.name}" for a in node.names)
        elif isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
        for child in ast.iter_child_nodes(node):
            visit(child)

    visit(ast.parse(path.read_text(encoding="utf-8"), str(path)))
    return {m for m in out if m.split(".")[0] in ("workbench", "procedures", "dashboard")}


def _files(package: str) -> list[Path]:
    base = ROOT / package.replace(".", "/")
    if base.with_suffix(".py").exists():
        return [base.with_suffix(".py")]
    return sorted(base.rglob("*.py"))


def _hits(mods: set[str], forbidden: tuple[str, ...]) -> list[str]:
    return sorted(m for m in mods if any(m == f or m.startswith(f + ".") for f in forbidden))


def test_layer_rules():
    bad = []
    for package, forbidden, why in RULES:
        for path in _files(package):
            for m in _hits(imports(path), forbidden):
                bad.append(f"{path.relative_to(ROOT)} imports {m} ({why})")
    assert not bad, "\n".join(bad)


def test_value_types_and_file_helpers_import_nothing_above_them():
    bad = []
    for package in VALUE_MODULES:
        for path in _files(package):
            for m in imports(path):
                if m.split(".")[:2] != ["workbench", "__version__"] and m != "workbench" \
                        and not any(m == v or m.startswith(v + ".") for v in VALUE_MAY_IMPORT + VALUE_MODULES):
                    bad.append(f"{path.relative_to(ROOT)} imports {m}")
    assert not bad, "\n".join(bad)


def test_no_library_module_imports_the_command_line_or_the_procedures():
    """Only the CLI imports the CLI; procedures are found by the registry (importlib), never imported statically."""
    bad = []
    for path in _files("workbench"):
        name = _module_name(path)
        if name.startswith("workbench.cli") or name == "workbench.__main__":
            continue
        for m in _hits(imports(path), ("workbench.cli", "dashboard")):
            bad.append(f"{path.relative_to(ROOT)} imports {m}")
        if not name.startswith(("workbench.jobs", "workbench.fleet")):
            for m in _hits(imports(path), ("procedures",)):
                bad.append(f"{path.relative_to(ROOT)} imports {m}")
    assert not bad, "\n".join(bad)


def test_jobs_are_used_only_from_the_edges():
    """Orchestration (workbench.jobs) is called by the CLI, the dashboard and fleet runs only."""
    bad = [f"{p.relative_to(ROOT)}" for p in _files("workbench")
           if _hits(imports(p), ("workbench.jobs",))
           and not _module_name(p).startswith(("workbench.cli", "workbench.fleet", "workbench.jobs"))]
    assert not bad, bad


@pytest.mark.parametrize("path,names", [
    ("workbench/analysis/northfinding.py", {"ProcedureResult", "load_spec", "RIGS_DIR"}),
    ("workbench/nav/truth.py", {"RIGS_DIR", "yaml", "load_rig_config"}),
    ("workbench/sim/__init__.py", {"record", "start", "Recording"}),
])
def test_named_modules_do_not_use(path, names):
    """The specific inversions the review found, checked by name as well as by import."""
    tree = ast.parse((ROOT / path).read_text(encoding="utf-8"))
    used = {n.id for n in ast.walk(tree) if isinstance(n, ast.Name)} | \
        {a.asname or a.name for n in ast.walk(tree) if isinstance(n, (ast.Import, ast.ImportFrom)) for a in n.names}
    assert not used & names, f"{path} uses {sorted(used & names)}"


def test_the_loopback_simulator_lives_under_sim():
    assert (ROOT / "workbench/sim/hil.py").exists() and not (ROOT / "workbench/drivers/hil.py").exists()


def test_the_checker_sees_imports_inside_functions(tmp_path):
    """The rule reader itself: a function-level import counts, a TYPE_CHECKING one does not."""
    p = tmp_path / "m.py"
    p.write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from workbench.grades import SensorSpec\n"
                 "def f():\n    from workbench.sim.rig import SimRig\n    import procedures.rate\n")
    assert imports(p) == {"workbench.sim.rig", "workbench.sim.rig.SimRig", "procedures.rate"}
