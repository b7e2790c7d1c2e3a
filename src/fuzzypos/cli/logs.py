"""Part of the command line (:mod:`fuzzypos.cli`): the commands that look at a log: ``info``
(what it holds) and ``plot-scan`` (the paper's figures for one of its scans)."""

from __future__ import annotations

import json
import warnings
from pathlib import Path
from typing import Annotated

import typer

from .app import (
    CONFIG_FILE,
    CONVENTION,
    FOV,
    JSON,
    LOG_ARG,
    MAX_RANGE,
    ODOM_TOPIC,
    PRESET,
    SCAN_RATE,
    SCAN_TOPIC,
    SKIP_BAD,
    app,
    console,
    fail,
    load_config,
    open_log,
    print_warnings,
    progress_display,
    wide,
)
from .tables import bag_alone, bag_overview, bag_tables, log_table


@app.command("plot-scan")
def plot_scan(
    log: Annotated[Path, LOG_ARG],
    index: Annotated[int, typer.Option("--index", "-n", help="the scan to plot, 0-based")],
    out: Annotated[
        Path | None,
        typer.Option(help="folder for the figures (default: plots/<log>-scan<N>/)", readable=False),
    ] = None,
    preset: Annotated[str, PRESET] = "default",
    config_file: Annotated[Path | None, CONFIG_FILE] = None,
    scan_topic: Annotated[str | None, SCAN_TOPIC] = None,
    skip_bad_lines: Annotated[bool, SKIP_BAD] = False,
    fov: Annotated[float, FOV] = 180.0,
    max_range: Annotated[float | None, MAX_RANGE] = None,
    convention: Annotated[str, CONVENTION] = "auto",
) -> None:
    """Draw the paper's Figs. 13–18 (filtering … virtual angular points) for one scan of a log.

    The log is read as run and info read it (the same reader options).
    """
    from ..features import extract_features
    from ..jobs.folders import log_name
    from ..plot.figures import plot_feature_figures

    cfg = load_config(preset, config_file)
    if index < 0:
        fail(f"--index must be 0 or more, got {index}")
    opened = open_log(
        log,
        scan_topic=scan_topic,
        skip_bad_lines=skip_bad_lines,
        fov=fov,
        max_range=max_range,
        convention=convention,
    )
    record, count = None, 0
    for rec in opened.records():
        if count == index:
            record = rec
            break
        count += 1
    if record is None:
        fail(f"{log}: has no scan {index} (it has {count} scans)")
    features = extract_features(record.scan, cfg)
    folder = (
        out if out is not None else Path("plots") / f"{log_name(log, keep_format=True)}-scan{index}"
    )
    written = plot_feature_figures(features, folder, index, config=cfg)
    for number, path in sorted(written.items()):
        console.print(f"Fig. {number}: {path}")


@app.command()
def info(
    log: Annotated[Path, LOG_ARG],
    json_out: Annotated[bool, JSON] = False,
    scan_topic: Annotated[str | None, SCAN_TOPIC] = None,
    odom_topic: Annotated[str | None, ODOM_TOPIC] = None,
    skip_bad_lines: Annotated[bool, SKIP_BAD] = False,
    fov: Annotated[float, FOV] = 180.0,
    convention: Annotated[str, CONVENTION] = "auto",
    config_file: Annotated[Path | None, CONFIG_FILE] = None,
    scan_rate: Annotated[float | None, SCAN_RATE] = None,
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

    scanner = load_config("default", config_file).scanner
    shown, look = (False, None) if scan_topic else bag_alone(log, odom_topic, json_out, wide())
    if shown:
        return
    opened = open_log(
        log,
        scan_topic=scan_topic,
        odom_topic=odom_topic,
        skip_bad_lines=skip_bad_lines,
        fov=fov,
        convention=convention,
        scan_rate=scan_rate,
    )
    bag = bag_overview(opened, look)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        if json_out:
            result = describe_log(opened, scanner=scanner)
        else:
            with progress_display() as progress:
                task = progress.add_task("reading", total=opened.scan_count_hint())
                result = describe_log(
                    opened,
                    progress=lambda k: progress.update(task, completed=k),
                    scanner=scanner,
                )
    print_warnings(caught)
    if json_out:
        typer.echo(json.dumps(result.as_dict() | ({"bag": bag.as_dict()} if bag else {}), indent=2))
        return
    table = log_table(str(log), result, scanner)
    wide().print(*bag_tables(bag), table)  # a bag's topics, transforms and defaults first
    for note in result.notes:
        typer.echo(f"note: {note}", err=True)
