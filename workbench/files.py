"""File helpers shared by every layer: atomic text writes, output folders and file digests.

:func:`atomic_write_text` (temp file in the same folder + atomic rename: a reader never sees
half a file, with the permissions the user's :func:`umask` gives), :func:`make_folder` (an output
folder, or one line naming why it cannot be made) and :func:`file_sha256` (streamed SHA-256 of a
file's bytes, for provenance).
"""

from __future__ import annotations

import hashlib
import os
import tempfile
from pathlib import Path

from workbench.errors import WorkbenchError


def umask() -> int:
    """The process umask (e.g. 0o022), read from /proc where it exists so it is never changed."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("Umask:"):
                return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def atomic_write_text(path: Path, text: str) -> Path:
    """Write ``text`` to ``path`` through a temp file in the same folder and an atomic rename
    (permissions as the user's umask gives a new file). A path that cannot be written (a folder,
    a file where a folder should be, no permission) is a WorkbenchError naming it."""
    try:
        for folder in (path.parent, *path.parent.parents):
            if folder.exists() and not folder.is_dir():
                raise NotADirectoryError(20, f"{folder} is a file, not a folder")
        path.parent.mkdir(parents=True, exist_ok=True)
        if path.is_dir():
            raise IsADirectoryError(21, "is a folder")
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    except OSError as exc:
        raise WorkbenchError(f"{path}: cannot write ({exc.strerror or exc})") from None
    try:
        os.fchmod(fd, 0o666 & ~umask())  # mkstemp creates 0600; the file gets the user's usual permissions
        with os.fdopen(fd, "w") as fh:
            fh.write(text)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException as exc:
        Path(tmp).unlink(missing_ok=True)
        if isinstance(exc, OSError):  # disk full, quota
            raise WorkbenchError(f"{path}: cannot write ({exc.strerror or exc})") from None
        raise
    return path


def make_folder(path: Path, what: str = "output folder") -> Path:
    """Create folder ``path`` (and its parents; an existing folder is fine); a file in the way or a
    disk that refuses is a WorkbenchError naming the path (was an OSError traceback)."""
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise WorkbenchError(f"{path}: cannot make the {what} ({exc.strerror or exc})") from None
    return path


def file_sha256(path: str | Path) -> str:
    """SHA-256 hex digest of a file's bytes (streamed)."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()
