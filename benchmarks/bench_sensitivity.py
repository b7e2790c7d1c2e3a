"""How much the relations metric of the shared logs moves when settings that have nothing to do
with long relations change a little: the default, and the default with one refinement setting
nudged (iterations 12 / 18, residual scale 0.04 / 0.06). Prints one row per log and variant.

The long relations measure drift, which a few degrees of heading lost at one turn decide; the
local ones measure the matcher. This shows how far apart the two kinds of figure are in
robustness, so that a change is not judged on one lucky run.

Each log and variant is a Ray task with one thread (``fuzzypos.jobs.tasks.run_tasks``, as
``fuzzypos batch``: a local Ray with ``--jobs`` CPUs, or the cluster of ``RAY_ADDRESS``)
where Ray (the ``ray`` extra) is installed, else the runs go one after the other in this
process; a line on stderr says which.

    python benchmarks/bench_sensitivity.py [--data ../shared/data] [--jobs 2]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

from fuzzypos import Config, Positioner
from fuzzypos.eval import relations_errors
from fuzzypos.io import open_log
from fuzzypos.io.relations import read_relations
from fuzzypos.jobs import run_tasks
from fuzzypos.jobs.benchmark import find_benchmark_logs
from fuzzypos.jobs.tasks import ray_installed

VARIANTS: dict[str, dict[str, dict[str, object]]] = {
    "default": {},
    "iterations 12": {"refinement": {"iterations": 12}},
    "iterations 18": {"refinement": {"iterations": 18}},
    "residual_scale 0.04": {"refinement": {"residual_scale": 0.04}},
    "residual_scale 0.06": {"refinement": {"residual_scale": 0.06}},
}


def run_one(log: str, relations: str, variant: str) -> tuple[str, str, dict[str, float], float]:
    records = list(open_log(log).records())
    pos = Positioner(Config().with_overrides(VARIANTS[variant]))
    t0 = time.perf_counter()
    poses = [pos.update(r.scan, r.odometry).pose.as_array() for r in records]
    seconds = time.perf_counter() - t0
    stamps = np.array([r.scan.stamp for r in records])
    score = relations_errors(stamps, np.array(poses), read_relations(relations)).as_dict()
    return Path(log).name, variant, score, len(records) / seconds


Row = tuple[str, str, dict[str, float], float]


def run_all(pairs: list[tuple[Path, Path]], jobs: int, ray: bool) -> list[Row]:
    """:func:`run_one` for every log and variant, as Ray tasks (``ray``) or one after the
    other; the rows in the order of the logs, then the variants."""
    calls = [(os.fspath(lg), os.fspath(rel), v) for lg, rel in pairs for v in VARIANTS]
    return [done.result() for done in run_tasks(run_one, calls, ray=ray, jobs=jobs)]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=os.environ.get("FUZZYPOS_DATA", "../shared/data"))
    ap.add_argument("--jobs", type=int, default=1, help="the local Ray's CPUs")
    args = ap.parse_args()
    try:
        pairs = find_benchmark_logs(args.data)
    except FileNotFoundError:
        sys.exit(f"{args.data}: no such folder (the shared data; see --data)")
    ray = ray_installed()
    n = len(pairs) * len(VARIANTS)
    if ray:
        where = os.environ.get("RAY_ADDRESS") or f"a local Ray with {max(1, args.jobs)} CPUs"
        note = f"{n} runs as Ray tasks, one thread each, on {where}"
    else:
        note = f"Ray is not installed: the {n} runs go one after the other in this process"
    print(note, file=sys.stderr, flush=True)
    rows = run_all(pairs, max(1, args.jobs), ray)
    print(
        "| log | variant | all trans m | all rot ° | local trans m / median | local rot ° "
        "| scans/s (Positioner) |"
    )
    print("|---|---|---:|---:|---:|---:|---:|")
    for log, variant, s, rate in rows:
        print(
            f"| {log} | {variant} | {s['all_trans_mean_m']:.3f} | {s['all_rot_mean_deg']:.2f} | "
            f"{s['local_trans_mean_m']:.4f} / {s['local_trans_median_m']:.4f} | "
            f"{s['local_rot_mean_deg']:.3f} | {rate:,.0f} |"
        )


if __name__ == "__main__":
    main()
