"""Part of the command line (:mod:`fuzzypos.cli`): ``batch``, many runs as Ray tasks."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from .app import PRESET, app, console, kept_on_interrupt
from .help import BATCH_HELP, BATCH_OPTIONS


@app.command(help=BATCH_HELP)
def batch(
    paths: Annotated[list[Path], typer.Argument(help="logs or their folders", readable=False)],
    out: Annotated[Path, typer.Option(help="the results' folder", readable=False)] = Path("batch"),
    configs: Annotated[list[Path] | None, typer.Option("--config", help="config TOML")] = None,
    preset: Annotated[str, PRESET] = "default",
    loop_closure: Annotated[bool, BATCH_OPTIONS["loop_closure"]] = False,
    max_scans: Annotated[int | None, typer.Option("--max-scans", help="scans per run")] = None,
    address: Annotated[str | None, typer.Option(help="a Ray cluster to join (auto)")] = None,
    jobs: Annotated[int | None, typer.Option(help="local Ray's CPUs (default all)")] = None,
    force: Annotated[bool, BATCH_OPTIONS["force"]] = False,
    verbose: Annotated[bool, BATCH_OPTIONS["verbose"]] = False,
) -> None:
    from ..jobs.batch import batch_table, progress_bar, run_batch

    kept_on_interrupt(f"the runs finished are in {out / 'batch.json'}")
    with progress_bar(console) as report:
        result = run_batch(paths, out, configs=configs or (), max_scans=max_scans,
            address=address, jobs=jobs, force=force, progress=report, preset=preset,
            loop_closure=loop_closure, verbose=verbose)  # fmt: skip
    console.print(batch_table(result.rows))
    raise typer.Exit(code=1 if result.failed or result.refused else 0)
