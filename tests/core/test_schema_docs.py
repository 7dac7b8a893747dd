"""Markdown key tables of a pydantic schema (workbench/schema_docs.py), on a small schema with known rows."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import BaseModel, Field

from workbench.schema_docs import TABLE_HEAD, default_text, key_row, sections, type_name, value_range


class Inner(BaseModel):
    """Inner section."""

    rate: Annotated[float, Field(gt=0, le=90, description="a rate | per second")] = 10.0


class Outer(BaseModel):
    """Outer."""

    name: str = Field(description="a name")
    kind: Literal["a", "b"] = "a"
    inner: Inner = Field(default_factory=Inner)
    maybe: Inner | None = None
    values: list[float] = [1.0, 2.0]


def test_sections_depth_first_with_prefixes():
    assert [(p, m) for p, m in sections(Outer)] == [("", Outer), ("inner", Inner), ("maybe", Inner)]


def test_cells():
    f = Outer.model_fields
    assert type_name(f["kind"].annotation) == "'a' \\| 'b'"
    assert type_name(f["maybe"].annotation) == "mapping \\| null"
    assert type_name(f["values"].annotation) == "list[float]"
    assert value_range(Inner.model_fields["rate"]) == "> 0, <= 90"
    assert default_text(f["name"]) == "required"
    assert default_text(f["inner"]) == "section defaults"
    assert default_text(f["values"]) == "`[1.0, 2.0]`"


def test_row_escapes_the_pipe():
    assert key_row("rate", Inner.model_fields["rate"]) == "| `rate` | float | > 0, <= 90 | `10.0` | a rate \\| per second |"
    assert len(TABLE_HEAD) == 2 and TABLE_HEAD[0].count("|") == key_row("rate", Inner.model_fields["rate"]).count("|") - 1
