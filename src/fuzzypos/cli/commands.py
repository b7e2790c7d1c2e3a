"""The ``fuzzypos`` command line: a thin typer layer over the library.

Library errors (``ValueError`` subclasses, ``OSError``) become one-line messages and exit
code 2; nothing here does work the library could do.
"""

from __future__ import annotations

import json
import re
import time
import warnings
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, NoReturn

import typer
from rich.console import Console
from rich.progress import Progress, TaskID
from rich.table import Table

from .._version import __version__
from ..config import Config, ConfigError
from ..config.docs import settings_lines, settings_markdown
from .help import (
    BATCH_HELP,
    BATCH_OPTIONS,
    RUN_OPTIONS,
    VERSION,
    Group,
    compiling_shown,
    finish_commands,
)
from .tables import (
    bag_alone,
    bag_overview,
    bag_tables,
    benchmark_table,
    log_table,
    loop_closure_lines,
    relations_line,
)

if TYPE_CHECKING:
    from ..io import OpenLog


app = typer.Typer(
    cls=Group,
    add_completion=False,
    no_args_is_help=True,
    help="Fuzzy-based positioning from 2D laser scans and odometry.",
)
console = Console()


@app.callback()
def _main(version: Annotated[bool, VERSION] = False) -> None:
    pass


def _fail(message: str, code: int = 2) -> NoReturn:
    typer.echo(f"fuzzypos: error: {message}", err=True)
    raise typer.Exit(code=code)


def _load_config(preset: str, config: Path | None) -> Config:
    """``--preset``, overridden by ``--config``, loaded as ``Config.from_toml`` loads a file.

    A ``preset = "..."`` line in the file picks the base unless ``--preset`` names another
    than the default (then the two must agree). Keys of older files are read with a warning.
    """
    try:
        base = Config.preset(preset)
        if config is None:
            return base
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", FutureWarning)
            data = _read_toml(config)
            cfg = Config.from_dict(
                data, base=None if preset == "default" else base, source=str(config)
            )
        for w in caught:
            if issubclass(w.category, FutureWarning):
                typer.echo(f"fuzzypos: warning: {w.message}", err=True)
            else:  # pragma: no cover - nothing else warns while loading
                warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
        return cfg
    except ConfigError as exc:
        _fail(str(exc))


def _read_toml(path: Path) -> dict:
    """The parsed file, as ``Config.from_toml`` reads it (errors name the file)."""
    from ..config.schema import read_toml

    return read_toml(path)


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
    try:
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
    except (ValueError, OSError) as exc:
        _fail(_error_text(exc))
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

    try:
        w = sim.world_by_name(world) if world in sim.WORLD_NAMES else sim.World.from_file(world)
        builders = {"circle": sim.CommandedPath.circle, "figure8": sim.CommandedPath.figure8}
        if ";" in path or "," in path:
            try:
                points = [
                    tuple(float(v) for v in p.split(",")) for p in path.split(";") if p.strip()
                ]
            except ValueError:
                points = []
            if len(points) < 2 or any(len(p) != 2 for p in points):
                _fail(f"--path {path!r}: waypoints are 'x,y;x,y;…' with at least two points")
            commanded = sim.CommandedPath.waypoints(points, speed=speed)
        elif path == "square":
            commanded = sim.CommandedPath.square(size, laps=max(1, round(laps)), speed=speed)
        elif path in builders:
            commanded = builders[path](size, laps=laps, speed=speed)
        else:
            _fail(f"unknown path {path!r}; known: circle, square, figure8, or waypoints 'x,y;x,y'")
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
    except (ValueError, OSError) as exc:
        _fail(_error_text(exc))
    console.print(f"{n} scans written to {out}" + (f", the truth to {tum}" if tum else ""))


_PRESET = typer.Option(help="base configuration: default or paper")
_CONFIG_FILE = typer.Option("--config", help="TOML file overriding keys", readable=False)


