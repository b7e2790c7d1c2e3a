"""Part of the command line (:mod:`fuzzypos.cli`): the commands that score: ``evaluate`` (a
trajectory against relations or a reference) and ``benchmark`` (every benchmark log)."""

from __future__ import annotations

import json
import warnings
from pathlib import Path
from typing import Annotated

import typer
from rich.progress import TaskID

from .app import JSON, app, err_console, fail, print_warnings, progress_display, wide
from .help import compiling_shown
from .tables import benchmark_table


@app.command()
def evaluate(
    estimate: Annotated[
        Path, typer.Argument(help="the estimated trajectory (TUM)", readable=False)
    ],
    relations: Annotated[
        Path | None,
        typer.Option(
            help="a relations file (t1 t2 x y z roll pitch yaw per line) of the log",
            readable=False,
        ),
    ] = None,
    reference: Annotated[
        Path | None, typer.Option(help="a reference trajectory (TUM)", readable=False)
    ] = None,
    json_out: Annotated[bool, JSON] = False,
) -> None:
    """Score a trajectory against relations and/or a reference trajectory.

    --relations: the benchmark's relations metric over all and local (t2 - t1 <= 10 s)
    relations: mean ± std and median of the translational and rotational errors, and how
    many matched. --reference: the ATE (RMSE after SE(2) alignment) and the RPE over 1 frame
    and over 1 m. Give one of them or both.
    """
    from ..eval.scoring import evaluate_trajectory

    if relations is None and reference is None:
        fail("evaluate needs --relations FILE and/or --reference REF.tum")
    ev = evaluate_trajectory(estimate, relations=relations, reference=reference)
    if json_out:
        typer.echo(json.dumps(ev.as_dict(), indent=2))
        return
    typer.echo(f"{estimate}: {ev.poses} poses")
    if ev.relations is not None:
        typer.echo(f"relations ({relations}):")
        for line in ev.relations.format().splitlines():
            typer.echo(f"  {line}")
    if ev.ate is not None:
        a = ev.ate
        typer.echo(
            f"ATE against {reference}: RMSE {a.rmse_m:.4f} m after SE(2) alignment (mean "
            f"{a.translation_m.mean:.4f} m, heading mean {a.rotation_deg.mean:.3f}°, "
            f"{a.matched} poses matched)"
        )
    for name, rpe in (("RPE over 1 frame", ev.rpe_frame), ("RPE over 1 m", ev.rpe_metre)):
        if rpe is not None:
            typer.echo(
                f"{name}: RMSE {rpe.translation_m.rmse:.4f} m / {rpe.rotation_deg.rmse:.3f}° "
                f"(mean {rpe.translation_m.mean:.4f} m / {rpe.rotation_deg.mean:.3f}°, "
                f"{rpe.pairs} pairs)"
            )
    for note in ev.notes:
        typer.echo(f"note: {note}")


@app.command()
def benchmark(
    data: Annotated[
        Path,
        typer.Option(
            "--data",
            envvar="FUZZYPOS_DATA",
            help="folder searched for NAME.relations with NAME.clf.gz, NAME.clf or NAME.bag "
            "next to it",
            readable=False,
        ),
    ] = Path("../shared/data"),
    out: Annotated[
        Path,
        typer.Option(
            "--out", help="folder for benchmark.json and the runs' results", readable=False
        ),
    ] = Path("results/benchmark"),
    max_scans: Annotated[
        int | None, typer.Option("--max-scans", help="run only the first N scans of each log")
    ] = None,
    json_out: Annotated[bool, typer.Option("--json", help="print the rows as JSON")] = False,
    jobs: Annotated[
        int, typer.Option("--jobs", help="runs at once, each a Ray task (1: one after the other)")
    ] = 1,
    loop_closure: Annotated[
        bool,
        typer.Option(
            "--loop-closure/--no-loop-closure",
            help="also run the default with loop closure: rows for its optimised trajectory "
            "and its online poses (not scored without gtsam)",
        ),
    ] = True,
) -> None:
    """Score the raw odometry, the paper preset, the default and the default with loop
    closure on every benchmark log.

    Every NAME.relations under --data with NAME.clf.gz, NAME.clf or NAME.bag next to it is a
    benchmark log. Prints the relations metric of each run and writes benchmark.json and
    the runs' results folders under --out. On the full shared logs this takes minutes
    (intel has 13,631 scans); --max-scans runs a stretch. --jobs N runs N at once as Ray
    tasks (a local Ray, or RAY_ADDRESS's cluster) where Ray is installed, with the same rows.
    """
    from ..jobs.benchmark import run_benchmark

    if max_scans is not None and max_scans < 1:
        fail(f"--max-scans must be at least 1, got {max_scans}")
    if jobs < 1:
        fail(f"--jobs must be at least 1, got {jobs}")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with progress_display() as progress:
            tasks: dict[str, TaskID] = {}

            def report(name: str, done: int, total: int | None) -> None:
                if name not in tasks:
                    tasks[name] = progress.add_task(name, total=total)
                progress.update(tasks[name], completed=done, total=total)

            result = run_benchmark(
                data, out, max_scans=max_scans, progress=report, jobs=jobs,
                loop_closure=loop_closure,
                compiling=lambda: compiling_shown(err_console, progress),
            )  # fmt: skip
    print_warnings(caught)
    failed = any("error" in r for r in result.data["rows"])
    if json_out:  # a run failed (not bad input): exit 1
        typer.echo(json.dumps(result.data["rows"], indent=2))
        raise typer.Exit(code=1 if failed else 0)
    title = "relations metric" + (f" (first {max_scans} scans of each log)" if max_scans else "")
    table, problems = benchmark_table(result.data["rows"], title, wide().width)
    wide().print(table)
    for line in problems:
        typer.echo(line)
    typer.echo(f"benchmark.json and the runs' results in {result.out_dir}/")
    if failed:  # a run failed (not bad input): exit 1
        raise typer.Exit(code=1)
