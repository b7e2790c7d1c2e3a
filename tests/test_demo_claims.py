"""The claims of issue 3 on the default demo (``fuzzypos demo``: seed 0, two laps of the 4 m
gym circle, 1,676 scans): the default configuration's final and mean position errors are at
least 5 times smaller than odometry's, and the paper preset's are smaller than odometry's.
The figures themselves are in the README (``make demo`` prints them)."""

from __future__ import annotations

import numpy as np
import pytest

from fuzzypos import Config, Positioner
from fuzzypos.demo import DemoSettings, simulate_gym_circle
from fuzzypos.evaluation import trajectory_errors


@pytest.fixture(scope="module")
def demo_run():
    return simulate_gym_circle(DemoSettings())


def _errors(run, config: Config):
    pos = Positioner(config)
    poses = [pos.update(s, run.odometry_pose(k)).pose.as_array() for k, s in enumerate(run.scans)]
    return trajectory_errors(run.true_poses, np.array(poses))


def test_default_is_five_times_better_than_odometry(demo_run) -> None:
    odo = trajectory_errors(demo_run.true_poses, demo_run.odometry_poses)
    est = _errors(demo_run, Config())
    assert est.final_position_error_m * 5 <= odo.final_position_error_m, (est, odo)
    assert est.mean_position_error_m * 5 <= odo.mean_position_error_m, (est, odo)


def test_paper_preset_beats_odometry(demo_run) -> None:
    odo = trajectory_errors(demo_run.true_poses, demo_run.odometry_poses)
    est = _errors(demo_run, Config.preset("paper"))
    assert est.final_position_error_m < odo.final_position_error_m, (est, odo)
    assert est.mean_position_error_m < odo.mean_position_error_m, (est, odo)
