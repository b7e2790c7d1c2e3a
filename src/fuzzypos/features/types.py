"""The feature containers that the extraction (:mod:`.extract`) and the compiled point features
(:mod:`.points`) share: the kinds of feature point, :class:`FeaturePoints`, :class:`Lines` and
the corners' context the point features are computed from."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import NDArray

from .._kernels.packing import Unpacks
from ..config import Config
from ..errors import FuzzyposError
from ..fuzzy import RuleBases
from ..geometry import stack_columns

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]

__all__ = [
    "BREAK_POINT",
    "ANGULAR_POINT",
    "VIRTUAL_ANGULAR_POINT",
    "KIND_NAMES",
    "FeatureError",
    "FeaturePoints",
    "Lines",
]

BREAK_POINT = 0
ANGULAR_POINT = 1
VIRTUAL_ANGULAR_POINT = 2
KIND_NAMES = ("break point", "angular point", "virtual angular point")


class FeatureError(FuzzyposError, ValueError):
    """Features handed to a stage that cannot use them: a corner context built by hand whose
    sizes or indices do not fit together, lines without the variances line matching needs."""


# ---------------------------------------------------------------------------------------------
# data containers
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class FeaturePoints:
    """Point features of one scan, in the robot frame.

    ``kind`` is BREAK_POINT, ANGULAR_POINT or VIRTUAL_ANGULAR_POINT; ``uncertainty`` in [0, 1]
    is the fuzzy uncertainty (eq. 4 for break and sampled angular points, eq. 11 for virtual
    and refined angular points).
    """

    xy: FloatArray
    uncertainty: FloatArray
    kind: NDArray[np.int8]

    def __len__(self) -> int:
        return int(self.xy.shape[0])

    def select(self, mask: BoolArray) -> FeaturePoints:
        return FeaturePoints(
            self.xy.compress(mask, axis=0), self.uncertainty[mask], self.kind[mask]
        )

    @classmethod
    def empty(cls) -> FeaturePoints:
        return cls(np.zeros((0, 2)), np.zeros(0), np.zeros(0, dtype=np.int8))


@dataclass(frozen=True, eq=False)
class Lines(Unpacks):
    """Line features in normal form ``normal · p = distance`` (robot frame).

    ``start``/``end`` are the segment's endpoints (§3.5), ``centre`` their midpoint, ``sigma``
    the mean point-to-line distance (eq. 8), ``delta`` the mean point uncertainty (eq. 6) and
    ``uncertainty`` the line's fuzzy uncertainty (eq. 9, Table 2). ``segment`` is the id of the
    segment the line was fitted to and ``cluster`` its cluster. ``angle_variance`` and
    ``distance_variance`` are the least-squares variances of the normal's angle and of the
    distance (from the residual scatter, at least 1 mm), for line-to-line matching.
    """

    normal: FloatArray
    distance: FloatArray
    start: FloatArray
    end: FloatArray
    centre: FloatArray
    n_points: IntArray
    sigma: FloatArray
    delta: FloatArray
    uncertainty: FloatArray
    segment: IntArray
    cluster: IntArray
    angle_variance: FloatArray | None = None
    distance_variance: FloatArray | None = None

    def __len__(self) -> int:
        return int(self.normal.shape[0])

    @property
    def direction(self) -> FloatArray:
        """Unit direction along each line (the normal turned by −90°)."""
        return stack_columns(self.normal[:, 1], -self.normal[:, 0])

    @cached_property
    def length(self) -> FloatArray:
        return np.hypot(self.end[:, 0] - self.start[:, 0], self.end[:, 1] - self.start[:, 1])

    @cached_property
    def normal_angle(self) -> FloatArray:
        """The angle of each line's normal, atan2(n_y, n_x)."""
        return np.arctan2(self.normal[:, 1], self.normal[:, 0])


@dataclass(frozen=True, eq=False)
class _CornerContext(Unpacks):
    """What the point features of one scan are computed from, on first use."""

    cfg: Config
    bases: RuleBases
    lines: Lines
    kept_points: FloatArray
    kept_uncertainty: FloatArray
    kept_ranges: FloatArray
    angle_increment: float
    corner_index: IntArray
    corner_xy: FloatArray
    joined: BoolArray
    corner_a: IntArray
    corner_b: IntArray
    corner_dv: FloatArray
    distance_scale: float
    line_distance_scale: float
    seg_before: IntArray
    seg_after: IntArray
    break_mask: BoolArray


_PointFeatures = tuple[FeaturePoints, FeaturePoints, IntArray, FeaturePoints, FeaturePoints]