@app.command()
def config(
    preset: Annotated[str, _PRESET] = "default",
    config_file: Annotated[Path | None, _CONFIG_FILE] = None,
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
    cfg = _load_config(preset, config_file)
    if markdown:
        typer.echo(settings_markdown(), nl=False)
        return
    if reasons:
        for line in settings_lines():
            typer.echo(line)
        return
    typer.echo(cfg.to_toml())


# -- real logs ------------------------------------------------------------------------------
err_console = Console(stderr=True)


def _error_text(exc: BaseException) -> str:
    """One line for a library or file-system error."""
    if isinstance(exc, OSError) and type(exc).__str__ is not OSError.__str__:
        return " ".join(str(exc).split())  # a typed error that words itself
    if isinstance(exc, OSError) and exc.filename is not None and exc.strerror:
        return f"{exc.filename}: {exc.strerror}"
    text = str(exc) or type(exc).__name__
    return _in_flags(" ".join(text.split()))  # one line


#: the library's argument names as the command line's flags
_FLAG_OF = {
    "field_of_view_deg": "--fov",
    "max_scans": "--max-scans",
    "scan_topic": "--scan-topic",
    "odom_topic": "--odom-topic",
    "max_range": "--max-range",
    "laser_offset": "--laser-offset",
    "convention": "--convention",
    "odometry": "--odometry",
    "start": "--start",
    "end": "--end",
    "scan_rate_hz": "--scan-rate",
}
_LIBRARY_NAME = re.compile(
    r"(?<![\w./\-'\"])(" + "|".join(_FLAG_OF) + r")(?:(=)(?=\S)|=|(?= must\b| \(\d))"
)


def _in_flags(text: str) -> str:
    """A library message in the command line's words: ``max_scans must …`` → ``--max-scans
    must …``, ``scan_topic='/x'`` → ``--scan-topic '/x'``, ``pass scan_topic=`` → ``pass
    --scan-topic``: a name followed by ``=``, `` must`` or `` (<number>``."""
    return _LIBRARY_NAME.sub(lambda m: _FLAG_OF[m[1]] + (" " if m[2] else ""), text)


def _open(
    log: Path,
    *,
    scan_topic: str | None = None,
    odom_topic: str | None = None,
    laser_offset: str | None = None,
    skip_bad_lines: bool = False,
    odometry: str = "scan",
    fov: float = 180.0,
    max_range: float | None = None,
    convention: str = "auto",
    scan_rate: float | None = None,
    base_frame: str | None = None,
) -> OpenLog:
    from ..io import open_log
    from ..io.logs import parse_laser_offset

    try:
        offset = None if laser_offset is None else parse_laser_offset(laser_offset)
        return open_log(
            log,
            scan_topic=scan_topic,
            odom_topic=odom_topic,
            laser_offset=offset,
            skip_bad_lines=skip_bad_lines,
            odometry=odometry,
            field_of_view_deg=fov,
            max_range=max_range,
            convention=convention,
            scan_rate_hz=scan_rate,
            base_frame=base_frame,
        )
    except (ValueError, OSError) as exc:
        _fail(_error_text(exc))


def _kept(exc: BaseException) -> str:
    """What a run stopped by ``exc`` kept, as the end of its one line."""
    from ..jobs.run import partial_results

    kept = partial_results(exc)
    if kept is None:
        return "; nothing kept" if isinstance(exc, KeyboardInterrupt) else ""
    marked = (
        '(summary.json: "partial": true)'
        if "summary.json" in kept.files
        else "(summary.json could not be written)"
    )
    reason = str(kept.summary.get("partial_reason") or "")
    if reason.startswith(("interrupted at scan", "failed at scan")):  # in the loop
        where = f"the {kept.scans} scans before it are kept in {kept.results_dir}/ {marked}"
        if isinstance(exc, KeyboardInterrupt):
            return f" at scan {kept.scans + 1}; {where}"
        return f" (stopped at scan {kept.scans + 1}; {where})"
    where = f"the results of the {kept.scans} scans are kept in {kept.results_dir}/ {marked}"
    if isinstance(exc, KeyboardInterrupt):  # after the loop: where
        return f" {reason.removeprefix('interrupted ')}; {where}"
    return f" (after the {kept.scans} scans; {where})"


def _progress() -> Progress:
    """A transient progress display on stderr, shown only on a terminal."""
    return Progress(console=err_console, transient=True, disable=not err_console.is_terminal)


def _print_warnings(caught: list[warnings.WarningMessage]) -> None:
    for w in caught:
        typer.echo(f"fuzzypos: warning: {' '.join(str(w.message).split())}", err=True)


def _wide() -> Console:
    """The console for tables: the terminal's; a wide one when stdout is a file or pipe (no
    wrapping at 80 columns)."""
    return console if console.is_terminal else Console(width=200)


_LOG_ARG = typer.Argument(
    help="a CARMEN log (.clf, plain or gzip), a ROS1 bag or a ROS2 bag directory; the kind is "
    "told by content, not by name",
    readable=False,  # the reader's own error is one line, typer's a box
)
_SCAN_TOPIC = typer.Option("--scan-topic", help="bags: the LaserScan topic (when several)")
_ODOM_TOPIC = typer.Option("--odom-topic", help="bags: the Odometry topic (when several)")
_SKIP_BAD = typer.Option(
    "--skip-bad-lines",
    help="CARMEN: skip malformed lines (counted) instead of stopping at the first",
)
_ODOMETRY = typer.Option(
    "--odometry",
    help="CARMEN: 'scan' (each scan line's own odometry fields) or 'interpolated' (the ODOM "
    "stream at the scan's stamp)",
)
_FOV = typer.Option("--fov", help="CARMEN FLASER: the scanner's field of view (degrees)")
_MAX_RANGE = typer.Option(
    "--max-range",
    help="CARMEN: readings at or above it are invalid (default: PARAM robot_front_laser_max, "
    "else learned from the data)",
)
_CONVENTION = typer.Option(
    "--convention",
    help="CARMEN FLASER beam angles: auto, resolution (fov/n) or span (fov/(n-1))",
)
_LASER_OFFSET = typer.Option(
    "--laser-offset",
    help="the laser's mounting pose on the robot 'x,y,θ' (m, m, degrees); overrides the log's",
)
_JSON = typer.Option("--json", help="print JSON instead of a table")
_SCAN_RATE = typer.Option(
    "--scan-rate",
    help="take the scans as evenly spaced at this rate (Hz) in file order, stamped k/HZ from 0, "
    "instead of the log's stamps (for a log whose stamps are corrupt)",
)


@app.command("plot-scan")
def plot_scan(
    log: Annotated[Path, _LOG_ARG],
    index: Annotated[int, typer.Option("--index", "-n", help="the scan to plot, 0-based")],
    out: Annotated[
        Path | None,
        typer.Option(help="folder for the figures (default: plots/<log>-scan<N>/)", readable=False),
    ] = None,
    preset: Annotated[str, _PRESET] = "default",
    config_file: Annotated[Path | None, _CONFIG_FILE] = None,
    scan_topic: Annotated[str | None, _SCAN_TOPIC] = None,
    skip_bad_lines: Annotated[bool, _SKIP_BAD] = False,
    fov: Annotated[float, _FOV] = 180.0,
    max_range: Annotated[float | None, _MAX_RANGE] = None,
    convention: Annotated[str, _CONVENTION] = "auto",
) -> None:
    """Draw the paper's Figs. 13–18 (filtering … virtual angular points) for one scan of a log.

    The log is read as run and info read it (the same reader options).
    """
    from ..features import extract_features
    from ..jobs.folders import log_name
    from ..plot.figures import plot_feature_figures

    cfg = _load_config(preset, config_file)
    if index < 0:
        _fail(f"--index must be 0 or more, got {index}")
    opened = _open(
        log,
        scan_topic=scan_topic,
        skip_bad_lines=skip_bad_lines,
        fov=fov,
        max_range=max_range,
        convention=convention,
    )
    try:
        record, count = None, 0
        for rec in opened.records():
            if count == index:
                record = rec
                break
            count += 1
        if record is None:
            _fail(f"{log}: has no scan {index} (it has {count} scans)")
        features = extract_features(record.scan, cfg)
        folder = (
            out
            if out is not None
            else Path("plots") / f"{log_name(log, keep_format=True)}-scan{index}"
        )
        written = plot_feature_figures(features, folder, index, config=cfg)
    except (ValueError, OSError) as exc:
        _fail(_error_text(exc))
    for number, path in sorted(written.items()):
        console.print(f"Fig. {number}: {path}")


@app.command()
def info(
    log: Annotated[Path, _LOG_ARG],
    json_out: Annotated[bool, _JSON] = False,
    scan_topic: Annotated[str | None, _SCAN_TOPIC] = None,
    odom_topic: Annotated[str | None, _ODOM_TOPIC] = None,
    skip_bad_lines: Annotated[bool, _SKIP_BAD] = False,
    fov: Annotated[float, _FOV] = 180.0,
    convention: Annotated[str, _CONVENTION] = "auto",
    config_file: Annotated[Path | None, _CONFIG_FILE] = None,
    scan_rate: Annotated[float | None, _SCAN_RATE] = None,
) -> None:
    """Describe a log (CARMEN, ROS1 bag or ROS2 bag): what it holds.

    A bag's topics first: each with its type and count, the scan and odometry topics' frames,
    rates and stamps, the transforms on /tf and /tf_static, the topics and --bag-out frames
    used by default. Then reads the log once and prints its kind, scans, beam counts and
    angles, field of view, duration (first and last stamp, and how often stamps go
    backwards), whether it has odometry and truth (TRUEPOS), the malformed lines skipped, how
    many readings each "no return" band of the configuration's scanner section (from
    --config) removes, and the "no return" codes found (which a run adds to those bands).
    """
    from ..io import describe_log

    scanner = _load_config("default", config_file).scanner
    shown, look = (False, None) if scan_topic else bag_alone(log, odom_topic, json_out, _wide())
    if shown:
        return
    opened = _open(
        log,
        scan_topic=scan_topic,
        odom_topic=odom_topic,
        skip_bad_lines=skip_bad_lines,
        fov=fov,
        convention=convention,
        scan_rate=scan_rate,
    )
    bag = bag_overview(opened, look)
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            if json_out:
                result = describe_log(opened, scanner=scanner)
            else:
                with _progress() as progress:
                    task = progress.add_task("reading", total=opened.scan_count_hint())
                    result = describe_log(
                        opened,
                        progress=lambda k: progress.update(task, completed=k),
                        scanner=scanner,
                    )
    except (ValueError, OSError) as exc:
        _fail(_error_text(exc))
    _print_warnings(caught)
    if json_out:
        typer.echo(json.dumps(result.as_dict() | ({"bag": bag.as_dict()} if bag else {}), indent=2))
        return
    table = log_table(str(log), result, scanner)
    _wide().print(*bag_tables(bag), table)  # a bag's topics, transforms and defaults first
    for note in result.notes:
        typer.echo(f"note: {note}", err=True)


@app.command()
def run(
    log: Annotated[Path, _LOG_ARG],
    out: Annotated[
        Path | None,
        typer.Option("--out", "-o", help="also write the trajectory here (TUM)", readable=False),
    ] = None,
    results: Annotated[
        Path | None,
        typer.Option(
            "--results",
            help="the results folder (default: a new results/<log>/<date-time>/, linked from "
            "results/<log>/latest); one holding another run's results is refused",
            readable=False,
        ),
    ] = None,
    overwrite: Annotated[
        bool,
        typer.Option(
            "--overwrite", help="clear the --results folder of another run's results first"
        ),
    ] = False,
    preset: Annotated[str, _PRESET] = "default",
    config_file: Annotated[Path | None, _CONFIG_FILE] = None,
    start: Annotated[
        float | None,
        typer.Option(
            help="begin at the first scan (in file order) at least this many seconds "
            "after the first scan's stamp"
        ),
    ] = None,
    end: Annotated[
        float | None,
        typer.Option(
            help="stop before the first scan (in file order, after the start) more "
            "than this many seconds after the first scan's stamp"
        ),
    ] = None,
    max_scans: Annotated[
        int | None, typer.Option("--max-scans", help="run at most this many scans")
    ] = None,
    skip_bad_lines: Annotated[bool, _SKIP_BAD] = False,
    laser_offset: Annotated[str | None, _LASER_OFFSET] = None,
    scan_topic: Annotated[str | None, _SCAN_TOPIC] = None,
    odom_topic: Annotated[str | None, _ODOM_TOPIC] = None,
    odometry: Annotated[str, _ODOMETRY] = "scan",
    fov: Annotated[float, _FOV] = 180.0,
    max_range: Annotated[float | None, _MAX_RANGE] = None,
    convention: Annotated[str, _CONVENTION] = "auto",
    scan_rate: Annotated[float | None, _SCAN_RATE] = None,
    bag_out: Annotated[Path | None, RUN_OPTIONS["bag_out"]] = None,
    bag_storage: Annotated[str | None, RUN_OPTIONS["bag_storage"]] = None,
    base_frame: Annotated[str | None, RUN_OPTIONS["base_frame"]] = None,
    odom_frame: Annotated[str | None, RUN_OPTIONS["odom_frame"]] = None,
    map_frame: Annotated[str | None, RUN_OPTIONS["map_frame"]] = None,
    loop_closure: Annotated[bool, RUN_OPTIONS["loop_closure"]] = False,
    save_map: Annotated[bool, RUN_OPTIONS["save_map"]] = False,
    map_resolution: Annotated[float | None, RUN_OPTIONS["map_resolution"]] = None,
    relations: Annotated[
        Path | None,
        typer.Option(
            "--relations",
            help="score the trajectory against this relations file (printed, and "
            "summary.json's relations; with --loop-closure the front end's and the online "
            "poses' too)",
            readable=False,
        ),
    ] = None,
) -> None:
    """Position the robot along a log and write a results folder.

    The folder (default a new results/<log>/<date-time>/) gets trajectory.tum (one pose per
    scan, stamped as in the log, in file order), trajectory.clf (the log with the estimate
    as FLASER's or ROBOTLASER1's pose and the odometry kept), config.toml, path.png (path,
    odometry and map) and summary.json (versions, input hash, scans, degraded scans,
    odometry jumps, speed, errors against the log's truth where it has some, the scans per
    reason, the learned odometry noise), and covariance.csv (each scan's step and pose
    covariance, reason and whether degraded).
    --bag-out also writes the estimate with its covariance into a bag (REP-105 frames,
    --base-frame, --odom-frame, --map-frame). Prints the scan rate
    and where the results are. A run stopped by an error or Ctrl-C keeps the scans done,
    marked "partial" in summary.json.
    """
    from ..io import read_relations
    from ..jobs.outputs import as_interrupt, is_interrupt
    from ..jobs.run import run_log

    cfg = _load_config(preset, config_file)
    lc: dict[str, object] = {"enabled": True} if loop_closure else {}
    lc |= {} if map_resolution is None else {"map_resolution": map_resolution}
    cfg = cfg.with_overrides({"loop_closure": lc})
    frames = {"base": base_frame, "odom": odom_frame, "map": map_frame}
    if bag_out is None and any(frames.values()):
        _fail("--base-frame, --odom-frame and --map-frame name --bag-out's frames: give --bag-out")
    opened = _open(
        log,
        base_frame=base_frame,
        scan_topic=scan_topic,
        odom_topic=odom_topic,
        laser_offset=laser_offset,
        skip_bad_lines=skip_bad_lines,
        odometry=odometry,
        fov=fov,
        max_range=max_range,
        convention=convention,
        scan_rate=scan_rate,
    )
    try:
        rel = None if relations is None else read_relations(relations)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            with _progress() as progress:
                task = progress.add_task("positioning", total=None)

                def report(done: int, total: int | None) -> None:
                    progress.update(task, completed=done, total=total)

                summary = run_log(
                    opened,
                    cfg,
                    results_dir=results,
                    overwrite=overwrite,
                    out_tum=out,
                    progress=report,
                    start=start,
                    end=end,
                    max_scans=max_scans,
                    preset=preset,
                    config_file=config_file,
                    bag_out=bag_out,
                    bag_storage=bag_storage,
                    bag_frames=frames,
                    relations=rel,
                    save_map=save_map,
                    compiling=lambda: compiling_shown(err_console, progress),
                )
    except (KeyboardInterrupt, SystemError) as exc:
        if not is_interrupt(exc):  # numba's SystemError around Ctrl-C is Ctrl-C
            raise
        typer.echo(f"fuzzypos: interrupted{_kept(as_interrupt(exc))}", err=True)
        raise typer.Exit(code=130) from None
    except (ValueError, OSError) as exc:
        _fail(_error_text(exc) + _kept(exc))
    _print_warnings(caught)
    s = summary.summary
    bad = f", {s['bad_lines_skipped']} bad lines skipped" if s["bad_lines_skipped"] else ""
    typer.echo(
        f"{summary.scans} scans in {summary.seconds:.2f} s: "
        f"{summary.scans_per_second:.1f} scans/s (positioner "
        f"{s['positioner_ms_per_scan']:.2f} ms per scan); {summary.scans_degraded} degraded, "
        f"{summary.odometry_jumps_rejected} odometry jumps rejected{bad}"
    )
    if s["truth_errors"]:
        e = s["truth_errors"]["estimate"]
        typer.echo(
            f"against the log's truth: final {e['final_position_error_m']:.3f} m, mean "
            f"{e['mean_position_error_m']:.3f} m, mean heading {e['mean_heading_error_deg']:.2f}°"
        )
    for line in loop_closure_lines(s):
        typer.echo(line)
    if s["relations"] and not s.get("loop_closure"):  # (loop closure's lines have them)
        typer.echo(relations_line(s["relations"]))
    for note in summary.notes:
        typer.echo(f"note: {note}", err=True)
    typer.echo(
        f"results in {summary.results_dir}/"
        + (f"; trajectory also in {out}" if out else "")
        + (f"; odometry bag in {bag_out}" if bag_out else "")
    )


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
    json_out: Annotated[bool, _JSON] = False,
) -> None:
    """Score a trajectory against relations and/or a reference trajectory.

    --relations: the benchmark's relations metric over all and local (t2 - t1 <= 10 s)
    relations: mean ± std and median of the translational and rotational errors, and how
    many matched. --reference: the ATE (RMSE after SE(2) alignment) and the RPE over 1 frame
    and over 1 m. Give one of them or both.
    """
    from ..eval.scoring import evaluate_trajectory

    if relations is None and reference is None:
        _fail("evaluate needs --relations FILE and/or --reference REF.tum")
    try:
        ev = evaluate_trajectory(estimate, relations=relations, reference=reference)
    except (ValueError, OSError) as exc:
        _fail(_error_text(exc))
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
        _fail(f"--max-scans must be at least 1, got {max_scans}")
    if jobs < 1:
        _fail(f"--jobs must be at least 1, got {jobs}")
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            with _progress() as progress:
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
    except (ValueError, OSError) as exc:
        _fail(_error_text(exc))
    _print_warnings(caught)
    failed = any("error" in r for r in result.data["rows"])
    if json_out:  # a run failed (not bad input): exit 1
        typer.echo(json.dumps(result.data["rows"], indent=2))
        raise typer.Exit(code=1 if failed else 0)
    title = "relations metric" + (f" (first {max_scans} scans of each log)" if max_scans else "")
    table, problems = benchmark_table(result.data["rows"], title, _wide().width)
    _wide().print(table)
    for line in problems:
        typer.echo(line)
    typer.echo(f"benchmark.json and the runs' results in {result.out_dir}/")
    if failed:  # a run failed (not bad input): exit 1
        raise typer.Exit(code=1)


