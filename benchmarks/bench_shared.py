"""The shared logs' figures as a report: ``fuzzypos benchmark`` on every shared log, written to
``docs/benchmarks/shared-logs.md`` with the date, commit, machine and command.

    python benchmarks/bench_shared.py [--data ../shared/data] [--max-scans N]
        [--no-loop-closure] [--out docs/benchmarks/shared-logs.md]

``fuzzypos benchmark`` runs the raw odometry, the paper preset, the default and the default
with loop closure (its optimised trajectory and its online poses) on every log under
``--data`` with a ``NAME.relations`` beside it (fr079 as its CARMEN log and its bag), and
scores each on the relations: mean translational (m) and rotational (°) error over all
relations and over the local ones (t2 − t1 ≤ 10 s). The report holds those figures, the
scans each run degraded, and each run's all-relations figure over the odometry's on the same
log (✗ above 1: worse than the odometry, which the front end must never be).
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import shlex
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_honesty import commit, machine

#: the columns: benchmark.json's key, the heading, the format
COLUMNS = (
    ("all_trans_mean_m", "all m", "{:.4f}"),
    ("all_rot_mean_deg", "all °", "{:.3f}"),
    ("local_trans_mean_m", "local m", "{:.4f}"),
    ("local_rot_mean_deg", "local °", "{:.3f}"),
    ("scans", "scans", "{:d}"),
    ("scans_degraded", "degraded", "{:d}"),
)


def run_benchmark(data: Path, out: Path, max_scans: int | None, loop_closure: bool) -> list[dict]:
    """``fuzzypos benchmark --json`` in a new process; its rows."""
    args = ["benchmark", "--data", str(data), "--out", str(out), "--json"]
    args += [] if max_scans is None else ["--max-scans", str(max_scans)]
    args += ["--loop-closure"] if loop_closure else ["--no-loop-closure"]
    done = subprocess.run(
        [sys.executable, "-c", "from fuzzypos.cli import app; app()", *args],
        capture_output=True, text=True, timeout=7200,
    )  # fmt: skip
    if done.returncode not in (0, 1):
        raise SystemExit(f"fuzzypos benchmark failed ({done.returncode}): {done.stderr.strip()}")
    rows: list[dict[str, Any]] = json.loads(done.stdout)
    for r in rows:
        r.pop("results", None)  # a temporary folder
    return rows


def table(rows: list[dict[str, Any]]) -> str:
    """The rows as markdown, log by log, with each run's all-relations figure over the
    odometry's on that log."""
    odometry = {r["log"]: r.get("all_trans_mean_m") for r in rows if r["config"] == "odometry"}
    head = ["log", "run"] + [h for _, h, _ in COLUMNS] + ["all m ÷ odometry"]
    lines = ["| " + " | ".join(head) + " |", "|---|---|" + "---:|" * (len(head) - 2)]
    for r in sorted(rows, key=lambda r: r["log"]):
        if "error" in r:
            lines.append(f"| {r['log']} | {r['config']} | failed: {r['error']} |")
            continue
        cells = ["" if r.get(key) is None else fmt.format(r[key]) for key, _, fmt in COLUMNS]
        base, own = odometry.get(r["log"]), r.get("all_trans_mean_m")
        ratio = ""
        if base and own is not None and r["config"] != "odometry":
            ratio = f"{own / base:.2f}" + (" ✗" if own > base else "")
        lines.append(f"| {r['log']} | {r['config']} | " + " | ".join(cells) + f" | {ratio} |")
    return "\n".join(lines) + "\n"


def markdown(rows: list[dict[str, Any]], meta: dict[str, str]) -> str:
    return (
        "# The shared logs\n\n"
        f"- date: {meta['date']}\n- commit: {meta['commit']}\n- machine: {meta['machine']}\n"
        f"- command: `{meta['command']}`\n- data: {meta['data']}\n\n"
        "`fuzzypos benchmark` on every shared log: the raw odometry, the paper preset, the "
        "default (the front end) and the default with loop closure (`loop-closure`: the "
        "optimised trajectory; `loop-closure-online`: each scan's pose as first output), "
        "scored on the log's relations (mean errors over all relations and over the local "
        "ones, t2 − t1 ≤ 10 s), and each run's all-relations error over the odometry's "
        "(✗: worse than the odometry). `benchmarks/bench_shared.py`'s docstring has the "
        "details.\n\n" + table(rows)
    )


def main(argv: list[str] | None = None) -> None:
    here = Path(__file__).resolve().parent
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=here.parent.parent / "shared" / "data")
    ap.add_argument("--max-scans", type=int, default=None)
    ap.add_argument("--no-loop-closure", dest="loop_closure", action="store_false")
    ap.add_argument("--out", type=Path, default=here.parent / "docs/benchmarks/shared-logs.md")
    a = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        rows = run_benchmark(a.data, Path(tmp), a.max_scans, a.loop_closure)
    meta = {
        "date": datetime.datetime.now().isoformat(timespec="seconds"),
        "commit": commit(),
        "machine": machine(),
        "command": (
            "python benchmarks/bench_shared.py "
            + shlex.join(argv if argv is not None else sys.argv[1:])
        ).strip(),
        "data": os.path.relpath(a.data, here.parent),  # no machine path in the report
    }
    text = markdown(rows, meta)
    print(text)
    a.out.parent.mkdir(parents=True, exist_ok=True)
    a.out.write_text(text, encoding="utf-8")
    a.out.with_suffix(".json").write_text(json.dumps({**meta, "rows": rows}, indent=2) + "\n")


if __name__ == "__main__":
    main()
