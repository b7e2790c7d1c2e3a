"""Scoring a trajectory: the error measures against ground truth or the Freiburg benchmark's
relations (:mod:`.metrics`) and the scoring of trajectory files (:mod:`.scoring`)."""

from __future__ import annotations

from .metrics import (
    AbsoluteTrajectoryError,
    ErrorStatistics,
    EvaluationError,
    RelationsErrors,
    RelationsScore,
    RelativePoseError,
    TrajectoryErrors,
    absolute_trajectory_error,
    position_errors,
    relations_errors,
    relative_pose_error,
    trajectory_errors,
)
from .scoring import Evaluation, evaluate_trajectory

__all__ = [
    "AbsoluteTrajectoryError",
    "ErrorStatistics",
    "Evaluation",
    "EvaluationError",
    "RelationsErrors",
    "RelationsScore",
    "RelativePoseError",
    "TrajectoryErrors",
    "absolute_trajectory_error",
    "evaluate_trajectory",
    "position_errors",
    "relations_errors",
    "relative_pose_error",
    "trajectory_errors",
]