@app.command(help=BATCH_HELP)
def batch(
    paths: Annotated[list[Path], typer.Argument(help="logs or their folders", readable=False)],
    out: Annotated[Path, typer.Option(help="the results' folder", readable=False)] = Path("batch"),
    configs: Annotated[list[Path] | None, typer.Option("--config", help="config TOML")] = None,
    preset: Annotated[str, _PRESET] = "default",
    loop_closure: Annotated[bool, BATCH_OPTIONS["loop_closure"]] = False,
    max_scans: Annotated[int | None, typer.Option("--max-scans", help="scans per run")] = None,
    address: Annotated[str | None, typer.Option(help="a Ray cluster to join (auto)")] = None,
    jobs: Annotated[int | None, typer.Option(help="local Ray's CPUs (default all)")] = None,
    force: Annotated[bool, BATCH_OPTIONS["force"]] = False,
    verbose: Annotated[bool, BATCH_OPTIONS["verbose"]] = False,
) -> None:
    from ..jobs.batch import batch_table, progress_bar, run_batch

    try:
        with progress_bar(console) as report:
            result = run_batch(paths, out, configs=configs or (), max_scans=max_scans,
                address=address, jobs=jobs, force=force, progress=report, preset=preset,
                loop_closure=loop_closure, verbose=verbose)  # fmt: skip
    except KeyboardInterrupt:
        _fail(f"interrupted; the runs finished are in {out / 'batch.json'}", 130)
    except (ValueError, OSError) as exc:
        _fail(_error_text(exc))
    console.print(batch_table(result.rows))
    raise typer.Exit(code=1 if result.failed or result.refused else 0)


finish_commands(app)  # every command's help from its docstring, unwrapped; usage lines


def main() -> None:  # pragma: no cover - console entry point
    app()
