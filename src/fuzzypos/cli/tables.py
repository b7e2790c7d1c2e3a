"""Part of the command line (:mod:`fuzzypos.cli`): the tables and lines it prints from the
library's results, kept apart so the commands stay short."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

import typer
from rich import box
from rich.console import Console
from rich.table import Table
from rich.text import Text

if TYPE_CHECKING:
    from ..config import ScannerConfig
    from ..io import LogInfo, OpenLog
    from ..io.bag_info import BagInfo, StreamInfo
    from ..io.logs import NoReturnCount
    from ..io.no_returns import FoundNoReturn

__all__ = [
    "bag_overview",
    "bag_tables",
    "benchmark_table",
    "found_rows",
    "loop_closure_lines",
    "no_return_rows",
    "odometry_text",
    "pm",
    "relations_line",
]

_BENCHMARK_COLUMNS = (
    "log",
    "config",
    "all trans m",
    "all rot °",
    "local trans m / median",
    "local rot °",
    "matched all/local",
    "scans/s",
    "degraded",
    "jumps",
)


def pm(mean: float | None, std: float | None, fmt: str) -> str:
    """``mean±std`` in ``fmt``, or a dash where there is none."""
    if mean is None or std is None or math.isnan(mean):
        return "–"
    return f"{mean:{fmt}}±{std:{fmt}}"


#: the narrow table's columns (each mean over its ± std on a second line)
_NARROW_COLUMNS = (
    "log",
    "config",
    "all m",
    "all °",
    "local m (median)",
    "local °",
    "matched all local",
    "scans /s",
    "degr- aded",
    "jumps",
)


def _narrow(mean: float | None, std: float | None, fmt: str) -> str:
    """:func:`pm` over two lines: the mean, then ``±std``."""
    return pm(mean, std, fmt).replace("±", "\n±")


def _cells(r: dict[str, Any], narrow: bool) -> list[str]:
    """A scored row's cells after its log and config."""
    sps = r.get("scans_per_second")
    med = r.get("local_trans_median_m")
    tail = [
        "–" if sps is None else f"{sps:.0f}",
        str(r.get("scans_degraded", "")),
        str(r.get("odometry_jumps_rejected", "")),
    ]
    both = f"{r.get('all_matched', 0)}/{r.get('local_matched', 0)}"
    if not narrow:
        return [
            pm(r.get("all_trans_mean_m"), r.get("all_trans_std_m"), ".3f"),
            pm(r.get("all_rot_mean_deg"), r.get("all_rot_std_deg"), ".2f"),
            pm(r.get("local_trans_mean_m"), r.get("local_trans_std_m"), ".3f")
            + ("" if med is None else f" / {med:.3f}"),
            pm(r.get("local_rot_mean_deg"), r.get("local_rot_std_deg"), ".2f"),
            both,
            *tail,
        ]
    return [
        _narrow(r.get("all_trans_mean_m"), r.get("all_trans_std_m"), ".3f"),
        _narrow(r.get("all_rot_mean_deg"), r.get("all_rot_std_deg"), ".2f"),
        _narrow(r.get("local_trans_mean_m"), r.get("local_trans_std_m"), ".3f")
        + ("" if med is None else f"\n({med:.3f})"),
        _narrow(r.get("local_rot_mean_deg"), r.get("local_rot_std_deg"), ".2f"),
        both.replace("/", "\n"),
        *tail,
    ]


def _layout(rows: list[dict[str, Any]], title: str, narrow: bool) -> tuple[Table, list[str]]:
    """The table in one layout: wide (a line a row) or narrow (values over two lines, headers
    wrapped, log and config folded, no frame; each number column as wide as its longest
    line, so that no number is cut)."""
    columns = _NARROW_COLUMNS if narrow else _BENCHMARK_COLUMNS
    cells: list[list[str | Text]] = []
    problems: list[str] = []
    for r in rows:
        if "error" in r:
            failed = Text("failed" if narrow else "failed (below)", style="red")
            cells.append([r["log"], r["config"], failed, *[""] * (len(columns) - 3)])
            problems.append(f"{r['log']} {r['config']}: {r['error']}")
            continue
        if "not_scored" in r:
            problems.append(f"{r['log']} {r['config']}: not scored: {r['not_scored']}")
        cells.append([r["log"], r["config"], *_cells(r, narrow)])
    if not narrow:
        table = Table(title=title)
    else:
        table = Table(title=title, box=box.SIMPLE_HEAD, padding=(0, 0))
    for k, col in enumerate(columns):
        left = k < 2
        if not narrow:
            table.add_column(col, justify="left" if left else "right", no_wrap=left)
            continue
        lines = [ln for row in cells for ln in str(row[k]).splitlines()] + col.split()
        table.add_column(
            col, justify="left" if left else "right", overflow="fold",
            min_width=None if left else max(len(ln) for ln in lines), ratio=1 if left else None,
        )  # fmt: skip
    for row in cells:
        table.add_row(*row)
    return table, problems


