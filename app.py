"""The lab dashboard: ``streamlit run app.py`` (store from ``WORKBENCH_DB``, default ./workbench.db).

Pages are the scripts ``dashboard/pages/NN_name.py``, ordered by ``NN``; a page's title is its
``TITLE = "..."`` constant when it has one, else its file name (``40_allan`` -> ``Allan``).
"""

from __future__ import annotations

import re
from pathlib import Path

import streamlit as st

from dashboard import auth

PAGES_DIR = Path(__file__).resolve().parent / "dashboard" / "pages"
_NAME = re.compile(r"^(\d+)_(\w+)\.py$")
_TITLE = re.compile(r"^TITLE\s*(?::\s*str\s*)?=\s*[\"'](.+?)[\"']\s*$", re.MULTILINE)


def discover(pages_dir: Path = PAGES_DIR) -> list[tuple[int, str, str, Path]]:
    """(order, url name, title, path) of every ``NN_name.py`` page, sorted by ``NN``."""
    found = []
    for path in pages_dir.glob("*.py"):
        m = _NAME.match(path.name)
        if not m:
            continue
        title = _TITLE.search(path.read_text(errors="replace"))
        name = m.group(2)
        found.append((int(m.group(1)), name,
                      title.group(1) if title else name.replace("_", " ").capitalize(), path))
    return sorted(found)


def main() -> None:
    st.set_page_config(page_title="Calibration workbench", page_icon="🧭", layout="wide")
    auth.gate()  # before any page: 127.0.0.1 only, or a signed-in operator (dashboard/auth.py)
    found = discover()
    if not found:
        st.error(f"No dashboard pages in {PAGES_DIR}")
        return
    pages = [st.Page(path, title=title, url_path=name, default=(i == 0))
             for i, (_, name, title, path) in enumerate(found)]
    st.navigation(pages).run()


if __name__ == "__main__":  # streamlit runs the script as __main__; tests import discover()
    main()
