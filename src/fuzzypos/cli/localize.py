"""Part of the command line (:mod:`fuzzypos.cli`): ``localize``, where the robot is in a saved
map (:mod:`fuzzypos.jobs.localize`). It says itself what a stopped job kept (``launch`` knows
the run's)."""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from ..errors import FuzzyposError
from .app import (
    CONFIG_FILE,
    CONVENTION,
    FLAGS,
    FOV,
    LASER_OFFSET,
    LOG_ARG,
    MAX_RANGE,
    ODOM_TOPIC,
    ODOMETRY,
    PRESET,
    SCAN_RATE,
    SCAN_TOPIC,
    SKIP_BAD,
    app,
    err_console,
    error_text,
    fail,
    load_config,
    open_log,
    print_warnings,
    progress_display,
)
from .help import RUN_OPTIONS, compiling_shown

if TYPE_CHECKING:
    from ..jobs.localize import LocalizeSummary

_MAP = typer.Option(
    "--map", help="the map: a ROS map_server yaml, its pgm or png beside it", readable=False
)
_INITIAL_POSE = typer.Option(
    "--initial-pose",
    help="x,y,θ (m, m, degrees) in the map frame: start near it, as AMCL's /initialpose "
    "(default: search the whole map)",
)
_INITIAL_SIGMA = typer.Option(
    "--initial-sigma",
    help="m,θ: how far the initial pose may be off, standard deviations (m, degrees)",
)
_BAG_OUT = typer.Option(
    "--bag-out",
    help="also write the poses into this new bag, as AMCL does: "
    "geometry_msgs/PoseWithCovarianceStamped on /amcl_pose and map → odom on /tf (a name "
    "ending .bag: ROS1, else a ROS2 directory); an existing path is refused",
    readable=False,
)
_STRETCH_HELP = {
    "start": "begin at the first scan at least this many seconds after the first scan's stamp",
    "end": "stop before the first scan more than this many seconds after the first scan's stamp",
}


#: the job's arguments as the command's flags, for the messages that name them
_FLAGS = {**FLAGS, "initial_pose": "--initial-pose", "initial_sigma": "--initial-sigma"}


def _error_text(exc: BaseException) -> str:
    """One line for a library or file-system error, the job's arguments named as flags."""
    if isinstance(exc, FuzzyposError) and not isinstance(exc, OSError):
        return " ".join(exc.worded(_FLAGS).split()) or type(exc).__name__
    return error_text(exc)


def _kept(exc: BaseException) -> str:
    """What a job stopped by ``exc`` kept, as the end of its one line."""
    from ..jobs.localize import localize_partial

    kept = localize_partial(exc)
    if kept is None:
        return "; nothing kept" if isinstance(exc, KeyboardInterrupt) else ""
    where = f"the {kept.scans} scans before it are kept in {kept.results_dir}/"
    marked = (
        ' (summary.json: "partial": true)'
        if "summary.json" in kept.files
        else " (summary.json could not be written)"
    )
    if isinstance(exc, KeyboardInterrupt):
        return f" at scan {kept.scans + 1}; {where}{marked}"
    return f" (stopped at scan {kept.scans + 1}; {where}{marked})"


def _report(summary: LocalizeSummary, log: Path, map_yaml: Path) -> None:
    """The job's lines: when it localised and how it went, or (exit 1) that it never did."""
    s = summary.summary
    states = s["states"]
    lost = sum(1 for e in s["events"] if e["event"] == "lost")
    if not summary.localised:
        typer.echo(
            f"fuzzypos: {log} never localised in {map_yaml} over {summary.scans} scans "
            f"({states['searching']} searching); results in {summary.results_dir}/ "
            '(summary.json: "localised": false)',
            err=True,
        )
        raise typer.Exit(code=1)
    at = s["localised_at"]
    q = s["confidence"]["quantiles_tracking"] or {}
    median = f", median confidence {q['p50']:.2f} while tracking" if "p50" in q else ""
    typer.echo(
        f"localised at scan {at['scan']} ({at['seconds_since_first_scan']:.1f} s into the log, "
        f"after {at['wall_seconds']:.1f} s of work); tracking {states['tracking']} of "
        f"{summary.scans} scans, lost {lost} time{'' if lost == 1 else 's'}{median}; final state "
        f"{s['final_state']}"
    )
    for note in summary.notes:
        typer.echo(f"note: {note}", err=True)
    typer.echo(f"results in {summary.results_dir}/")