def benchmark_table(
    rows: list[dict[str, Any]], title: str, width: int | None = None
) -> tuple[Table, list[str]]:
    """The benchmark's rows as a table, and a line per failed or unscored row. ``width``: the
    columns it is printed in: where the wide layout (a line a row) would not fit, the narrow
    one (each mean over its ± std, headers wrapped, no frame), whose numbers are never cut."""
    table, problems = _layout(rows, title, narrow=False)
    if width is not None:
        needed = Console(width=10_000).measure(table).maximum
        if needed > width:
            table, problems = _layout(rows, title, narrow=True)
    return table, problems


def loop_closure_lines(lc: dict[str, Any] | None, relations: dict[str, Any] | None) -> list[str]:
    """``fuzzypos run --loop-closure``'s lines: the closures (``lc``, ``summary.json``'s
    ``loop_closure``), and where the run was scored against relations, the front end's, the
    online and the optimised (``relations``) figures side by side."""
    if not lc:
        return []
    head = (
        f"loop closure ({lc.get('mode', 'offline')}): {lc['keyframes']} keyframes, "
        f"{len(lc['closures'])} closures ({lc['closures_kept']} kept), largest correction "
        f"{lc['max_correction_m']:.3f} m, {lc['seconds']:.1f} s in the graph"
    )
    lines = [head]
    scored = [
        (name, rel)
        for name, rel in (
            ("front end", lc.get("relations_frontend")),
            ("online", lc.get("relations_online")),
            ("optimised", relations),
        )
        if rel
    ]
    lines.extend(f"  {relations_line(rel, name)}" for name, rel in scored)
    return lines


def relations_line(rel: dict[str, Any], name: str = "") -> str:
    """The relations metric of a run (``summary.json``'s ``relations``) in one line: all and
    local relations' mean translation (m) and rotation (°) errors."""
    return (
        f"relations{f', {name}' if name else ''}: all {rel['all_trans_mean_m']:.3f} m / "
        f"{rel['all_rot_mean_deg']:.2f}°, local {rel['local_trans_mean_m']:.4f} m / "
        f"{rel['local_rot_mean_deg']:.3f}°"
    )


def no_return_rows(counts: list[NoReturnCount]) -> list[tuple[str, str]]:
    """``("no-return 81.83–81.91 m", "5,849 readings")`` per band, with those in the band that
    ``range_max`` had already made invalid."""
    rows = []
    for c in counts:
        band = f"{c.low_m:g} m" if c.low_m == c.high_m else f"{c.low_m:g}–{c.high_m:g} m"
        text = f"{c.removed:,} readings removed"
        if c.in_band > c.removed:
            text += f" ({c.in_band - c.removed:,} more in the band already invalid at range_max)"
        rows.append((f"no-return {band}", text))
    return rows or [("no-return bands", "none")]


def found_rows(found: list[FoundNoReturn], looked: bool) -> list[tuple[str, str]]:
    """``("no-return 50 m (found in the data)", "863 readings")`` per code found, saying
    which of them ``range_max`` or a configured band already made invalid."""
    if not looked:
        return [("no-return values found", "not looked for (find_no_return_values = false)")]
    rows = []
    for f in found:
        text = f"{f.readings:,} readings"
        if f.in_configured_band:
            text += " (in a configured band)"
        elif f.invalid_at_range_max:
            text += f" ({f.invalid_at_range_max:,} already invalid at range_max)"
        rows.append((f"no-return {f.value_m:g} m (found in the data)", text))
    return rows or [("no-return values found", "none")]


