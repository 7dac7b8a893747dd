"""Markdown tables of a strict pydantic schema: every key with its type, range, default and meaning.

:func:`sections` (each nested model with its dotted prefix, depth first) and :func:`key_row`
(one table row of a field). Used by :func:`workbench.rigschema.schema_markdown` for the key
tables of ``docs/rigs.md``; knows nothing of rigs.
"""

from __future__ import annotations

import json
import types
from typing import Annotated, Any, Literal, Union, get_args, get_origin

from pydantic import BaseModel

TABLE_HEAD = ["| key | type | range | default | meaning |", "|---|---|---|---|---|"]


def type_name(annotation: Any) -> str:
    """A field's type in words for a table cell (``float``, ``'ascii' \\| 'modbus'``, ``mapping``, ``... \\| null``)."""
    origin, args = get_origin(annotation), get_args(annotation)
    if origin is Annotated:
        return type_name(args[0])
    if origin is Literal:
        return " \\| ".join(repr(a) for a in args)
    if origin in (Union, types.UnionType):
        names = list(dict.fromkeys(type_name(a) for a in args if a is not type(None)))
        return " \\| ".join(names) + (" \\| null" if type(None) in args else "")
    if origin in (list, dict):
        return f"{origin.__name__}[{', '.join(type_name(a) for a in args)}]"
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return "mapping"
    return getattr(annotation, "__name__", str(annotation))


def value_range(field: Any) -> str:
    """A field's bounds (``> 0, <= 90``), '' when unbounded."""
    out = []
    for m in field.metadata:
        for attr, sym in (("gt", ">"), ("ge", ">="), ("lt", "<"), ("le", "<=")):
            if getattr(m, attr, None) is not None:
                out.append(f"{sym} {getattr(m, attr):g}")
    return ", ".join(out)


def default_text(field: Any) -> str:
    """A field's default as JSON in backticks, ``required``, or ``section defaults``."""
    if field.is_required():
        return "required"
    if field.default_factory is not None:
        return "section defaults"
    return "`" + json.dumps(field.default, ensure_ascii=False).replace("|", "\\|") + "`"


def _walk(model: type[BaseModel], prefix: str, seen: list) -> None:
    seen.append((prefix, model))
    for key, f in model.model_fields.items():
        for sub in _models_in(f.annotation):
            _walk(sub, f"{prefix}.{key}" if prefix else key, seen)


def _models_in(annotation: Any) -> list[type[BaseModel]]:
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return [annotation]
    return [m for a in get_args(annotation) for m in _models_in(a)]


def sections(root: type[BaseModel]) -> list[tuple[str, type[BaseModel]]]:
    """``(prefix, model)`` of ``root`` and every model nested in its fields, depth first ('' for the root)."""
    seen: list = []
    _walk(root, "", seen)
    return seen


def key_row(key: str, field: Any) -> str:
    """One Markdown table row: key, type, range, default, meaning (the field's description)."""
    desc = (field.description or "").replace("|", "\\|")
    return f"| `{key}` | {type_name(field.annotation)} | {value_range(field)} | {default_text(field)} | {desc} |"
