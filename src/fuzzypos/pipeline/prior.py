"""The odometry prior stage: the motion a scan starts from, odometry jumps, standing still."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..config import OdometryConfig, OdometryNoiseConfig
from ..geometry import Pose2D, relative3
from ._window import Window

__all__ = ["OdometryPrior", "Prior"]

FloatArray = NDArray[np.float64]

#: the usual scan period is a quantile of this many last time steps
_STEPS = 51
#: and is known once this many have been seen (a quantile of fewer is one of the few; before
#: it, no time step counts as a gap)
_MIN_STEPS = 10


@dataclass(frozen=True, eq=False)
class Prior:
    """The prior for one scan's motion since the previous scan.

    ``increment``: the odometry increment ``⊖o_k ⊕ o_{k+1}`` (SPEC) where both scans have
    odometry and it is a robot's motion, else the last estimated increment (after a jump: at
    most as far as it went in its own time step). ``odometry``: the odometry increment, None
    without odometry. ``dt``: seconds since the previous scan (never negative).
    ``odometry_rejected``: the odometry increment was a jump. ``standing_still``: the odometry
    pose did not change at all (the wheels did not turn). ``stale``: seconds of ``dt`` beyond
    ``stale_periods`` usual scan periods (the running ``stale_quantile`` of the time steps):
    time the odometry was not updated (0 for a scan on time).
    """

    increment: FloatArray
    odometry: FloatArray | None
    dt: float
    odometry_rejected: bool
    standing_still: bool
    stale: float = 0.0

    @classmethod
    def _of(
        cls,
        increment: FloatArray,
        odometry: FloatArray | None,
        dt: float,
        odometry_rejected: bool,
        standing_still: bool,
        stale: float,
    ) -> Prior:
        """What the constructor builds, straight into the instance's dict (the frozen
        ``__init__``'s ``object.__setattr__`` per field costs more; once or twice a scan)."""
        out = object.__new__(cls)
        out.__dict__.update(
            increment=increment, odometry=odometry, dt=dt, odometry_rejected=odometry_rejected,
            standing_still=standing_still, stale=stale,
        )  # fmt: skip
        return out

    @property
    def from_odometry(self) -> bool:
        """Whether the increment is the odometry's (not a jump, not the last increment)."""
        return self.odometry is not None and not self.odometry_rejected


class OdometryPrior:
    """Turns the odometry poses into the prior of each scan's motion (``[odometry]``)."""

    def __init__(
        self, settings: OdometryConfig, stale_periods: float, stale_quantile: float
    ) -> None:
        self.settings = settings
        self.stale_periods = stale_periods
        self.stale_quantile = stale_quantile
        self.reset()

    @classmethod
    def of_sections(cls, odometry: OdometryConfig, noise: OdometryNoiseConfig) -> OdometryPrior:
        """The prior of the ``[odometry]`` section, its time steps stale past
        ``[odometry_noise]``'s ``stale_periods`` usual ones (their ``stale_quantile``)."""
        return cls(odometry, noise.stale_periods, noise.stale_quantile)

    def reset(self) -> None:
        self._prev_odom: Pose2D | None = None
        self._prev_stamp = 0.0
        self._last_increment: FloatArray = np.zeros(3)
        self._last_dt = 0.0
        self._steps = Window(_STEPS)
        #: odometry increments rejected as jumps so far
        self.jumps = 0

    def start(self, stamp: float, odom: Pose2D | None) -> None:
        """The first scan: nothing to predict yet."""
        self._prev_odom = odom
        self._prev_stamp = stamp

    def predict(self, stamp: float, odom: Pose2D | None) -> Prior:
        """The prior for the scan at ``stamp`` whose odometry pose is ``odom`` (or None)."""
        rejected = False
        odo_inc = None
        dt = max(0.0, stamp - self._prev_stamp)
        prev_odom = self._prev_odom
        standing = False
        if odom is not None and prev_odom is not None:
            # the increment in floats from the poses' own (what relative() of their arrays
            # computes, without the arrays)
            before = (prev_odom.x, prev_odom.y, prev_odom.theta)
            inc = relative3(before, (odom.x, odom.y, odom.theta))
            odo_inc = np.array(inc)
            rejected = self._is_jump(inc[0], inc[1], inc[2], dt)
            # the very same pose: the wheels did not turn (Pose2D's ==, field by field)
            standing = self.settings.trust_stand_still and (
                odom.x == prev_odom.x and odom.y == prev_odom.y and odom.theta == prev_odom.theta
            )
        self._prev_stamp = stamp
        if odo_inc is not None and not rejected:
            prior = odo_inc
        elif rejected:  # the last motion, at most as far as it went in its own time step
            ratio = min(1.0, dt / self._last_dt) if self._last_dt > 0 else 1.0
            prior = self._last_increment * ratio
        else:
            prior = self._last_increment
        if rejected:
            self.jumps += 1
        self._prev_odom = odom
        stale = 0.0
        if len(self._steps) >= _MIN_STEPS:
            usual = self._steps.quantile(self.stale_quantile)
            stale = max(0.0, dt - self.stale_periods * usual)
        if dt > 0.0:
            self._steps.append(dt)
        return Prior._of(prior, odo_inc, dt, rejected, standing, stale)

    def accept(self, increment: FloatArray, dt: float) -> None:
        """The increment estimated for the scan ``dt`` after the previous one: the prior of a
        scan without (sane) odometry."""
        self._last_increment = increment
        self._last_dt = dt

    def is_jump(self, increment: FloatArray, dt: float) -> bool:
        """An odometry increment no robot makes: faster than ``max_speed`` / ``max_turn_rate``
        over ``dt`` plus the allowances (stamps of real logs are not acquisition times)."""
        return self._is_jump(float(increment[0]), float(increment[1]), float(increment[2]), dt)

    def _is_jump(self, x: float, y: float, theta: float, dt: float) -> bool:
        """:meth:`is_jump` of the increment ``(x, y, theta)``."""
        o = self.settings
        dist = math.hypot(x, y)
        return (
            dist > o.max_speed * dt + o.max_jump_distance
            or abs(theta) > o.max_turn_rate * dt + o.max_jump_angle
        )
