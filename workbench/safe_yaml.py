"""YAML documents read with limits: size, alias expansion, nesting.

``yaml.safe_load`` shares aliased nodes, so a 1 KB "billion laughs" document loads quickly
and then exhausts memory in whatever walks it (validation, JSON, a copy). Here a document
is refused before it is turned into Python objects when it is larger than ``max_bytes``, its
nodes expanded through every alias number more than ``max_nodes``, an alias is recursive,
or it nests too deep. Public: :func:`load_yaml_text`, :func:`load_yaml_file`,
:data:`MAX_BYTES`, :data:`MAX_NODES`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from workbench.errors import WorkbenchError

MAX_BYTES = 1 << 20  # a configuration or profile is a few KB; 1 MiB is generous
MAX_NODES = 100_000  # nodes after alias expansion


def _expanded_nodes(root: yaml.Node, limit: int, source: str, error: type[WorkbenchError]) -> int:
    """Node count of ``root`` with every alias expanded (memoised on the shared nodes)."""
    sizes: dict[int, int] = {}
    active: set[int] = set()
    stack: list[tuple[yaml.Node, bool]] = [(root, False)]
    while stack:
        node, done = stack.pop()
        key = id(node)
        children = [] if isinstance(node, yaml.ScalarNode) else (
            node.value if isinstance(node, yaml.SequenceNode) else [n for kv in node.value for n in kv])
        if done:
            active.discard(key)
            sizes[key] = 1 + sum(sizes[id(c)] for c in children)
            if sizes[key] > limit:
                raise error(f"{source}: YAML document expands to more than {limit} nodes through its aliases")
            continue
        if key in sizes:
            continue
        if key in active:
            raise error(f"{source}: YAML document has a recursive alias")
        active.add(key)
        stack.append((node, True))
        stack.extend((c, False) for c in children if id(c) not in sizes)
    return sizes[id(root)]


def load_yaml_text(text: str, source: str, max_bytes: int = MAX_BYTES, max_nodes: int = MAX_NODES,
                   error: type[WorkbenchError] = WorkbenchError) -> Any:
    """Parse one YAML document (safe types only) within the limits; ``error`` names ``source``."""
    if len(text.encode("utf-8", "surrogatepass")) > max_bytes:
        raise error(f"{source}: YAML document larger than {max_bytes} bytes")
    try:
        loader = yaml.SafeLoader(text)
    except yaml.YAMLError as exc:  # characters YAML does not allow
        raise error(f"{source}: not valid YAML ({' '.join(str(exc).split())})") from None
    try:
        node = loader.get_single_node()
        if node is None:
            return None
        _expanded_nodes(node, max_nodes, source, error)
        return loader.construct_document(node)
    except yaml.YAMLError as exc:
        raise error(f"{source}: not valid YAML ({' '.join(str(exc).split())})") from None
    except RecursionError:
        raise error(f"{source}: YAML document nests too deep") from None
    finally:
        loader.dispose()


def load_yaml_file(path: Path, max_bytes: int = MAX_BYTES, max_nodes: int = MAX_NODES,
                   error: type[WorkbenchError] = WorkbenchError) -> Any:
    """Read and parse the YAML file ``path`` within the limits (size checked before reading)."""
    path = Path(path)
    try:
        if path.stat().st_size > max_bytes:
            raise error(f"{path}: YAML document larger than {max_bytes} bytes")
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise error(f"{path}: not UTF-8 text (byte {exc.start})") from None
    except OSError as exc:
        raise error(f"{path}: cannot read ({exc.strerror})") from None
    return load_yaml_text(text, str(path), max_bytes, max_nodes, error)
