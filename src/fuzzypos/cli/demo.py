"""Part of the command line (:mod:`fuzzypos.cli`): the commands without a log: ``demo`` (the
paper's experiment, simulated), ``simulate`` (a simulated CARMEN log) and ``config``."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Annotated

import typer
from rich.progress import Progress
from rich.table import Table

from .._version import __version__
from ..config import Config
from ..config.docs import settings_lines, settings_markdown
from .app import CONFIG_FILE, PRESET, app, console, err_console, fail, load_config
from .help import compiling_shown


@app.command()
def demo(
    out: Annotated[
        Path, typer.Option(help="folder for the figures and summary.json", readable=False)
    ] = Path("demo-output"),
    seed: Annotated[int, typer.Option(help="random seed of the simulation")] = 0,
    laps: Annotated[float, typer.Option(help="laps of the 4 m circle")] = 2.0,
) -> None:
    """The paper's experiment, simulated, with its figures.

    A robot drives a circle in a gym on a slippery floor (the truth is a spiral, odometry
    believes in the circle); positions it with the default configuration and the paper
    preset; writes the paper's Figs. 13–20 and summary.json.
    """
    console.print(f"fuzzypos demo: simulating {laps:g} laps of a 4 m circle in a gym, positioning "
        f"with the paper preset and the default; figures into {out}/", highlight=False)  # fmt: skip
    from ..jobs.demo import DemoSettings, run_demo
    from ..pipeline.warm import compile_kernels

    settings = DemoSettings(seed=seed, laps=laps)
    compile_kernels(Config(), lambda: compiling_shown(err_console))
    with Progress(console=console, transient=True) as progress:
        tasks: dict[str, object] = {}

        def report(name: str, k: int, n: int) -> None:
            if name not in tasks:
                tasks[name] = progress.add_task(f"{name:>8}", total=n)
            progress.update(tasks[name], completed=k)  # type: ignore[arg-type]

        t0 = time.perf_counter()
        result = run_demo(out, settings, progress=report)
        seconds = time.perf_counter() - t0
    summary = result.summary
    console.print(
        f"fuzzypos {__version__} demo: {summary['scans']} scans, "
        f"{summary['distance_travelled_m']:.1f} m along the true path ({result.run.path.name} in "
        f"the {result.run.world.name}, seed {seed}); {seconds:.1f} s"
    )
    table = Table(title="position error against the simulated truth")
    for col in ("", "final (m)", "mean (m)", "max (m)", "mean heading (°)", "degraded"):
        table.add_column(col, justify="right")
    for name in ("odometry", "paper", "default"):
        e = result.errors[name]
        table.add_row(
            name,
            f"{e.final_position_error_m:.3f}",
            f"{e.mean_position_error_m:.3f}",
            f"{e.max_position_error_m:.3f}",
            f"{e.mean_heading_error_deg:.2f}",
            str(e.scans_degraded),
        )
    console.print(table)
    console.print(f"figures and summary.json in {out}/")


@app.command()
def simulate(
    out: Annotated[
        Path,
        typer.Option("--out", "-o", help="the CARMEN log to write (.gz: gzipped)", readable=False),
    ],
    tum: Annotated[
        Path | None, typer.Option(help="also write the true trajectory as TUM", readable=False)
    ] = None,
    world: Annotated[
        str,
        typer.Option(help="gym, office, furnished_room, rectangular_room, or a world file"),
    ] = "gym",
    path: Annotated[
        str, typer.Option(help="circle, square, figure8, or waypoints 'x,y;x,y;…' (m)")
    ] = "circle",
    size: Annotated[
        float, typer.Option(help="the circle's or figure eight's radius, the square's side (m)")
    ] = 4.0,
    laps: Annotated[float, typer.Option(help="laps of the path")] = 1.0,
    speed: Annotated[float, typer.Option(help="m/s")] = 0.3,
    seed: Annotated[int, typer.Option(help="random seed")] = 0,
) -> None:
    """Simulate a run and write it as a CARMEN log.

    FLASER lines carry the odometry, TRUEPOS lines the truth, as CARMEN's own simulator does.
    """
    from .. import sim
    from ..io import CarmenRecord, write_carmen, write_tum
    from ..jobs.demo import DemoSettings

    w = sim.world_by_name(world) if world in sim.WORLD_NAMES else sim.World.from_file(world)
    builders = {"circle": sim.CommandedPath.circle, "figure8": sim.CommandedPath.figure8}
    if ";" in path or "," in path:
        try:
            points = [tuple(float(v) for v in p.split(",")) for p in path.split(";") if p.strip()]
        except ValueError:
            points = []
        if len(points) < 2 or any(len(p) != 2 for p in points):
            fail(f"--path {path!r}: waypoints are 'x,y;x,y;…' with at least two points")
        commanded = sim.CommandedPath.waypoints(points, speed=speed)
    elif path == "square":
        commanded = sim.CommandedPath.square(size, laps=max(1, round(laps)), speed=speed)
    elif path in builders:
        commanded = builders[path](size, laps=laps, speed=speed)
    else:
        fail(f"unknown path {path!r}; known: circle, square, figure8, or waypoints 'x,y;x,y'")
    run = sim.simulate_run(w, commanded, DemoSettings().scanner, sim.SlipModel(), seed)
    records = (
        CarmenRecord(scan, run.odometry_pose(k), run.true_pose(k))
        for k, scan in enumerate(run.scans)
    )
    n = write_carmen(
        out,
        records,
        header_comment=f"fuzzypos simulate: {commanded.name} in {w.name}, seed {seed}",
    )
    if tum is not None:
        write_tum(tum, run.stamps, run.true_poses)
    console.print(f"{n} scans written to {out}" + (f", the truth to {tum}" if tum else ""))


@app.command()
def config(
    preset: Annotated[str, PRESET] = "default",
    config_file: Annotated[Path | None, CONFIG_FILE] = None,
    reasons: Annotated[
        bool, typer.Option(help="print the reason for every setting instead")
    ] = False,
    markdown: Annotated[
        bool,
        typer.Option(
            help="print every setting's default, unit, bounds and reason as markdown "
            "(docs/configuration.md)"
        ),
    ] = False,
) -> None:
    """Print a configuration as TOML (or why each value is what it is)."""
    cfg = load_config(preset, config_file)
    if markdown:
        typer.echo(settings_markdown(), nl=False)
        return
    if reasons:
        for line in settings_lines():
            typer.echo(line)
        return
    typer.echo(cfg.to_toml())
