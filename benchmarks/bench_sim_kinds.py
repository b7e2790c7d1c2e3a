"""Simulated runs of the kinds of real log we are checked on (``fuzzypos.sim.kinds``): odometry
against the default :class:`~fuzzypos.Positioner`, which trusts the odometry where it is the
more precise (``odometry_noise.trust_where_better``), and against the default without that
trust, locally and over the whole run, as a table; beside them the paper's gym half lap,
whose odometry is precise step by step but biased (the B21r's slip).

Local: the relative pose error (:func:`~fuzzypos.eval.metrics.relative_pose_error`) over
``WINDOWS`` scans (at 1.6 Hz, 2 scans = 1.25 s, 5 scans = 3.1 s; consecutive, non-overlapping
pairs): the mean translation (m) and rotation (°) error of the motion between the two scans.
Whole run: the final and the mean position error (:func:`~fuzzypos.eval.metrics.
trajectory_errors`). ``tests/sim/test_sim_kinds.py`` states the goal with these figures: the
default no worse than odometry locally, better over the whole run.

    python benchmarks/bench_sim_kinds.py
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from fuzzypos import Config, Positioner, sim
from fuzzypos.eval import relative_pose_error, trajectory_errors
from fuzzypos.jobs import DemoSettings

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


def gym_half_lap(seed: int) -> sim.SimulatedRun:
    """The paper's experiment: half a lap of the gym circle with the B21r's slip, an
    odometry precise step by step but biased (slip and an outward skid)."""
    path = sim.CommandedPath.circle(4.0, 0.5, 0.3)
    return sim.simulate_run(sim.gym(), path, DemoSettings().scanner, sim.SlipModel(), seed)


#: the estimators besides odometry: the default, and the default not trusting the odometry
#: where the learned noise says it is the more precise (``odometry_noise.trust_where_better``)
CONFIGS: dict[str, Config] = {
    "default": Config(),
    "not trusting": Config().with_overrides({"odometry_noise": {"trust_where_better": False}}),
}


def main() -> None:
    local = " | ".join(f"{w} scans trans (m) / rot (°)" for w in WINDOWS)
    print(f"| run | seed | estimate | {local} | final / mean (m) |")
    print("|---|---:|---|" + "---:|" * (len(WINDOWS) + 1))
    for name, make in {
        **KINDS,
        "gym half lap, B21r slip (paper's experiment)": gym_half_lap,
    }.items():
        for seed in SEEDS:
            run = make(seed)
            rows = {"odometry": figures(run, run.odometry_poses).cells()}
            for label, config in CONFIGS.items():
                rows[label] = figures(run, estimate(run, Positioner(config))).cells()
            for label, cells in rows.items():
                print(f"| {name} | {seed} | {label} | " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main()