def odometry_text(result: LogInfo) -> str:
    """``info``'s odometry row: the scans it covers, and those it does not (see the note)."""
    missed = result.scans_odometry_not_covered
    if not missed:
        return f"yes ({result.scans_with_odometry} scans)" if result.has_odometry else "no"
    if result.has_odometry:
        return f"yes ({result.scans_with_odometry} scans); {missed} scans not covered (see note)"
    return f"none that covers the scans ({missed} scans not covered: see the note)"


# -- info on a bag ---------------------------------------------------------------------------
def _counts(counts: dict[str, int] | None, total: int) -> str:
    """``laser`` where every message has it, else ``a (3), b (2)``."""
    if not counts:
        return ""
    if len(counts) == 1 and next(iter(counts.values())) == total:
        return next(iter(counts))
    return ", ".join(f"{k or '(empty)'} ({n:,})" for k, n in counts.items())


def _rate(s: StreamInfo) -> str:
    if s.rate_hz is None:
        return "–"
    median = s.median_rate_hz
    return f"{s.rate_hz:.2f} Hz" + ("" if median is None else f" (median {median:.2f})")


def _span(s: StreamInfo) -> str:
    if s.first_stamp is None or s.last_stamp is None or s.span_s is None:
        return "–"
    return f"{s.first_stamp!r} … {s.last_stamp!r} ({s.span_s:.1f} s)"


def _pick_text(topic: str | None, candidates: list[str], kind: str, flag: str) -> str:
    if topic is not None:
        return topic if len(candidates) == 1 else f"{topic} ({flag}; of {', '.join(candidates)})"
    if not candidates:
        return f"none (no {kind} topic)"
    return f"none: {len(candidates)} {kind} topics ({', '.join(candidates)}): pass {flag}"


def bag_tables(info: BagInfo | None) -> list[Table]:
    """``info``'s tables for a bag: its topics (with the frames, rate and span of the scan
    and odometry topics), its transforms, and what fuzzypos reads and writes by default
    (none for no bag)."""
    if info is None:
        return []
    streams = {s.topic: s for s in info.streams}
    topics = Table(title=f"{info.path}: ROS{info.ros_version} topics")
    for col in ("topic", "type", "messages", "frame_id", "child_frame_id", "rate", "stamps"):
        topics.add_column(col, justify="right" if col == "messages" else "left")
    for t in info.topics:
        s = streams.get(t.topic)
        cells = ["", "", "", ""]
        if s is not None:
            children = _counts(s.child_frame_ids, s.messages)
            cells = [_counts(s.frame_ids, s.messages), children, _rate(s), _span(s)]
        topics.add_row(t.topic, t.msgtype or "(mixed types)", f"{t.messages:,}", *cells)
    tables = [topics]
    if info.tf:
        tf = Table(title="transforms (tf2_msgs/TFMessage)")
        for col in ("topic", "parent → child", "transforms"):
            tf.add_column(col, justify="right" if col == "transforms" else "left")
        for p in info.tf:
            tf.add_row(p.topic, f"{p.parent} → {p.child}", f"{p.count:,}")
        tables.append(tf)
    picks = Table(title="fuzzypos's defaults", show_header=False)
    picks.add_column("", style="bold")
    picks.add_column("")
    picks.add_row("scan topic", _pick_text(info.scan_topic, info.scan_candidates, "LaserScan",
                                           "--scan-topic"))  # fmt: skip
    picks.add_row("odometry topic", _pick_text(info.odom_topic, info.odom_candidates,
                                               "Odometry", "--odom-topic"))  # fmt: skip
    f = info.frames
    for key, flag in (("base", "--base-frame"), ("odom", "--odom-frame"), ("map", "--map-frame")):
        where = f.sources.get(key, "")
        picks.add_row(f"run --bag-out {key} frame", f"{getattr(f, key)} ({where}; {flag})")
    tables.append(picks)
    return tables


