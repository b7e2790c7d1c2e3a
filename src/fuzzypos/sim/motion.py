"""Pose sequences for tests and benchmarks: :func:`arc_path`, :func:`drifting_odometry` and
:func:`random_motions` (single rigid motions between two scans, :class:`MotionTrial`).

For a robot driving a commanded path with wheel slip, see :mod:`fuzzypos.sim.robot`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..geometry import Pose2D, compose, relative
from .scanner import ScannerModel, visible_corners
from .world import FloatArray, SimError, World

__all__ = ["arc_path", "drifting_odometry", "MotionTrial", "random_motions"]


def arc_path(start: Pose2D, n: int, step: float, turn_deg: float) -> list[Pose2D]:
    """``n`` poses from ``start``, each ``step`` metres forward and ``turn_deg`` degrees left of
    the previous one (a constant-curvature arc; ``turn_deg=0`` is a straight line)."""
    if n < 1:
        raise SimError(f"arc_path needs at least one pose, got n={n}")
    inc = np.array([step, 0.0, math.radians(turn_deg)])
    poses = [start.as_array()]
    for _ in range(n - 1):
        poses.append(compose(poses[-1], inc))
    return [Pose2D.from_array(p) for p in poses]


def drifting_odometry(
    true_poses: Sequence[Pose2D],
    scale: float = 1.0,
    rotation_bias_deg: float = 0.0,
    noise_std: tuple[float, float] = (0.0, 0.0),
    rng: np.random.Generator | None = None,
) -> list[Pose2D]:
    """Odometry that integrates distorted true increments: translation scaled by ``scale``,
    ``rotation_bias_deg`` added to every increment's rotation, plus Gaussian noise
    ``(metres, degrees)`` per increment. It starts at the first true pose."""
    if not true_poses:
        return []
    rng = rng if rng is not None else np.random.default_rng(0)
    arr = np.array([p.as_array() for p in true_poses])
    odo = [arr[0]]
    for k in range(1, len(arr)):
        u = relative(arr[k - 1], arr[k])
        u[:2] *= scale
        u[2] += math.radians(rotation_bias_deg)
        u[:2] += rng.normal(0.0, noise_std[0], 2)
        u[2] += math.radians(rng.normal(0.0, noise_std[1]))
        odo.append(compose(odo[-1], u))
    return [Pose2D.from_array(p) for p in odo]


@dataclass(frozen=True, eq=False)
class MotionTrial:
    """One simulated motion: the world poses of two scans, the true increment between them
    (``⊖start ⊕ end``) and an odometry increment (the true one composed with an error)."""

    start: FloatArray
    end: FloatArray
    increment: FloatArray
    odometry: FloatArray


def random_motions(
    world: World,
    scanner: ScannerModel,
    n: int,
    seed: int,
    area: tuple[float, float] = (1.5, 1.0),
    max_translation: float = 0.5,
    max_rotation_deg: float = 20.0,
    odometry_error: tuple[float, float] = (0.07, 5.0),
    min_corners: int = 2,
) -> list[MotionTrial]:
    """``n`` random rigid motions (|t| ≤ ``max_translation``, uniform over the disc; |θ| ≤
    ``max_rotation_deg``) from random start poses in ``|x| ≤ area[0], |y| ≤ area[1]`` (any
    heading), keeping only those where both poses see at least ``min_corners`` corners
    (:func:`visible_corners`). The odometry increment is the true one composed with an error
    uniform within ±``odometry_error[0]`` metres per axis and ±``odometry_error[1]`` degrees.
    """
    rng = np.random.default_rng(seed)
    trials: list[MotionTrial] = []
    for _ in range(50 * n):
        if len(trials) == n:
            break
        start = np.array(
            [
                rng.uniform(-area[0], area[0]),
                rng.uniform(-area[1], area[1]),
                rng.uniform(-math.pi, math.pi),
            ]
        )
        t = max_translation * math.sqrt(rng.uniform())
        phi = rng.uniform(-math.pi, math.pi)
        inc = np.array(
            [
                t * math.cos(phi),
                t * math.sin(phi),
                math.radians(rng.uniform(-max_rotation_deg, max_rotation_deg)),
            ]
        )
        ex, ey = odometry_error[0], odometry_error[0]
        err = np.array(
            [
                rng.uniform(-ex, ex),
                rng.uniform(-ey, ey),
                math.radians(rng.uniform(-odometry_error[1], odometry_error[1])),
            ]
        )
        end = compose(start, inc)
        if (
            len(visible_corners(world, start, scanner)) < min_corners
            or len(visible_corners(world, end, scanner)) < min_corners
        ):
            continue
        trials.append(MotionTrial(start, end, inc, compose(inc, err)))
    if len(trials) < n:
        raise SimError(
            f"random_motions: only {len(trials)} of {n} motions see {min_corners} corners"
        )
    return trials
