"""Bounded YAML: size, alias expansion, recursion and nesting refused with one line naming the source."""

import pytest

from workbench.errors import WorkbenchError
from workbench.safe_yaml import load_yaml_file, load_yaml_text


def test_ordinary_documents_and_shared_aliases_load():
    assert load_yaml_text("a: &x {b: 1}\nc: *x\n", "f.yaml") == {"a": {"b": 1}, "c": {"b": 1}}
    assert load_yaml_text("", "f.yaml") is None


@pytest.mark.parametrize("text,match", [
    ("a: &a [*a]\n", "recursive alias"),
    ("[" * 5000 + "]" * 5000, "nests too deep"),
    ("a: [1\n", "not valid YAML"),
    ("a: !!python/object:os.system x\n", "not valid YAML"),
    ("a: 1\n---\nb: 2\n", "not valid YAML"),
])
def test_hostile_documents_are_refused(text, match):
    with pytest.raises(WorkbenchError, match=match) as info:
        load_yaml_text(text, "f.yaml")
    assert str(info.value).startswith("f.yaml: ") and "\n" not in str(info.value)


def test_expansion_limit_counts_through_aliases():
    doc = "a: &a [1, 2, 3, 4, 5, 6, 7, 8, 9]\nb: &b [*a, *a, *a, *a, *a, *a, *a, *a, *a, *a]\nc: [*b, *b, *b, *b]\n"
    assert load_yaml_text(doc, "f.yaml", max_nodes=520)["c"][0][0] == list(range(1, 10))
    with pytest.raises(WorkbenchError, match="expands to more than 519 nodes"):
        load_yaml_text(doc, "f.yaml", max_nodes=519)  # 520 nodes: 1 + 3 keys + 10 + 101 + 405


def test_files_checked_for_size_before_reading(tmp_path):
    (tmp_path / "big.yaml").write_text("x" * 200)
    with pytest.raises(WorkbenchError, match="larger than 100 bytes"):
        load_yaml_file(tmp_path / "big.yaml", max_bytes=100)
    (tmp_path / "bin.yaml").write_bytes(b"\xff\xfe\x00")
    with pytest.raises(WorkbenchError, match="not UTF-8"):
        load_yaml_file(tmp_path / "bin.yaml")
    with pytest.raises(WorkbenchError, match="cannot read"):
        load_yaml_file(tmp_path / "none.yaml")