def bag_overview(log: OpenLog, seen: BagInfo | None = None) -> BagInfo | None:
    """``info``'s look into an opened bag (:func:`~fuzzypos.io.bag_info.describe_bag`, with
    the topics its reader picked; :func:`bag_tables` shows it); None for a CARMEN log. An
    error: one line, exit 2. ``seen``: the look :func:`bag_alone` already took, used where it
    picked the reader's topics (the bag is not read twice)."""
    from ..io import BagReader
    from ..io.bag_info import describe_bag

    reader = log.reader
    if not isinstance(reader, BagReader):
        return None
    if seen is not None and (seen.scan_topic, seen.odom_topic) == (
        reader.scan_topic,
        reader.odom_topic,
    ):
        seen.path = log.name
        return seen
    try:
        info = describe_bag(reader.path, scan_topic=reader.scan_topic, odom_topic=reader.odom_topic)
    except (ValueError, OSError) as exc:
        typer.echo(f"fuzzypos: error: {' '.join(str(exc).split())}", err=True)
        raise typer.Exit(code=2) from None
    info.path = log.name
    return info


def bag_alone(
    path: Path, odom_topic: str | None, json_out: bool, console: Console
) -> tuple[bool, BagInfo | None]:
    """``info``'s first look into a bag: ``(shown, info)``. A bag without one LaserScan topic
    to read (none, as in a bag that ``run --bag-out`` wrote, or several without
    ``--scan-topic``) is shown here: its topics, transforms and defaults (:func:`bag_tables`;
    ``{"bag": …}`` with ``json_out``) and a note on stderr of what ``run`` needs. A bag with
    one scan topic is not shown, and its ``info`` is kept for ``info`` to show beside the
    log's table. ``(False, None)`` for anything else (a CARMEN log, a pipe, a path that is no
    bag or cannot be read): ``info`` reads it itself and says what is wrong."""
    from ..io import log_kind
    from ..io.bag_info import describe_bag

    try:
        if not (path.is_file() or path.is_dir()):  # a pipe is read once, by info itself
            return False, None
        if log_kind(path) not in ("ros1", "ros2"):
            return False, None
        info = describe_bag(path, odom_topic=odom_topic)
    except (ValueError, OSError):
        return False, None  # info's own reading says what is wrong, in one line
    if info.scan_topic is not None:
        return False, info
    if json_out:
        typer.echo(json.dumps({"bag": info.as_dict()}, indent=2))
    else:
        console.print(*bag_tables(info))
    why = (
        "no sensor_msgs/msg/LaserScan topic, so no scans to describe or run"
        if not info.scan_candidates
        else "LaserScan topics " + ", ".join(info.scan_candidates) + ": pass --scan-topic to "
        "pick one for its scans (and for run)"
    )
    typer.echo(f"note: {path}: {why}", err=True)
    return True, info


def log_table(title: str, result: LogInfo, scanner: ScannerConfig) -> Table:
    """``info``'s table of what a log holds (:func:`~fuzzypos.io.logs.describe_log`'s
    ``result``; the "no return" rows judged by ``scanner``)."""
    table = Table(title=title, show_header=False)
    table.add_column("", style="bold")
    table.add_column("")

    def stamp(t: float | None) -> str:
        return "–" if t is None else repr(t)

    angles = fov_text = duration = "–"
    if result.angle_min_deg is not None and result.angle_max_deg is not None:
        angles = f"{result.angle_min_deg:.3f}° … {result.angle_max_deg:.3f}°"
    if result.field_of_view_deg is not None:
        fov_text = f"{result.field_of_view_deg:.3f}° (beams × increment)"
    if result.duration_s is not None:
        duration = f"{result.duration_s:.3f} s"
    elif result.stamp_problem is not None:
        duration = "unknown: the stamps are corrupt (see the warning)"
    rows = [
        ("kind", result.kind),
        ("scans", str(result.scans)),
        ("beams", ", ".join(map(str, result.beams)) or "–"),
        ("beam angles", angles),
        ("field of view", fov_text),
        ("range_max", ", ".join(f"{r:g} m" for r in result.range_max) or "none finite"),
        ("first stamp", stamp(result.first_stamp)),
        ("last stamp", stamp(result.last_stamp)),
        ("duration", duration),
        ("stamps going backwards", str(result.stamps_backwards)),
        ("stamps repeated", str(result.stamps_repeated)),
        ("odometry", odometry_text(result)),
        ("truth (TRUEPOS)", f"yes ({result.scans_with_truth} scans)" if result.has_truth else "no"),
        ("bad lines skipped", str(result.bad_lines) + (" (truncated)" if result.truncated else "")),
        *no_return_rows(result.no_returns),
        *found_rows(result.no_return_values_found, scanner.find_no_return_values),
    ]
    for k, v in rows:
        table.add_row(k, v)
    return table
