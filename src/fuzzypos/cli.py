"""The ``fuzzypos`` command line: a thin typer layer over the library.

Library errors (``ValueError`` subclasses, ``OSError``) become one-line messages and exit
code 2; nothing here does work the library could do.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Optional

import typer
from rich.console import Console
from rich.progress import Progress
from rich.table import Table

from . import __version__
from .config import Config, ConfigError

app = typer.Typer(add_completion=False, no_args_is_help=True, help="Fuzzy-based positioning from 2D laser scans and odometry.")
console = Console()


def _fail(message: str) -> None:
    typer.echo(f"fuzzypos: error: {message}", err=True)
    raise typer.Exit(code=2)


def _load_config(preset: str, config: Optional[Path]) -> Config:
    try:
        base = Config.preset(preset)
        if config is None:
            return base
        return Config.from_dict(_read_toml(config), base=base, source=str(config))
    except ConfigError as exc:
        _fail(str(exc))
        raise  # unreachable


def _read_toml(path: Path) -> dict:
    import sys

    if sys.version_info >= (3, 11):
        import tomllib
    else:  # pragma: no cover
        import tomli as tomllib
    try:
        return tomllib.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read config: {exc.strerror or exc}") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{path}: invalid TOML: {exc}") from None


@app.command()
def demo(
    out: Path = typer.Option(Path("demo-output"), help="folder for the figures and summary.json"),
    seed: int = typer.Option(0, help="random seed of the simulation"),
    laps: float = typer.Option(2.0, help="laps of the 4 m circle"),
) -> None:
    """The paper's experiment, simulated: a robot drives a circle in a gym on a slippery floor
    (the truth is a spiral, odometry believes in the circle); positions it with the default
    configuration and the paper preset; writes the paper's Figs. 13–20 and summary.json."""
    from .demo import DemoSettings, run_demo

    settings = DemoSettings(seed=seed, laps=laps)
    try:
        with Progress(console=console, transient=True) as progress:
            tasks: dict[str, object] = {}

            def report(name: str, k: int, n: int) -> None:
                if name not in tasks:
                    tasks[name] = progress.add_task(f"{name:>8}", total=n)
                progress.update(tasks[name], completed=k)  # type: ignore[arg-type]

            t0 = time.perf_counter()
            result = run_demo(out, settings, progress=report)
            seconds = time.perf_counter() - t0
    except (ValueError, OSError) as exc:
        _fail(str(exc))
        return
    summary = result.summary
    console.print(
        f"fuzzypos {__version__} demo: {summary['scans']} scans, {summary['distance_travelled_m']:.1f} m "
        f"along the true path ({result.run.path.name} in the {result.run.world.name}, seed {seed}); "
        f"{seconds:.1f} s"
    )
    table = Table(title="position error against the simulated truth")
    for col in ("", "final (m)", "mean (m)", "max (m)", "mean heading (°)", "degraded"):
        table.add_column(col, justify="right")
    for name in ("odometry", "paper", "default"):
        e = result.errors[name]
        table.add_row(
            name, f"{e.final_position_error_m:.3f}", f"{e.mean_position_error_m:.3f}",
            f"{e.max_position_error_m:.3f}", f"{e.mean_heading_error_deg:.2f}", str(e.scans_degraded),
        )
    console.print(table)
    console.print(f"figures and summary.json in {out}/")


