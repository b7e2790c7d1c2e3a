"""What the gate and the switches that are off by default do on the shared logs.

Runs the default, the default without the gate, with the gate open even where the odometry is
the poorer (``gate.only_where_odometry_is_better`` off), with the learned odometry as the
refinement's prior or its calibration applied everywhere (``odometry_noise.in_refinement``,
``odometry_noise.calibrate``), and not trusting the odometry where it is the more precise
(``odometry_noise.trust_where_better`` off), over every shared CARMEN log (the relations metric,
as ``fuzzypos benchmark`` scores it), and prints one table with the scans the gate rejected,
the share of scans where the odometry was trusted, and the learned odometry noise and
calibration at the end of the log. Each log and variant is a Ray task with one thread
(``fuzzypos.jobs.tasks.run_tasks``: a local Ray with ``--jobs`` CPUs, or the cluster of
``RAY_ADDRESS``) where Ray is installed, else the runs go one after the other in this
process; a line on stderr says which.

    python benchmarks/bench_switches.py [--data DIR] [--jobs N] [--max-scans N]
"""

from __future__ import annotations

import argparse
import math
import os
import sys
from pathlib import Path
from typing import Any

import numpy as np

from fuzzypos import Config, Positioner, Reason
from fuzzypos.eval import relations_errors
from fuzzypos.io import open_log
from fuzzypos.io.relations import read_relations
from fuzzypos.jobs import run_tasks
from fuzzypos.jobs.benchmark import find_benchmark_logs
from fuzzypos.jobs.tasks import ray_installed

VARIANTS: dict[str, dict[str, dict[str, Any]]] = {
    "default": {},
    "gate off": {"gate": {"enabled": False}},
    "gate everywhere": {"gate": {"only_where_odometry_is_better": False}},
    "learned prior everywhere": {"odometry_noise": {"in_refinement": True}},
    "calibration everywhere": {"odometry_noise": {"calibrate": True}},
    "better odometry not trusted": {"odometry_noise": {"trust_where_better": False}},
}


def run(job: tuple[str, str, str, int | None]) -> dict[str, Any]:
    """One variant over one log: its relations figures and what the noise model learned."""
    variant, log_path, relations_path, max_scans = job
    pos = Positioner(Config().with_overrides(VARIANTS[variant]))
    stamps, poses, gated, trusted = [], [], 0, 0
    for k, rec in enumerate(open_log(log_path).records()):
        if max_scans is not None and k >= max_scans:
            break
        est = pos.update(rec.scan, rec.odometry)
        stamps.append(est.stamp)
        poses.append(est.pose.as_array())
        gated += est.reason is Reason.GATED
        trusted += pos.odometry_noise.trusted
    scores = relations_errors(np.array(stamps), np.array(poses), read_relations(relations_path))
    noise = pos.odometry_noise
    return {
        "log": Path(log_path).name,
        "variant": variant,
        **scores.as_dict(),
        "gated": gated,
        "trusted": trusted / max(len(stamps), 1),
        "alpha_translation": noise.alpha_translation,
        "alpha_rotation_deg": math.degrees(noise.alpha_rotation),
        "scale": noise.scale,
        "rotation_factor": noise.rotation_factor,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", default=os.environ.get("FUZZYPOS_DATA", "../shared/data"))
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--max-scans", type=int, default=None)
    args = parser.parse_args()
    logs = [(str(log), str(rel)) for log, rel in find_benchmark_logs(args.data)]
    logs = [(log, rel) for log, rel in logs if not log.endswith(".bag")]
    jobs = [(v, log, rel, args.max_scans) for log, rel in logs for v in VARIANTS]
    if ray_installed():
        where = os.environ.get("RAY_ADDRESS") or f"a local Ray with {max(1, args.jobs)} CPUs"
        note = f"{len(jobs)} runs as Ray tasks, one thread each, on {where}"
    else:
        note = f"Ray is not installed: the {len(jobs)} runs go one after the other in this process"
    print(note, file=sys.stderr, flush=True)
    outcomes = run_tasks(run, [(j,) for j in jobs], ray=ray_installed(), jobs=max(1, args.jobs))
    rows = [done.result() for done in outcomes]
    print(
        "| log | variant | all trans m | local trans m | local rot ° | gated | trusted "
        "| learned σ_t m/√m | learned σ_θ °/√m | scale | rotation factor |"
    )
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        print(
            f"| {r['log']} | {r['variant']} | {r['all_trans_mean_m']:.3f} "
            f"| {r['local_trans_mean_m']:.4f} | {r['local_rot_mean_deg']:.3f} | {r['gated']} "
            f"| {100.0 * r['trusted']:.0f} % "
            f"| {r['alpha_translation']:.4f} | {r['alpha_rotation_deg']:.3f} "
            f"| {r['scale']:.4f} | {r['rotation_factor']:.4f} |"
        )


if __name__ == "__main__":
    main()
