"""Scoring trajectories against ground truth.

Pure functions over ``(n, 3)`` pose arrays ``[x, y, θ]`` (one row per scan, the same scans in
both). A later issue adds the relations metric of the Freiburg benchmark and ATE/RPE.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .geometry import wrap_angle

FloatArray = NDArray[np.float64]

__all__ = ["EvaluationError", "TrajectoryErrors", "distance_along", "position_errors", "trajectory_errors"]


class EvaluationError(ValueError):
    """Trajectories that cannot be compared (shapes, lengths, non-finite values)."""


def _poses(name: str, a: ArrayLike) -> FloatArray:
    arr = np.asarray(a, dtype=float)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise EvaluationError(f"{name} must be an (n, 3) array of poses, got shape {arr.shape}")
    if not np.isfinite(arr).all():
        raise EvaluationError(f"{name} holds non-finite values")
    return arr


def distance_along(poses: ArrayLike) -> FloatArray:
    """Cumulative distance travelled along a path, (n,), starting at 0."""
    p = _poses("poses", poses)
    steps = np.hypot(np.diff(p[:, 0]), np.diff(p[:, 1]))
    return np.concatenate([[0.0], np.cumsum(steps)])


def position_errors(truth: ArrayLike, estimate: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Per pose: the position error (m) and the absolute heading error (rad)."""
    t = _poses("truth", truth)
    e = _poses("estimate", estimate)
    if t.shape != e.shape:
        raise EvaluationError(f"truth has {t.shape[0]} poses, estimate {e.shape[0]}")
    d = np.hypot(t[:, 0] - e[:, 0], t[:, 1] - e[:, 1])
    h = np.abs(wrap_angle(t[:, 2] - e[:, 2]))
    return d, h


@dataclass(frozen=True)
class TrajectoryErrors:
    """Summary of an estimated trajectory against the truth (metres and degrees)."""

    final_position_error_m: float
    mean_position_error_m: float
    max_position_error_m: float
    mean_heading_error_deg: float
    scans_degraded: int = 0

    def as_dict(self) -> dict[str, float | int]:
        return asdict(self)


def trajectory_errors(truth: ArrayLike, estimate: ArrayLike, scans_degraded: int = 0) -> TrajectoryErrors:
    """Final, mean and maximum position error and mean heading error of ``estimate``."""
    d, h = position_errors(truth, estimate)
    if d.size == 0:
        raise EvaluationError("no poses to compare")
    return TrajectoryErrors(
        final_position_error_m=float(d[-1]),
        mean_position_error_m=float(d.mean()),
        max_position_error_m=float(d.max()),
        mean_heading_error_deg=float(np.degrees(h.mean())),
        scans_degraded=int(scans_degraded),
    )
