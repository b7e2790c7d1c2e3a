"""Simulated runs of the kinds of real log we are checked on (``fuzzypos.sim.kinds``): odometry
against the default :class:`~fuzzypos.Positioner`, locally and over the whole run, as a table.

Local: the relative pose error (:func:`~fuzzypos.evaluation.relative_pose_error`) over
``WINDOWS`` scans (at 1.6 Hz, 2 scans = 1.25 s, 5 scans = 3.1 s; consecutive, non-overlapping
pairs): the mean translation (m) and rotation (°) error of the motion between the two scans.
Whole run: the final and the mean position error (:func:`~fuzzypos.evaluation.
trajectory_errors`). ``tests/test_sim_kinds.py`` states the goal with these figures: the
default no worse than odometry locally, better over the whole run.

    python benchmarks/bench_sim_kinds.py
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from fuzzypos import Positioner, sim
from fuzzypos.evaluation import relative_pose_error, trajectory_errors

#: the runs, by name: a function of the seed
KINDS: dict[str, Callable[[int], sim.SimulatedRun]] = {
    "SICK interlaced, outdoor yard (ROBOTLASER1 kind)": sim.sick_outdoor_run,
}
#: the local windows, in scans
WINDOWS = (2, 5)
SEEDS = (0, 1, 2)


@dataclass(frozen=True)
class KindFigures:
    """One trajectory's figures against the truth: per window (scans) the mean translation (m)
    and rotation (°) error of the relative motions; the final and the mean position error (m)."""

    local_translation_m: dict[int, float]
    local_rotation_deg: dict[int, float]
    final_position_m: float
    mean_position_m: float

    def cells(self) -> list[str]:
        local = [
            f"{self.local_translation_m[w]:.4f} / {self.local_rotation_deg[w]:.3f}"
            for w in sorted(self.local_translation_m)
        ]
        return [*local, f"{self.final_position_m:.3f} / {self.mean_position_m:.3f}"]


def figures(
    run: sim.SimulatedRun, poses: ArrayLike, windows: tuple[int, ...] = WINDOWS
) -> KindFigures:
    """The figures of ``poses`` (``(n, 3)``, one per scan of ``run``) against the run's truth."""
    est = np.asarray(poses, dtype=float)
    trans: dict[int, float] = {}
    rot: dict[int, float] = {}
    for w in windows:
        rpe = relative_pose_error(run.stamps, run.true_poses, run.stamps, est, delta=w)
        trans[w] = rpe.translation_m.mean
        rot[w] = rpe.rotation_deg.mean
    e = trajectory_errors(run.true_poses, est)
    return KindFigures(trans, rot, e.final_position_error_m, e.mean_position_error_m)


def estimate(run: sim.SimulatedRun, positioner: Positioner | None = None) -> np.ndarray:
    """The poses ``positioner`` (default: ``Positioner()``, the default settings) gives over
    the run's scans and odometry, ``(n, 3)``."""
    pos = Positioner() if positioner is None else positioner
    return np.array(
        [pos.update(s, run.odometry_pose(k)).pose.as_array() for k, s in enumerate(run.scans)]
    )


def main() -> None:
    local = " | ".join(
        f"{who} {w} scans trans (m) / rot (°)" for who in ("odometry", "default") for w in WINDOWS
    )
    print(f"| run | seed | {local} | odometry final / mean (m) | default final / mean (m) |")
    print("|---|---:|" + "---:|" * (2 * len(WINDOWS) + 2))
    for name, make in KINDS.items():
        for seed in SEEDS:
            run = make(seed)
            odo = figures(run, run.odometry_poses).cells()
            dflt = figures(run, estimate(run)).cells()
            row = [*odo[:-1], *dflt[:-1], odo[-1], dflt[-1]]
            print(f"| {name} | {seed} | " + " | ".join(row) + " |", flush=True)


if __name__ == "__main__":
    main()
