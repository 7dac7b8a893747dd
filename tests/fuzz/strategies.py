"""Hypothesis strategies shared by the fuzz properties: hostile values and edits of nested documents."""

from __future__ import annotations

import copy
from typing import Any

from hypothesis import strategies as st

# text a shell can pass (no NUL, no lone surrogates)
TEXT = st.text(st.characters(blacklist_categories=("Cs",), blacklist_characters="\x00"), max_size=40)
HOSTILE_TEXT = st.one_of(TEXT, st.sampled_from(["", "..", "../../x", "/etc/passwd", "[/]", "[bold]x[/bold]",
                                                "{0.__class__}", "*a", "&a", "nan", "-1", "1e999", "\\", "%s",
                                                "<script>x</script>"]))
NUMBER = st.one_of(st.integers(-10**12, 10**12), st.floats(allow_nan=True, allow_infinity=True),
                   st.sampled_from([0, -1, 0.0, -0.0, 1e308, -1e308, 2**63]))
SCALAR = st.one_of(st.none(), st.booleans(), NUMBER, HOSTILE_TEXT)
VALUE = st.recursive(SCALAR, lambda inner: st.one_of(st.lists(inner, max_size=4),
                                                     st.dictionaries(TEXT, inner, max_size=3)), max_leaves=6)
NON_FINITE = st.sampled_from([float("nan"), float("inf"), float("-inf")])


def paths(doc: Any, prefix: tuple = ()) -> list[tuple]:
    """Every key/index path of a nested document (dicts and lists)."""
    out = [prefix] if prefix else []
    if isinstance(doc, dict):
        for k, v in doc.items():
            out += paths(v, (*prefix, k))
    elif isinstance(doc, list):
        for i, v in enumerate(doc[:6]):
            out += paths(v, (*prefix, i))
    return out


def edited(doc: Any, path: tuple, action: str, value: Any = None) -> Any:
    """A copy of ``doc`` with the item at ``path`` replaced by ``value``, deleted, or given an extra key."""
    new = copy.deepcopy(doc)
    parent = new
    for k in path[:-1]:
        parent = parent[k]
    key = path[-1]
    if action == "delete":
        del parent[key]
    elif action == "extra" and isinstance(parent, dict):
        parent[f"{key}_x"] = value
    else:
        parent[key] = value
    return new


@st.composite
def edits(draw, doc: Any) -> Any:
    """A document with one hostile edit: a value replaced, a key deleted or an unknown key added."""
    path = draw(st.sampled_from(paths(doc)))
    action = draw(st.sampled_from(["replace", "replace", "delete", "extra"]))
    return edited(doc, path, action, draw(VALUE))
