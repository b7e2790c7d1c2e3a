"""Localisation in a known occupancy map (issue 37): :class:`Localizer` takes each scan and
the odometry and answers a :class:`LocalizationEstimate`: SEARCHING until the evidence picks
one place of the map over every other, then TRACKING (pose and covariance), LOST when the map
stops fitting (it then searches again). The map's likelihood field is cached beside the map
file (:mod:`.field`); the method and its cost: docs/localization.md."""

from __future__ import annotations

from .localizer import Localizer
from .types import InitialPoseError, LocalizationEstimate, LocalizerState

__all__ = ["InitialPoseError", "LocalizationEstimate", "Localizer", "LocalizerState"]
