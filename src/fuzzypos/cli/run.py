"""Part of the command line (:mod:`fuzzypos.cli`): ``run``, positioning along a log into a
results folder."""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Annotated

import typer

from .app import (
    CONFIG_FILE,
    CONVENTION,
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
    fail,
    load_config,
    open_log,
    print_warnings,
    progress_display,
)
from .help import RUN_OPTIONS, compiling_shown
from .tables import loop_closure_lines, relations_line


@app.command()
def run(
    log: Annotated[Path, LOG_ARG],
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
    preset: Annotated[str, PRESET] = "default",
    config_file: Annotated[Path | None, CONFIG_FILE] = None,
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
    skip_bad_lines: Annotated[bool, SKIP_BAD] = False,
    laser_offset: Annotated[str | None, LASER_OFFSET] = None,
    scan_topic: Annotated[str | None, SCAN_TOPIC] = None,
    odom_topic: Annotated[str | None, ODOM_TOPIC] = None,
    odometry: Annotated[str, ODOMETRY] = "scan",
    fov: Annotated[float, FOV] = 180.0,
    max_range: Annotated[float | None, MAX_RANGE] = None,
    convention: Annotated[str, CONVENTION] = "auto",
    scan_rate: Annotated[float | None, SCAN_RATE] = None,
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
    from ..jobs.run import run_log

    cfg = load_config(preset, config_file)
    lc: dict[str, object] = {"enabled": True} if loop_closure else {}
    lc |= {} if map_resolution is None else {"map_resolution": map_resolution}
    cfg = cfg.with_overrides({"loop_closure": lc})
    frames = {"base": base_frame, "odom": odom_frame, "map": map_frame}
    if bag_out is None and any(frames.values()):
        fail("--base-frame, --odom-frame and --map-frame name --bag-out's frames: give --bag-out")
    opened = open_log(
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
    rel = None if relations is None else read_relations(relations)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with progress_display() as progress:
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
    print_warnings(caught)
    bad = summary.bad_lines_skipped
    typer.echo(
        f"{summary.scans} scans in {summary.seconds:.2f} s: "
        f"{summary.scans_per_second:.1f} scans/s (positioner "
        f"{summary.positioner_ms_per_scan:.2f} ms per scan); {summary.scans_degraded} degraded, "
        f"{summary.odometry_jumps_rejected} odometry jumps rejected"
        + (f", {bad} bad lines skipped" if bad else "")
    )
    if summary.truth_errors is not None:
        e = summary.truth_errors.estimate
        typer.echo(
            f"against the log's truth: final {e.final_position_error_m:.3f} m, mean "
            f"{e.mean_position_error_m:.3f} m, mean heading {e.mean_heading_error_deg:.2f}°"
        )
    for line in loop_closure_lines(summary.loop_closure, summary.relations):
        typer.echo(line)
    if summary.relations and not summary.loop_closure:  # (loop closure's lines have them)
        typer.echo(relations_line(summary.relations))
    for note in summary.notes:
        typer.echo(f"note: {note}", err=True)
    typer.echo(
        f"results in {summary.results_dir}/"
        + (f"; trajectory also in {out}" if out else "")
        + (f"; odometry bag in {bag_out}" if bag_out else "")
    )
