"""Discovery of procedures (``procedures/*.py``) and export formats (``workbench/exports/*.py``).

A procedure module defines ``NAME``, ``TITLE``, ``TRIADS``, ``CAMPAIGN_ORDER``, ``DEFAULTS``,
``sequence(spec, **options)``, ``analyze(session, **options)`` and ``figures(result)``
(see ``docs/architecture.md``). An export module defines ``FORMAT``, ``SUFFIX``,
``DESCRIPTION`` and ``export(calset) -> Export``.
"""

from __future__ import annotations

import importlib
import pkgutil
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from types import ModuleType

from workbench.errors import ExportError, ProcedureError


@dataclass(frozen=True)
class Export:
    """An exported calibration: the file text and what the format could not express."""

    text: str
    dropped: list[str] = field(default_factory=list)


def _modules(package: str) -> list[ModuleType]:
    pkg = importlib.import_module(package)
    return [importlib.import_module(f"{package}.{m.name}") for m in pkgutil.iter_modules(pkg.__path__)
            if not m.name.startswith("_")]


@lru_cache(maxsize=1)
def procedures() -> dict[str, ModuleType]:
    """All procedure modules by command-line name."""
    return {m.NAME: m for m in _modules("procedures") if hasattr(m, "NAME") and hasattr(m, "analyze")}


def procedure(name: str) -> ModuleType:
    """The procedure module called ``name``; raises ProcedureError naming the known ones.

    The module ``procedures/<name with - as _>.py`` is imported alone (a batch worker need not
    import every procedure); the full scan only names the known ones in the error.
    """
    try:
        module = importlib.import_module(f"procedures.{name.replace('-', '_')}")
        if getattr(module, "NAME", None) == name and hasattr(module, "analyze"):
            return module
    except ImportError:
        pass
    procs = procedures()
    if name not in procs:
        raise ProcedureError(f"unknown procedure {name!r} {unknown_hint(name, sorted(procs))}")
    return procs[name]


def procedure_names() -> list[str]:
    """The registered procedures' names, read from the ``NAME`` literal of each module's source
    (a module whose ``NAME`` is not a literal is imported to find out): checking a name costs no import."""
    names = []
    for module, declared in _declared(("NAME",)):
        if "NAME" in declared:
            names.append(str(declared["NAME"]))
        else:
            m = importlib.import_module(module)
            if hasattr(m, "NAME") and hasattr(m, "analyze"):
                names.append(m.NAME)
    return sorted(names)


def _declared(names: tuple[str, ...]):
    """(module name, literal values of ``names`` in its source) of every ``procedures/*.py`` not starting with _."""
    pkg = importlib.import_module("procedures")
    for info in pkgutil.iter_modules(pkg.__path__):
        if not info.name.startswith("_"):
            spec = info.module_finder.find_spec(info.name, None)
            yield f"procedures.{info.name}", _constants(getattr(spec, "origin", None), names)


def unknown_hint(name: str, known: list[str]) -> str:
    """``(known: a, b, c)`` and, for a near miss of one of ``known``, ``; did you mean 'x'?``."""
    import difflib

    near = difflib.get_close_matches(str(name), known, n=1, cutoff=0.6)
    return f"(known: {', '.join(known) or 'none'})" + (f"; did you mean {near[0]!r}?" if near else "")


_UNKNOWN = object()


def _constants(path: str | None, names: tuple[str, ...] = ("TRIADS", "CAMPAIGN_ORDER")) -> dict:
    """The literal top-level values of ``names`` in the module source at ``path`` (read, not imported).

    A name whose value is not a literal, or a file that cannot be read or parsed, gives nothing
    for it (the module is then imported to find out).
    """
    import ast

    try:
        tree = ast.parse(Path(path).read_text(encoding="utf-8"))
    except (OSError, TypeError, SyntaxError, ValueError):
        return {}
    out = {}
    for node in tree.body:
        targets = node.targets if isinstance(node, ast.Assign) else [node.target] if isinstance(node, ast.AnnAssign) else []
        for target in targets:
            if isinstance(target, ast.Name) and target.id in names and getattr(node, "value", None) is not None:
                try:
                    out[target.id] = ast.literal_eval(node.value)
                except ValueError:
                    out[target.id] = _UNKNOWN
    return {k: v for k, v in out.items() if v is not _UNKNOWN}


def campaign_procedures(triads: set[str]) -> list[ModuleType]:
    """Procedures of the campaign that apply to a unit with ``triads``, in campaign order.

    Only those are imported: a module whose source declares ``CAMPAIGN_ORDER = None`` or
    ``TRIADS`` the unit does not have (literal values, read with :mod:`ast`) is left alone.
    """
    procs = []
    for module, declared in _declared(("TRIADS", "CAMPAIGN_ORDER")):
        if ("CAMPAIGN_ORDER" in declared and declared["CAMPAIGN_ORDER"] is None) or \
                ("TRIADS" in declared and not set(declared["TRIADS"]) <= triads):
            continue
        m = importlib.import_module(module)
        if hasattr(m, "NAME") and hasattr(m, "analyze") and getattr(m, "CAMPAIGN_ORDER", None) is not None \
                and set(m.TRIADS) <= triads:
            procs.append(m)
    return sorted(procs, key=lambda m: m.CAMPAIGN_ORDER)


@lru_cache(maxsize=1)
def exporters() -> dict[str, ModuleType]:
    """All export modules by format name."""
    return {m.FORMAT: m for m in _modules("workbench.exports") if hasattr(m, "FORMAT")}


def export_set(calset, fmt: str) -> Export:
    """``calset`` (a :class:`workbench.calset.CalibrationSet`) in export format ``fmt``. A set breaking the
    id / serial / model rules (one stored before them) is refused, one line: those go verbatim into the file."""
    problems = calset.name_problems()
    if problems:
        raise ExportError(f"{problems[0]}; export refused (a set stored before this rule is readable, never exported)")
    return exporter(fmt).export(calset)


def exporter(fmt: str) -> ModuleType:
    """The export module for ``fmt``; raises ExportError naming the known formats."""
    ex = exporters()
    if fmt not in ex:
        raise ExportError(f"unknown export format {fmt!r} (known: {', '.join(sorted(ex))})")
    return ex[fmt]
