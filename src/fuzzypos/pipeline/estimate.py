"""What the positioner returns for each scan: the :class:`Estimate` and the :class:`Reason` it
is what it is."""

from __future__ import annotations

import enum
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..features import Features
from ..geometry import Pose2D

__all__ = ["Estimate", "Reason"]


class Reason(str, enum.Enum):
    """Why an estimate is what it is (a string enum: it compares equal to its value)."""

    #: the first scan: the trajectory starts at its odometry pose (or the origin)
    FIRST_SCAN = "first scan"
    #: the scan was matched against the keyframe
    MATCHED = "matched"
    #: the odometry did not move: neither did the estimate
    STANDING_STILL = "standing still"
    #: too few feature points in this scan or the keyframe to pair (§3.7)
    TOO_FEW_FEATURES = "too few features"
    #: the feature points paired, but too few pairs gave a pose (§4)
    TOO_FEW_PAIRS = "too few pairs"
    #: the match disagreed with the odometry beyond the gate: the odometry was kept
    GATED = "rejected by the gate"
    #: a match the features alone gave (no fit confirmed it) contradicted the odometry beyond
    #: its learned noise and the features' own error: the odometry was kept
    CONTRADICTS_ODOMETRY = "contradicts the odometry"

    def __str__(self) -> str:
        return self.value


@dataclass(frozen=True, eq=False)
class Estimate:
    """The estimate at one scan.

    ``pose``: the robot's pose in the trajectory frame (which starts at the first scan's
    odometry pose, or the origin). ``increment``: the pose of this scan in the frame of the
    previous one (the identity for the first scan). ``prior``: the increment pairing started
    from. ``n_pairs``: the pairs the increment rests on (line pairs where line-to-line matching
    gave it, feature-point pairs where the paper's pairing did). ``degraded``: True where the
    estimate fell back to the prior. ``features``: this scan's features (None unless kept).
    ``reason``: why the estimate is what it is. ``odometry_rejected``: the odometry increment
    was no robot's motion (a jump) and the last increment replaced it as the prior.
    ``refined``: the point-to-line refinement gave it. ``covariance``: the 3×3 covariance
    of the increment's error ε = ⊖(true increment) ⊕ ``increment`` as (x, y in m, θ in rad)
    in the previous scan's frame. ``keyframe_covariance``: the 3×3 covariance of this scan's
    pose relative to its keyframe, from the fit against the keyframe itself (what a pose
    graph's edge between keyframes needs; not a sum of per-scan covariances); the keyframe is
    the one the scan was matched against (a scan that becomes the next keyframe is still
    relative to the old one). ``gate``: the Mahalanobis distance squared of the match's
    disagreement with the odometry under both covariances (None where not compared).
    ``keyframe``: this scan became the keyframe the next scans are matched against (the first
    scan, and every renewal: what a pose graph's vertices are).
    """

    stamp: float
    pose: Pose2D
    increment: Pose2D
    prior: Pose2D
    n_pairs: int
    degraded: bool
    features: Features | None = None
    reason: Reason = Reason.MATCHED
    odometry_rejected: bool = False
    refined: bool = False
    covariance: NDArray[np.float64] | None = None
    keyframe_covariance: NDArray[np.float64] | None = None
    gate: float | None = None
    keyframe: bool = False

    @classmethod
    def _trusted(
        cls,
        *,
        stamp: float,
        pose: Pose2D,
        increment: Pose2D,
        prior: Pose2D,
        n_pairs: int,
        degraded: bool,
        features: Features | None,
        reason: Reason,
        odometry_rejected: bool,
        refined: bool,
        covariance: NDArray[np.float64] | None,
        keyframe_covariance: NDArray[np.float64] | None,
        gate: float | None,
        keyframe: bool,
    ) -> Estimate:
        """The estimate of every field, as the constructor builds it, straight into the
        instance's dict (the frozen dataclass's ``__init__`` sets each of the fourteen through
        ``object.__setattr__``; the positioner's own)."""
        e = object.__new__(cls)
        e.__dict__.update(
            stamp=stamp, pose=pose, increment=increment, prior=prior, n_pairs=n_pairs,
            degraded=degraded, features=features, reason=reason,
            odometry_rejected=odometry_rejected, refined=refined, covariance=covariance,
            keyframe_covariance=keyframe_covariance, gate=gate, keyframe=keyframe,
        )  # fmt: skip
        return e
