"""The speed-up of ``fuzzypos batch`` on this machine: the shared logs (every log under
``--data``: intel, aces as a CARMEN file and as a ROS1 bag) run once with ``--jobs 1`` (one
after the other, one Ray task at a time) and once with ``--jobs 2``, each into a fresh
temporary folder (nothing skipped), with the default configuration. Prints the whole
process's wall time of each command (Ray's start-up and each worker's loading of the
compiled kernels included), the sum of the runs' own seconds from ``batch.json``, and the
speed-up (the ``--jobs 1`` wall time over each one's), and the machine's load average
before and after each command (other jobs on the machine take CPUs from the parallel run).
The command runs on a local Ray (``RAY_ADDRESS`` is dropped from its environment).

    python benchmarks/bench_batch.py [--data ../shared/data] [--max-scans N] [--jobs 2]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from fuzzypos.jobs.batch import find_logs
from fuzzypos.jobs.folders import log_name

#: ``fuzzypos batch`` through this interpreter (the checkout's package, whatever is installed)
COMMAND = [sys.executable, "-c", "from fuzzypos.cli import main; main()", "batch"]


def run_batch_command(
    data: str, jobs: int, max_scans: int | None, out: Path
) -> tuple[float, list[dict[str, Any]]]:
    """One ``fuzzypos batch`` over ``data`` into ``out``: its wall seconds and batch.json's rows."""
    cmd = [*COMMAND, data, "--out", str(out), "--jobs", str(jobs)]
    if max_scans is not None:
        cmd += ["--max-scans", str(max_scans)]
    env = {k: v for k, v in os.environ.items() if k != "RAY_ADDRESS"}
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True, check=False)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        sys.exit(f"{' '.join(cmd[3:])}: exit {proc.returncode}\n{proc.stdout}{proc.stderr}")
    rows = json.loads((out / "batch.json").read_text(encoding="utf-8"))["rows"]
    return wall, rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=os.environ.get("FUZZYPOS_DATA", "../shared/data"))
    ap.add_argument("--max-scans", type=int, default=None, help="scans per run (default all)")
    ap.add_argument("--jobs", type=int, default=2, help="the parallel run's jobs")
    args = ap.parse_args()
    try:
        logs = find_logs([args.data])
    except (OSError, ValueError) as exc:
        sys.exit(f"{args.data}: {exc} (the shared data; see --data)")
    names = ", ".join(log_name(p, keep_format=True) for p in logs)
    print(f"logs: {names}; cpus: {os.cpu_count()}", flush=True)
    results = []
    for jobs in (1, args.jobs):
        load = os.getloadavg()[0]
        with tempfile.TemporaryDirectory(prefix="bench_batch-") as tmp:
            wall, rows = run_batch_command(args.data, jobs, args.max_scans, Path(tmp) / "out")
        if any(r["status"] != "ok" for r in rows):
            sys.exit(f"--jobs {jobs}: a run did not finish: {rows}")
        results.append((jobs, wall, rows, f"{load:.1f} / {os.getloadavg()[0]:.1f}"))
        print(f"--jobs {jobs}: {wall:.1f} s", file=sys.stderr, flush=True)
    sequential = results[0][1]
    print()
    print(
        "| --jobs | runs | scans | wall s (whole command) | sum of runs' s | speed-up "
        "| load before / after |"
    )
    print("|---:|---:|---:|---:|---:|---:|---:|")
    for jobs, wall, rows, loads in results:
        scans = sum(r["scans"] for r in rows)
        runs_s = sum(r["seconds"] for r in rows)
        print(
            f"| {jobs} | {len(rows)} | {scans:,} | {wall:.1f} | {runs_s:.1f} | "
            f"{sequential / wall:.2f} | {loads} |"
        )
    print()
    print("| --jobs | log | scans | run s |")
    print("|---:|---|---:|---:|")
    for jobs, _wall, rows, _loads in results:
        for r in sorted(rows, key=lambda r: r["log"]):
            name = log_name(r["log"], keep_format=True)
            print(f"| {jobs} | {name} | {r['scans']:,} | {r['seconds']:.1f} |")


if __name__ == "__main__":
    main()