@app.command()
def simulate(
    out: Path = typer.Option(..., "--out", "-o", help="the CARMEN log to write (.gz: gzipped)"),
    tum: Optional[Path] = typer.Option(None, help="also write the true trajectory as TUM"),
    world: str = typer.Option("gym", help="gym, office, furnished_room, rectangular_room, or a world file"),
    path: str = typer.Option("circle", help="circle, square, figure8, or waypoints 'x,y;x,y;…' (m)"),
    size: float = typer.Option(4.0, help="the circle's or figure eight's radius, the square's side (m)"),
    laps: float = typer.Option(1.0, help="laps of the path"),
    speed: float = typer.Option(0.3, help="m/s"),
    seed: int = typer.Option(0, help="random seed"),
) -> None:
    """Simulate a run and write it as a CARMEN log: FLASER lines carry the odometry, TRUEPOS
    lines the truth, as CARMEN's own simulator does."""
    from . import sim
    from .demo import DemoSettings
    from .io import CarmenRecord, write_carmen, write_tum

    try:
        w = sim.world_by_name(world) if world in sim.WORLD_NAMES else sim.World.from_file(world)
        builders = {"circle": sim.CommandedPath.circle, "figure8": sim.CommandedPath.figure8}
        if ";" in path or "," in path:
            try:
                points = [tuple(float(v) for v in p.split(",")) for p in path.split(";") if p.strip()]
            except ValueError:
                points = []
            if len(points) < 2 or any(len(p) != 2 for p in points):
                _fail(f"--path {path!r}: waypoints are 'x,y;x,y;…' with at least two points")
                return
            commanded = sim.CommandedPath.waypoints(points, speed=speed)
        elif path == "square":
            commanded = sim.CommandedPath.square(size, laps=max(1, round(laps)), speed=speed)
        elif path in builders:
            commanded = builders[path](size, laps=laps, speed=speed)
        else:
            _fail(f"unknown path {path!r}; known: circle, square, figure8, or waypoints 'x,y;x,y'")
            return
        run = sim.simulate_run(w, commanded, DemoSettings().scanner, sim.SlipModel(), seed)
        records = (
            CarmenRecord(scan, run.odometry_pose(k), run.true_pose(k)) for k, scan in enumerate(run.scans)
        )
        n = write_carmen(out, records, header_comment=f"fuzzypos simulate: {commanded.name} in {w.name}, seed {seed}")
        if tum is not None:
            write_tum(tum, run.stamps, run.true_poses)
    except (ValueError, OSError) as exc:
        _fail(str(exc))
        return
    console.print(f"{n} scans written to {out}" + (f", the truth to {tum}" if tum else ""))


@app.command()
def config(
    preset: str = typer.Option("default", help="base configuration: default or paper"),
    config_file: Optional[Path] = typer.Option(None, "--config", help="TOML file overriding keys"),
    reasons: bool = typer.Option(False, help="print the reason for every setting instead"),
) -> None:
    """Print a configuration as TOML (or why each value is what it is)."""
    cfg = _load_config(preset, config_file)
    if reasons:
        for key, why in Config.reasons().items():
            typer.echo(f"{key}: {why}")
        return
    typer.echo(cfg.to_toml())


@app.command("plot-scan")
def plot_scan(
    log: Path = typer.Argument(..., help="a CARMEN log (plain or gzipped)"),
    index: int = typer.Option(..., "--index", "-n", help="the scan to plot, 0-based"),
    out: Optional[Path] = typer.Option(None, help="folder for the figures (default: plots/<log>-scan<N>/)"),
    preset: str = typer.Option("default", help="base configuration: default or paper"),
    config_file: Optional[Path] = typer.Option(None, "--config", help="TOML file overriding keys"),
) -> None:
    """Draw the paper's Figs. 13–18 (filtering … virtual angular points) for one scan of a log."""
    from .features import extract_features
    from .io import read_carmen
    from .plot import plot_feature_figures

    cfg = _load_config(preset, config_file)
    if index < 0:
        _fail(f"--index must be 0 or more, got {index}")
    try:
        record, count = None, 0
        for rec in read_carmen(log):
            if count == index:
                record = rec
                break
            count += 1
        if record is None:
            _fail(f"{log}: has no scan {index} (it has {count} scans)")
            return
        features = extract_features(record.scan, cfg)
        folder = out if out is not None else Path("plots") / f"{log.name}-scan{index}"
        written = plot_feature_figures(features, folder, index)
    except (ValueError, OSError) as exc:
        _fail(str(exc))
        return
    for number, path in sorted(written.items()):
        console.print(f"Fig. {number}: {path}")


def main() -> None:  # pragma: no cover - console entry point
    app()
