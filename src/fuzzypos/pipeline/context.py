"""A scan's way through the positioner's stages: what the prior stage gives the later ones
(:class:`ScanContext`, one per scan, filled in stage by stage) and what the step from the
keyframe gives (:class:`Matched`), instead of tuples and long lists of arguments."""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from ..features import Features
from ..scan import LaserScan
from .estimate import Reason
from .prior import Prior
from .uncertainty import Assessment

__all__ = ["Matched", "ScanContext"]

FloatArray = NDArray[np.float64]


class Matched(NamedTuple):
    """The step from the keyframe (features → match → refine → assess): the scan's
    ``features``, the match's pairs and reason, whether a fit gave the motion (``refined``),
    the motion from the keyframe (``from_key``; None: the prior stands) and the assessment."""

    features: Features
    n_pairs: int
    reason: Reason
    refined: bool
    from_key: FloatArray | None
    assessment: Assessment


@dataclass(eq=False, slots=True)
class ScanContext:
    """One scan on its way through the stages. The prior stage fills in: the ``scan``, its
    odometry ``prior`` (calibrated), the previous scan's pose from the keyframe ``t_prev``,
    the same prior from the keyframe ``key_prior``, the prior's covariance, the information
    of the features' and of the odometry's motion for the refinement (``information``; None:
    the fixed sigmas) and the previous scan's covariance relative to the keyframe before
    this scan's assessment (``held``). The step from the keyframe then leaves its
    :class:`Matched` (``matched``), which the contradiction check may overrule."""

    scan: LaserScan
    prior: Prior
    t_prev: FloatArray
    key_prior: FloatArray
    prior_covariance: FloatArray
    information: tuple[FloatArray, FloatArray] | None
    held: FloatArray
    matched: Matched | None = None

    @property
    def held_information(self) -> FloatArray | None:
        """The odometry's information for the refinement's hold (None: the fixed sigmas)."""
        return None if self.information is None else self.information[1]
