"""What the localizer answers: its state, each scan's estimate, and the error of an initial
pose that cannot be."""

from __future__ import annotations

import enum
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..errors import FuzzyposError
from ..geometry import Pose2D

__all__ = ["InitialPoseError", "LocalizationEstimate", "LocalizerState"]


class InitialPoseError(FuzzyposError, ValueError):
    """An initial pose off the map, or inside a wall or unknown space far from free space
    (the message names the pose)."""


class LocalizerState(str, enum.Enum):
    """Where the localizer stands."""

    SEARCHING = "searching"  #: not yet localised (global search; ambiguous places stay here)
    TRACKING = "tracking"  #: localised: pose and covariance are valid
    LOST = "lost"  #: was tracking, the map no longer fits; relocalising globally


@dataclass(frozen=True)
class LocalizationEstimate:
    """One scan's answer: the pose in the map frame and its covariance (x, y, θ) where
    localised (``state`` TRACKING), else None; the increment's covariance since the previous
    scan (robot frame); how sure it is (0..1: the evidence's decisiveness while searching,
    the scan's fit to the map while tracking) and why, in one short phrase."""

    stamp: float
    state: LocalizerState
    pose: Pose2D | None
    covariance: NDArray[np.float64] | None
    step_covariance: NDArray[np.float64] | None
    confidence: float
    reason: str

    @property
    def localised(self) -> bool:
        """Whether the pose is valid (the state is TRACKING)."""
        return self.state is LocalizerState.TRACKING
