"""Names from user input made safe: path components, files confined to a folder, format templates.

- :func:`safe_component`: a serial or name that becomes one path component (a safe character
  set, no ``..``, no separators).
- :func:`confined_path`: a relative file name from a profile or an upload, resolved inside a
  base folder (no absolute paths, no ``..``, no symlink out of the folder).
- :func:`plain_template`: a ``str.format`` template whose fields are plain names (no
  ``{x.attr}`` / ``{x[0]}`` access to Python objects), optionally from an allowed set.
- :func:`plain_line`: free text (a unit's model) that stays one line of printable characters,
  so it cannot add lines to a parameter file or a header an export writes it into.
- :func:`name_problems`: which of those rules a calibration set's id, serial and model break (a set
  stored before them is read with a warning, never exported).
"""

from __future__ import annotations

import re
import string
from collections.abc import Iterable
from pathlib import Path, PurePosixPath, PureWindowsPath

from workbench.errors import WorkbenchError

SAFE_COMPONENT = re.compile(r"[A-Za-z0-9][A-Za-z0-9._+-]{0,63}")
PLAIN_LINE_MAX = 200  # characters of a free-text field (a unit's model)
# line breaks, tabs, escapes, C1 controls; and the invisible format characters that reorder or hide text
# where it is shown (bidirectional overrides and isolates, zero-width characters, the BOM): a model
# 'm\u202eevil' reads backwards in a certificate or a C comment
CONTROL = re.compile(r"[\x00-\x1f\x7f-\x9f\u2028\u2029\u200b-\u200f\u202a-\u202e\u2060-\u2069\ufeff]")


def safe_component(text: str, what: str = "name", error: type[WorkbenchError] = WorkbenchError) -> str:
    """``text`` if it is 1-64 of ``A-Z a-z 0-9 . _ + -`` starting with a letter or digit, else ``error``."""
    if not isinstance(text, str) or not SAFE_COMPONENT.fullmatch(text) or ".." in text:
        raise error(f"{what} {text!r}: use 1-64 letters, digits and . _ + - (starting with a letter or digit)")
    return text


def plain_line(text: str, what: str = "text", error: type[WorkbenchError] = WorkbenchError) -> str:
    """``text`` if it is a string of at most :data:`PLAIN_LINE_MAX` characters with no control
    character or line break, else ``error`` naming ``what``."""
    if not isinstance(text, str) or len(text) > PLAIN_LINE_MAX or CONTROL.search(text):
        shown = text[:40] if isinstance(text, str) else text
        raise error(f"{what} {shown!r}: expected one line of at most {PLAIN_LINE_MAX} printable characters")
    return text


def confined_path(base: Path, name: str, what: str = "file",
                  error: type[WorkbenchError] = WorkbenchError) -> Path:
    """``base / name`` for a relative ``name`` that stays inside ``base`` (after resolving symlinks)."""
    if not isinstance(name, str) or not name or "\x00" in name:
        raise error(f"{what} {name!r}: expected a file name")
    for pure in (PurePosixPath(name), PureWindowsPath(name)):
        if pure.is_absolute() or pure.anchor or ".." in pure.parts:
            raise error(f"{what} {name!r}: must be a file inside {base} (no absolute path, no '..')")
    root = Path(base).resolve()
    path = (root / name).resolve()
    if path != root and root not in path.parents:
        raise error(f"{what} {name!r}: resolves outside {base}")
    return path


def plain_template(template: str, allowed: Iterable[str] | None = None, what: str = "template",
                   error: type[WorkbenchError] = WorkbenchError) -> str:
    """``template`` if every ``{field}`` is a plain name (and in ``allowed`` when given), else ``error``."""
    try:
        names = [f for _, f, _, _ in string.Formatter().parse(template) if f is not None]
    except (ValueError, TypeError) as exc:
        raise error(f"{what} {template!r}: not a format template ({exc})") from None
    allowed = None if allowed is None else set(allowed)
    for n in names:
        if not n.isidentifier():
            raise error(f"{what} {template!r}: field {{{n}}} is not a plain name")
        if allowed is not None and n not in allowed:
            raise error(f"{what} {template!r}: unknown field {{{n}}} (known: {', '.join(sorted(allowed))})")
    return template


def name_problems(set_id, serial, model, source: str) -> list[str]:
    """One line per rule broken by a calibration set's ``id`` and ``unit.serial`` (:func:`safe_component`)
    and ``unit.model`` (:func:`plain_line`), each naming ``source`` and the key: they name store keys and
    go verbatim into exports (a C header, parameter files), where a line break or ``*/`` could add a
    #define or a parameter line. Empty when the set could be written today."""
    from workbench.errors import CalibrationFormatError

    out = []
    for check, value, key in ((safe_component, set_id, "id"), (safe_component, serial, "unit.serial"),
                              (plain_line, model, "unit.model")):
        try:
            check(value, f"{source}: {key}", CalibrationFormatError)
        except CalibrationFormatError as exc:
            out.append(str(exc))
    return out
