"""Saving a procedure's figures: each drawn once, half of them in a forked process when there are many.

:func:`save_figures` writes ``<name>.png`` for each figure into a folder (a temporary file
renamed, so a reader never sees half a PNG) and closes the figures. With :data:`MANY` figures
or more and a second CPU, a forked child draws every other figure while this process draws the
rest: the child inherits the figures as they are in memory, so nothing is pickled or drawn
twice, and each PNG holds the same bytes as when the figures are drawn one after the other
(Agg is deterministic). Inside a worker process of :mod:`workbench.workers` (a daemon, which
may not fork) the figures are drawn in order; the campaign spreads them over its workers itself.
"""

from __future__ import annotations

import multiprocessing as mp
from collections.abc import Iterable, Mapping
from pathlib import Path

from workbench.errors import WorkbenchError
from workbench.workers import usable_workers

MANY = 4  # figures from which a second process draws half of them
DPI = 110  # dots per inch of every saved figure


def prepare_drawing() -> None:
    """Load what the first figure saved in a process loads: the Agg renderer, the PNG writer, the default
    font and the mathtext parser (log-axis tick labels). Called before worker processes fork, they
    share it instead of each loading it."""
    import PIL.Image
    from matplotlib.backends.backend_agg import RendererAgg
    from matplotlib.font_manager import FontProperties

    PIL.Image.preinit()
    renderer = RendererAgg(1, 1, DPI)
    renderer.get_text_width_height_descent("0", FontProperties(), ismath=False)
    renderer.get_text_width_height_descent(r"$\mathdefault{10^{0}}$", FontProperties(), ismath=True)


def _save(figures: Mapping, fig_dir: Path, names: Iterable[str]) -> None:
    for name in names:
        tmp = fig_dir / f".{name}.tmp.png"
        figures[name].savefig(tmp, dpi=DPI)  # laid out once when drawn (layout.FittedMargins), not re-fitted here
        tmp.replace(fig_dir / f"{name}.png")


def _child(figures: Mapping, fig_dir: Path, names: list[str], conn) -> None:
    from workbench.workers import _portable, fresh_std_streams

    fresh_std_streams()
    try:
        _save(figures, fig_dir, names)
    except BaseException as exc:  # noqa: BLE001 - sent to the parent, which raises it as one line
        conn.send(_portable(exc))
    else:
        conn.send(None)
    conn.close()


def save_figures(figures: Mapping, fig_dir: Path, names: Iterable[str] | None = None,
                 workers: int | None = None) -> list[Path]:
    """Save ``figures`` ({name: matplotlib Figure}; only ``names`` of them if given) as ``fig_dir/<name>.png``.

    Every figure of ``figures`` is closed afterwards. ``workers``: processes to draw with
    (default :func:`workbench.workers.usable_workers`); two are used from :data:`MANY` figures on.
    Returns the paths written, in the order of ``names``.
    """
    import matplotlib.pyplot as plt

    names = list(figures) if names is None else list(names)
    fig_dir = Path(fig_dir)
    fig_dir.mkdir(parents=True, exist_ok=True)
    n = usable_workers(2) if workers is None else workers
    try:
        if len(names) >= MANY and n >= 2 and not mp.current_process().daemon:
            mine, theirs = names[0::2], names[1::2]
            ctx = mp.get_context("fork")
            here, there = ctx.Pipe(duplex=False)
            child = ctx.Process(target=_child, args=(figures, fig_dir, theirs, there), name="workbench-figures")
            child.start()
            there.close()
            try:
                _save(figures, fig_dir, mine)
            finally:
                try:
                    failure = here.recv()
                except EOFError:  # the child stopped before it could answer: see its exit code
                    failure = None
                child.join()
            if failure is not None:
                raise failure
            if child.exitcode != 0:
                raise WorkbenchError(f"{fig_dir}: the process drawing {', '.join(theirs)} stopped "
                                     f"(exit code {child.exitcode})")
        else:
            _save(figures, fig_dir, names)
    finally:
        for fig in figures.values():
            plt.close(fig)
    return [fig_dir / f"{name}.png" for name in names]
