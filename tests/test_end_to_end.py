"""End-to-end accuracy of the default configuration on simulated runs with known truth.

Half a lap of the gym circle and a 16 m drive down the office corridor, three seeds each,
with the demo's scanner (SICK LMS200-like, 30 m) and the B21r slip. Thresholds are the
measured worst case rounded up (stated in the README):

| run | default final / mean (m), seeds 0–2 | odometry final / mean (m) |
| --- | --- | --- |
| gym, 4 m circle, ½ lap | 0.030 / 0.026, 0.034 / 0.021, 0.024 / 0.023 | 0.33–0.35 / 0.15–0.16 |
| office corridor, 16 m | 0.131 / 0.075, 0.127 / 0.058, 0.051 / 0.035 | 0.31–0.32 / 0.15–0.16 |

(``python benchmarks/bench_sim_runs.py`` prints these runs, with the paper preset.)
"""

from __future__ import annotations

import numpy as np
import pytest

from fuzzypos import Config, Positioner, sim
from fuzzypos.demo import DemoSettings
from fuzzypos.evaluation import TrajectoryErrors, trajectory_errors


def _run(
    world: sim.World, path: sim.CommandedPath, seed: int
) -> tuple[TrajectoryErrors, TrajectoryErrors]:
    run = sim.simulate_run(world, path, DemoSettings().scanner, sim.SlipModel(), seed)
    pos = Positioner(Config())
    poses, degraded = [], 0
    for k, scan in enumerate(run.scans):
        est = pos.update(scan, run.odometry_pose(k))
        poses.append(est.pose.as_array())
        degraded += est.degraded
    return (
        trajectory_errors(run.true_poses, np.array(poses), degraded),
        trajectory_errors(run.true_poses, run.odometry_poses),
    )


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_gym_circle(seed: int) -> None:
    est, odo = _run(sim.gym(), sim.CommandedPath.circle(4.0, 0.5, 0.3), seed)
    assert est.scans_degraded == 0
    assert est.final_position_error_m < 0.04 and est.mean_position_error_m < 0.03, est
    assert est.final_position_error_m < odo.final_position_error_m / 2, (est, odo)
    assert est.mean_position_error_m < odo.mean_position_error_m / 2, (est, odo)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_office_corridor(seed: int) -> None:
    est, odo = _run(
        sim.office(), sim.CommandedPath.waypoints([(-8.0, 0.0), (8.0, 0.0)], speed=0.3), seed
    )
    assert est.scans_degraded <= 2
    assert est.final_position_error_m < 0.15 and est.mean_position_error_m < 0.08, est
    assert est.final_position_error_m < odo.final_position_error_m, (est, odo)
    assert est.mean_position_error_m < odo.mean_position_error_m, (est, odo)
