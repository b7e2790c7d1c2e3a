"""A test double of the localizer contract (``fuzzypos.localization``: ``LocalizerState``,
``LocalizationEstimate``, ``Localizer(occupancy_map, config, *, initial_pose, initial_sigma)``
with ``update(scan, odom)``), for the localize job's tests: it is *searching* for its first
``searching`` scans, then *tracking*, answering each scan with the true pose of its stamp
(``TRUTH``, set by the test) and a known covariance, but *lost* for the scans of ``lost``
(0-based), or never localises (``searching=None``). Nothing here localises anything."""

from __future__ import annotations

import enum
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from fuzzypos.geometry import Pose2D

#: stamp → the true pose (x, y, θ) in the map frame; the test sets it
TRUTH: dict[float, tuple[float, float, float]] = {}


class LocalizerState(str, enum.Enum):
    SEARCHING = "searching"
    TRACKING = "tracking"
    LOST = "lost"


@dataclass(frozen=True)
class LocalizationEstimate:
    stamp: float
    state: LocalizerState
    pose: Pose2D | None
    covariance: Any
    step_covariance: Any
    confidence: float
    reason: str

    @property
    def localised(self) -> bool:
        return self.state is LocalizerState.TRACKING


def covariance_of(k: int) -> np.ndarray:
    """The known pose covariance the double gives for scan ``k`` (every entry distinct)."""
    return np.array([[4.0, 0.5, 0.1], [0.5, 3.0, -0.2], [0.1, -0.2, 0.7]]) * 1e-4 * (1 + k % 7)


def step_of(k: int) -> np.ndarray:
    return covariance_of(k) / 10.0


@dataclass(eq=False)
class FakeLocalizer:
    occupancy_map: Any
    config: Any = None
    initial_pose: Sequence[float] | None = None
    initial_sigma: tuple[float, float] | None = None
    searching: int | None = 5
    lost: range = range(0)
    #: scan (0-based) → an exception to raise there
    fail_at: dict[int, BaseException] = field(default_factory=dict)
    #: scans whose estimate claims tracking with no covariance
    broken_at: tuple[int, ...] = ()
    calls: list[tuple[float, Pose2D | None]] = field(default_factory=list)

    def update(self, scan: Any, odom: Pose2D | Sequence[float] | None = None) -> Any:
        k = len(self.calls)
        self.calls.append((scan.stamp, None if odom is None else Pose2D(*odom)))
        if k in self.fail_at:
            raise self.fail_at[k]
        if self.searching is None or k < self.searching:
            return self._not(scan.stamp, LocalizerState.SEARCHING, 0.1, "ambiguous")
        if k in self.lost:
            return self._not(scan.stamp, LocalizerState.LOST, 0.05, "the map no longer fits")
        pose = Pose2D(*TRUTH[scan.stamp])
        first = k == self.searching or (k - 1) in self.lost
        cov = None if k in self.broken_at else covariance_of(k)
        step = None if first else step_of(k)
        confidence = 0.5 + 0.5 * math.tanh(0.1 * (k - (self.searching or 0)))
        return LocalizationEstimate(
            scan.stamp, LocalizerState.TRACKING, pose, cov, step, confidence, "matched"
        )

    def _not(self, stamp: float, state: LocalizerState, conf: float, why: str) -> Any:
        return LocalizationEstimate(stamp, state, None, None, None, conf, why)


def factory(**settings: Any) -> Any:
    """A localizer factory as the job takes one: ``(occupancy_map, config, initial_pose=,
    initial_sigma=)`` → a :class:`FakeLocalizer` with ``settings``; ``factory.made`` holds
    those it made."""
    made: list[FakeLocalizer] = []

    def make(occupancy_map: Any, config: Any = None, **kw: Any) -> FakeLocalizer:
        loc = FakeLocalizer(occupancy_map, config, **kw, **settings)
        made.append(loc)
        return loc

    make.made = made  # type: ignore[attr-defined]
    return make


#: the CLI's localizer in its tests (``fuzzypos.jobs.localize._LOCALIZER`` pointed here):
#: searching for 5 scans, then tracking; ``SETTINGS`` changes that
SETTINGS: dict[str, Any] = {}


def Localizer(occupancy_map: Any, config: Any = None, **kw: Any) -> FakeLocalizer:
    return FakeLocalizer(occupancy_map, config, **kw, **SETTINGS)
