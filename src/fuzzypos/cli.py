"""The ``fuzzypos`` command line: a thin typer layer over the library.

Library errors (``ValueError`` subclasses, ``OSError``) become one-line messages and exit
code 2; nothing here does work the library could do.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import numpy as np
import typer
from rich.console import Console
from rich.progress import Progress
from rich.table import Table

from . import __version__
from .config import Config, ConfigError
from .geometry import Pose2D, relative
from .positioner import Positioner
from .sim import ScannerModel, arc_path, drifting_odometry, furnished_room, simulate_scans

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


@dataclass(frozen=True)
class _Errors:
    final: float
    mean: float
    max: float
    mean_heading_deg: float
    degraded: int


def _errors(truth: list[Pose2D], est: list[Pose2D], degraded: int) -> _Errors:
    t = np.array([p.as_array() for p in truth])
    e = np.array([p.as_array() for p in est])
    d = np.hypot(*(t[:, :2] - e[:, :2]).T)
    dh = np.abs(np.degrees(np.angle(np.exp(1j * (t[:, 2] - e[:, 2])))))
    return _Errors(float(d[-1]), float(d.mean()), float(d.max()), float(dh.mean()), degraded)


@app.command()
def demo(
    scans: int = typer.Option(150, help="number of scans to simulate"),
    seed: int = typer.Option(0, help="random seed (noise and odometry)"),
    noise: float = typer.Option(0.01, help="range noise standard deviation, metres"),
) -> None:
    """Simulate a robot driving an arc in a furnished room and position it from its scans."""
    if scans < 2:
        _fail(f"--scans must be at least 2, got {scans}")
    world = furnished_room(0)
    scanner = ScannerModel(n_beams=180, range_max=8.0, range_noise_std=noise)
    rng = np.random.default_rng(seed)
    truth = arc_path(Pose2D(-1.5, -1.0, 0.3), scans, step=0.02, turn_deg=0.6)
    # odometry that over-reads distance by 3% and turns 0.15° too much per scan, with noise
    odom = drifting_odometry(truth, scale=1.03, rotation_bias_deg=0.15, noise_std=(0.002, 0.05), rng=rng)
    sim_scans = simulate_scans(world, truth, scanner, rng=rng, stamps=[0.1 * k for k in range(scans)])
    console.print(
        f"fuzzypos {__version__} demo: {scans} scans of {scanner.n_beams} beams in "
        f"{world.name}, {noise * 100:.1f} cm range noise, odometry +3 % distance and "
        "+0.15°/scan heading drift"
    )
    results: dict[str, tuple[_Errors, float, float]] = {}
    with Progress(console=console, transient=True) as progress:
        for name in ("paper", "default"):
            pos = Positioner(Config.preset(name))
            task = progress.add_task(f"{name:>8}", total=scans)
            ests = []
            t0 = time.perf_counter()
            for s, o in zip(sim_scans, odom):
                ests.append(pos.update(s, o))
                progress.advance(task)
            dt = time.perf_counter() - t0
            n_feat = float(np.mean([len(e.features.points_of_interest) for e in ests if e.features]))
            deg = sum(e.degraded for e in ests)
            results[name] = (_errors(truth, [e.pose for e in ests], deg), scans / dt, n_feat)
    odo_err = _errors(truth, odom, 0)
    table = Table(title="position error against the simulated truth")
    for col in ("", "final (m)", "mean (m)", "max (m)", "mean heading (°)", "degraded", "scans/s"):
        table.add_column(col, justify="right")
    table.add_row("odometry", f"{odo_err.final:.3f}", f"{odo_err.mean:.3f}", f"{odo_err.max:.3f}",
                  f"{odo_err.mean_heading_deg:.2f}", "0", "")
    for name, (err, rate, _) in results.items():
        table.add_row(name, f"{err.final:.3f}", f"{err.mean:.3f}", f"{err.max:.3f}",
                      f"{err.mean_heading_deg:.2f}", str(err.degraded), f"{rate:.0f}")
    console.print(table)
    dist = sum(math.hypot(*relative(truth[k - 1].as_array(), truth[k].as_array())[:2]) for k in range(1, scans))
    console.print(
        f"distance travelled {dist:.2f} m; feature points per scan: "
        f"{results['default'][2]:.1f} (default), {results['paper'][2]:.1f} (paper)"
    )


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
