"""New folders that appear whole or not at all, and files with the user's permissions.

:func:`staged_folder` writes into a hidden temp folder beside the target and renames it
into place when the block succeeds (removing it when it fails), so a failed command leaves
no half-written folder; it refuses a target that already holds something.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from workbench.errors import WorkbenchError
from workbench.files import umask


def refuse_existing(target: Path, what: str = "folder") -> None:
    """WorkbenchError if ``target`` exists and is a file or a folder that is not empty."""
    target = Path(target)
    if target.exists() and (not target.is_dir() or any(target.iterdir())):
        raise WorkbenchError(f"{target}: already exists; choose a new {what} (nothing was overwritten)")


@contextmanager
def staged_folder(target: Path, what: str = "folder") -> Iterator[Path]:
    """Yield a temp folder beside ``target``; renamed to ``target`` on success, removed on failure."""
    target = Path(target)
    refuse_existing(target, what)
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(dir=target.parent, prefix=f".{target.name}.", suffix=".tmp"))
    try:
        os.chmod(tmp, 0o777 & ~umask())
        yield tmp
        refuse_existing(target, what)  # someone else may have created it meanwhile
        os.rename(tmp, target)  # an empty target folder is replaced atomically
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
