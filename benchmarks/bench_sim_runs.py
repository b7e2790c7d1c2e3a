"""End-to-end accuracy on simulated runs with known truth: the runs of
``tests/jobs/test_end_to_end.py`` (half a lap of the gym circle, the office corridor; seeds 0-2),
odometry against the default and the paper preset, as a table.

    python benchmarks/bench_sim_runs.py
"""

from __future__ import annotations

import numpy as np

from fuzzypos import Config, Positioner, sim
from fuzzypos.eval import trajectory_errors
from fuzzypos.jobs import DemoSettings

RUNS = {
    "gym, 4 m circle, half a lap": (sim.gym, lambda: sim.CommandedPath.circle(4.0, 0.5, 0.3)),
    "office corridor, 16 m": (
        sim.office,
        lambda: sim.CommandedPath.waypoints([(-8.0, 0.0), (8.0, 0.0)], speed=0.3),
    ),
}


def main() -> None:
    print(
        "| run | seed | odometry final / mean (m) | paper final / mean (m) "
        "| default final / mean (m) |"
    )
    print("|---|---:|---:|---:|---:|")
    for name, (world, path) in RUNS.items():
        for seed in (0, 1, 2):
            run = sim.simulate_run(world(), path(), DemoSettings().scanner, sim.SlipModel(), seed)
            cells = []
            odo = trajectory_errors(run.true_poses, run.odometry_poses)
            cells.append(f"{odo.final_position_error_m:.3f} / {odo.mean_position_error_m:.3f}")
            for preset in ("paper", "default"):
                pos = Positioner(Config.preset(preset))
                poses = [
                    pos.update(s, run.odometry_pose(k)).pose.as_array()
                    for k, s in enumerate(run.scans)
                ]
                e = trajectory_errors(run.true_poses, np.array(poses))
                cells.append(f"{e.final_position_error_m:.3f} / {e.mean_position_error_m:.3f}")
            print(f"| {name} | {seed} | " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main()
