"""Part of the command line (:mod:`fuzzypos.cli`): the tables and lines it prints from the
library's results, kept apart so the commands stay short."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

from rich.table import Table
from rich.text import Text

if TYPE_CHECKING:
    from .logs import LogInfo, NoReturnCount
    from .no_returns import FoundNoReturn

__all__ = [
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


def benchmark_table(rows: list[dict[str, Any]], title: str) -> tuple[Table, list[str]]:
    """The benchmark's rows as a table, and a line per failed or unscored row."""
    table = Table(title=title)
    for col in _BENCHMARK_COLUMNS:
        left = col in ("log", "config")
        table.add_column(col, justify="left" if left else "right", no_wrap=left)
    problems: list[str] = []
    for r in rows:
        if "error" in r:
            table.add_row(r["log"], r["config"], Text("failed (below)", style="red"), *[""] * 7)
            problems.append(f"{r['log']} {r['config']}: {r['error']}")
            continue
        if "not_scored" in r:
            problems.append(f"{r['log']} {r['config']}: not scored: {r['not_scored']}")
        sps = r.get("scans_per_second")
        med = r.get("local_trans_median_m")
        table.add_row(
            r["log"],
            r["config"],
            pm(r.get("all_trans_mean_m"), r.get("all_trans_std_m"), ".3f"),
            pm(r.get("all_rot_mean_deg"), r.get("all_rot_std_deg"), ".2f"),
            pm(r.get("local_trans_mean_m"), r.get("local_trans_std_m"), ".3f")
            + ("" if med is None else f" / {med:.3f}"),
            pm(r.get("local_rot_mean_deg"), r.get("local_rot_std_deg"), ".2f"),
            f"{r.get('all_matched', 0)}/{r.get('local_matched', 0)}",
            "–" if sps is None else f"{sps:.0f}",
            str(r.get("scans_degraded", "")),
            str(r.get("odometry_jumps_rejected", "")),
        )
    return table, problems


def loop_closure_lines(summary: dict[str, Any]) -> list[str]:
    """``fuzzypos run --loop-closure``'s lines: the closures, and where the run was scored
    against relations, the front end's, the online and the optimised figures side by side."""
    lc = summary.get("loop_closure")
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
            ("optimised", summary.get("relations")),
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
