"""Deprecated path: the trajectory error measures moved to :mod:`fuzzypos.eval.metrics`
(``from fuzzypos.eval import relations_errors``). This module re-exports its names for the
scripts that import them here."""

from __future__ import annotations

from .eval.metrics import (
    DEFAULT_ASSOCIATION_GAP,
    DEFAULT_RELATIONS_GAP,
    AbsoluteTrajectoryError,
    ErrorStatistics,
    EvaluationError,
    RelationsErrors,
    RelationsScore,
    RelativePoseError,
    TrajectoryErrors,
    absolute_trajectory_error,
    align_se2,
    associate,
    distance_along,
    nearest_stamps,
    position_errors,
    relations_errors,
    relative_pose_error,
    trajectory_errors,
)

__all__ = [
    "DEFAULT_ASSOCIATION_GAP",
    "DEFAULT_RELATIONS_GAP",
    "AbsoluteTrajectoryError",
    "ErrorStatistics",
    "EvaluationError",
    "RelationsErrors",
    "RelationsScore",
    "RelativePoseError",
    "TrajectoryErrors",
    "absolute_trajectory_error",
    "align_se2",
    "associate",
    "distance_along",
    "nearest_stamps",
    "position_errors",
    "relations_errors",
    "relative_pose_error",
    "trajectory_errors",
]