@app.command()
def localize(
    log: Annotated[Path, LOG_ARG],
    map_yaml: Annotated[Path, _MAP],
    initial_pose: Annotated[str | None, _INITIAL_POSE] = None,
    initial_sigma: Annotated[str | None, _INITIAL_SIGMA] = None,
    results: Annotated[
        Path | None,
        typer.Option(
            help="the results folder (default: a new results/<log>/<date-time>/); one holding "
            "another run's results is refused",
            readable=False,
        ),
    ] = None,
    overwrite: Annotated[
        bool, typer.Option("--overwrite", help="clear the --results folder of another run first")
    ] = False,
    preset: Annotated[str, PRESET] = "default",
    config_file: Annotated[Path | None, CONFIG_FILE] = None,
    start: Annotated[float | None, typer.Option(help=_STRETCH_HELP["start"])] = None,
    end: Annotated[float | None, typer.Option(help=_STRETCH_HELP["end"])] = None,
    max_scans: Annotated[
        int | None, typer.Option("--max-scans", help="at most this many scans")
    ] = None,
    skip_bad_lines: Annotated[bool, SKIP_BAD] = False,
    laser_offset: Annotated[str | None, LASER_OFFSET] = None,
    scan_topic: Annotated[str | None, SCAN_TOPIC] = None,
    odom_topic: Annotated[str | None, ODOM_TOPIC] = None,
    odometry: Annotated[str, ODOMETRY] = "scan",
    fov: Annotated[float, FOV] = 180.0,
    max_range: Annotated[float | None, MAX_RANGE] = None,
    convention: Annotated[str, CONVENTION] = "auto",
    scan_rate: Annotated[float | None, SCAN_RATE] = None,
    bag_out: Annotated[Path | None, _BAG_OUT] = None,
    bag_storage: Annotated[str | None, RUN_OPTIONS["bag_storage"]] = None,
    base_frame: Annotated[str | None, RUN_OPTIONS["base_frame"]] = None,
    odom_frame: Annotated[str | None, RUN_OPTIONS["odom_frame"]] = None,
    map_frame: Annotated[str | None, RUN_OPTIONS["map_frame"]] = None,
) -> None:
    """Localise the robot along a log in a saved map (a ROS map_server yaml).

    Writes a results folder like run's: trajectory.tum (the pose in the map frame of every scan
    where it is localised, none elsewhere), covariance.csv (their step and pose covariances,
    confidence and reason), config.toml and summary.json ("localised", when, every time it lost
    and found itself, the scans per state, its confidence over time). --bag-out also writes
    the poses on /amcl_pose and map → odom on /tf. Exit 1 where it never localised; a bad map
    or an initial pose off the map: exit 2.
    """
    from ..jobs.localize import localize_log, parse_initial_pose, parse_initial_sigma
    from ..jobs.outputs import as_interrupt, is_interrupt

    cfg = load_config(preset, config_file)
    frames = {"base": base_frame, "odom": odom_frame, "map": map_frame}
    if bag_out is None and any(frames.values()):
        fail("--base-frame, --odom-frame and --map-frame name --bag-out's frames: give --bag-out")
    try:
        pose = None if initial_pose is None else parse_initial_pose(initial_pose)
        sigma = None if initial_sigma is None else parse_initial_sigma(initial_sigma)
        opened = open_log(
            log, base_frame=base_frame, scan_topic=scan_topic, odom_topic=odom_topic,
            laser_offset=laser_offset, skip_bad_lines=skip_bad_lines, odometry=odometry,
            fov=fov, max_range=max_range, convention=convention, scan_rate=scan_rate,
        )  # fmt: skip
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            with progress_display() as progress:
                task = progress.add_task("localising", total=None)
                summary = localize_log(
                    opened, map_yaml, cfg, initial_pose=pose, initial_sigma=sigma,
                    results_dir=results, overwrite=overwrite, start=start, end=end,
                    max_scans=max_scans, preset=preset, config_file=config_file,
                    bag_out=bag_out, bag_storage=bag_storage, bag_frames=frames,
                    progress=lambda done, total: progress.update(task, completed=done, total=total),
                    compiling=lambda: compiling_shown(err_console, progress),
                )  # fmt: skip
    except (KeyboardInterrupt, SystemError) as exc:
        if not is_interrupt(exc):
            raise
        typer.echo(f"fuzzypos: interrupted{_kept(as_interrupt(exc))}", err=True)
        raise typer.Exit(code=130) from None
    except (FuzzyposError, ValueError, OSError) as exc:
        fail(_error_text(exc) + _kept(exc))
    print_warnings(caught)
    _report(summary, log, map_yaml)
