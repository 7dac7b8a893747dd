"""``workbench batch``, ``simulate-fleet`` and ``certificate``: fleet-scale work."""

from __future__ import annotations

from pathlib import Path

import typer
from rich.progress import BarColumn, TextColumn

from workbench.cli import err, out, progress_bar, styled
from workbench.cli.run import parse_options


def batch(procedure: str = typer.Argument(..., metavar="PROCEDURE"),
          session_dirs: list[Path] = typer.Argument(..., metavar="SESSION_DIR...", help="Session folders."),
          scheduler: str = typer.Option("local", "--scheduler", help="'local' (a LocalCluster on 127.0.0.1), "
                                                                     "'serial', or tcp://HOST:PORT."),
          workers: int = typer.Option(2, "--workers", min=1, help="Workers of the local cluster."),
          dashboard: bool = typer.Option(False, "--dashboard", help="Start the Dask dashboard (127.0.0.1:8787)."),
          option: list[str] = typer.Option(None, "--option", "-o", help="Analysis option key=value."),
          no_store: bool = typer.Option(False, "--no-store")) -> None:
    """Analyse many sessions in parallel on Dask; results stream into the store; failures are isolated."""
    from workbench.fleet.batch import cluster_client, run_batch
    from workbench.registry import procedure as get_procedure
    from workbench.store import Store

    get_procedure(procedure)  # an unknown procedure fails before a cluster starts
    store = None if no_store else Store()
    opts = parse_options(option)
    with progress_bar(TextColumn("batch", style="bold"), BarColumn(), TextColumn("{task.completed}/{task.total}"),
                      TextColumn("{task.fields[last]}")) as bar:
        task = bar.add_task("batch", total=len(session_dirs), last="")

        def progress(done: int, total: int, outcome: dict) -> None:
            bar.update(task, completed=done, last=("ok " if outcome["ok"] else "FAILED ")
                       + Path(outcome["session_dir"]).name)

        if scheduler == "serial":
            report = run_batch(procedure, session_dirs, None, store, opts, progress, keep_results=False)
        else:
            with cluster_client(scheduler, workers, dashboard) as client:
                report = run_batch(procedure, session_dirs, client, store, opts, progress, keep_results=False)
    out.print(f"{len(report.succeeded)} analysed, {len(report.failures)} failed"
              f"{'; results stored in ' + store.url if store else ''}")
    for f in report.failures:
        out.print(styled("failed:", "red", f" {f['session_dir']}: {f['error']}"), highlight=False)
    if report.failures:
        raise typer.Exit(1)


def simulate_fleet_cmd(grade: str = typer.Option(..., "--grade", help="Grade name or fixture path."),
                       units: int = typer.Option(..., "--units", min=1, help="Number of units."),
                       procedure: str = typer.Option(..., "--procedure"),
                       out_dir: Path = typer.Option(..., "--out"),
                       seed: int = typer.Option(1, "--seed", min=0, help="Seed of the first unit; unit k uses seed + k."),
                       option: list[str] = typer.Option(None, "--option", "-o", help="Sequence option key=value.")
                       ) -> None:
    """Record a procedure for N simulated units of one grade (one session folder per unit)."""
    from workbench.fleet.simulate import simulate_fleet

    with progress_bar(TextColumn("simulate", style="bold"), BarColumn(),
                      TextColumn("{task.completed}/{task.total}")) as bar:
        task = bar.add_task("simulate", total=units)
        dirs = simulate_fleet(grade, units, procedure, out_dir, seed, options=parse_options(option),
                              progress=lambda k, n, d: bar.update(task, completed=k))
    out.print(f"{len(dirs)} sessions under {out_dir}")


def certificate(set_id: str = typer.Argument(..., metavar="SET_ID"),
                out_file: Path = typer.Option(Path("certificate.html"), "--out"),
                pdf: bool = typer.Option(True, "--pdf/--no-pdf", help="Also print a PDF with Chromium if present.")
                ) -> None:
    """Render the calibration certificate of a stored set (HTML, and PDF where Chromium exists)."""
    import time

    from workbench.fleet.certificate import write_certificate
    from workbench.store import Store

    store = Store()
    cal = store.get_set(set_id)
    t0 = time.monotonic()
    with err.status(f"certificate of {cal.unit.serial}: reading the store") as status:
        paths = write_certificate(cal, store, out_file, pdf, progress=lambda msg: status.update(
            f"certificate of {cal.unit.serial}: {msg} ({time.monotonic() - t0:.1f} s)"))
    for path in paths:
        out.print(f"wrote {path}", soft_wrap=True)
    out.print(f"certificate rendered in {time.monotonic() - t0:.1f} s")


def register(app: typer.Typer) -> None:
    app.command("batch")(batch)
    app.command("simulate-fleet")(simulate_fleet_cmd)
    app.command("certificate")(certificate)
