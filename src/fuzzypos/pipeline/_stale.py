"""How fast an odometry increment's error grows with the time it was stale, learned from the
matches after gaps.

After a gap in time (``Prior.stale`` seconds beyond the usual scan periods) the odometry's
covariance grows by ``(speed · stale)²`` in translation and ``(turn_rate · stale)²`` in
rotation (:meth:`~.noise.OdometryNoise.covariance`). Whether it should depends on the log:
where the odometry pose rides with each scan (a CARMEN log's FLASER line) a gap in the laser's
records is no gap in the odometry, whose increment over it is as good as any other of that
length; where the odometry stops while the robot moves on (a stalled odometry topic) the
increment misses what happened in the gap. The configured rates (``stale_speed``,
``stale_turn_rate``) assume the worse case until ``stale_min_samples`` matches after gaps have
been seen; from then on each rate is the robust fit to the last ``window`` of them: the r ≥ 0 at
which the median of ``e² / (v + r² τ²)`` over the samples is χ²(1)'s median, for a sample's
disagreement e of the scan's own motion with the odometry, the variance v it has on time
(the odometry's on-time noise plus the match's own), and its stale time τ. The median is
non-increasing in r, so bisection finds it; a rate whose median at r = 0 lies below χ²(1)'s
median is 0 (the gaps' disagreements are the on-time noise), one above it at the bound is the
bound (``odometry.max_speed``, ``odometry.max_turn_rate``: no robot moves faster).
"""

from __future__ import annotations

import math
from collections import deque

__all__ = ["StaleRates", "fit_stale_rate"]

#: the median of χ² with one degree of freedom
_MEDIAN_CHI2_1 = 0.454936423119572
#: bisection steps: the bound over 2⁴⁰, far below any rate that matters
_STEPS = 40


def _median(values: list[float]) -> float:
    a = sorted(values)
    n = len(a)
    return a[n // 2] if n % 2 else 0.5 * (a[n // 2 - 1] + a[n // 2])


def fit_stale_rate(samples: list[tuple[float, float, float]], bound: float) -> float:
    """The rate r in [0, ``bound``] at which the median of ``e² / (v + r² τ²)`` over
    ``samples`` of ``(e², v, τ²)`` (one degree of freedom each) is χ²(1)'s median (module
    docstring)."""

    def median_at(r: float) -> float:
        r2 = r * r
        return _median([e2 / (v + r2 * t2) for e2, v, t2 in samples])

    if median_at(0.0) <= _MEDIAN_CHI2_1:
        return 0.0
    if median_at(bound) >= _MEDIAN_CHI2_1:
        return bound
    lo, hi = 0.0, bound
    for _ in range(_STEPS):
        mid = 0.5 * (lo + hi)
        if median_at(mid) > _MEDIAN_CHI2_1:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


class StaleRates:
    """The stale odometry's translation ``speed`` (m/s) and ``turn_rate`` (rad/s): the
    configured ones until ``min_samples`` matches after gaps, then learned (module
    docstring)."""

    def __init__(
        self,
        speed: float,
        turn_rate: float,
        max_speed: float,
        max_turn_rate: float,
        window: int,
        min_samples: int,
    ) -> None:
        self._configured = (speed, turn_rate)
        self._bounds = (max_speed, max_turn_rate)
        self._window = window
        self.min_samples = min_samples
        self.reset()

    def reset(self) -> None:
        self.speed, self.turn_rate = self._configured
        # per sample: x and y as two one-dimensional samples, and θ
        self._translation: deque[tuple[float, float, float]] = deque(maxlen=2 * self._window)
        self._rotation: deque[tuple[float, float, float]] = deque(maxlen=self._window)

    @property
    def samples(self) -> int:
        """How many matches after gaps have been learned from (within the window)."""
        return len(self._rotation)

    def learn(
        self,
        disagreement: tuple[float, float, float],
        on_time_variance: tuple[float, float, float],
        stale: float,
    ) -> None:
        """A match after a gap of ``stale`` seconds: its disagreement with the odometry
        (x, y, θ) and the variance that disagreement has on time (the odometry's noise over
        the increment plus the match's own), per component."""
        values = (*disagreement, *on_time_variance)
        if not (stale > 0.0 and all(math.isfinite(v) for v in values)):
            return
        if min(on_time_variance) <= 0.0:  # (the odometry's floors keep it positive)
            return
        t2 = stale * stale
        ex, ey, et = disagreement
        vx, vy, vt = on_time_variance
        self._translation.append((ex * ex, vx, t2))
        self._translation.append((ey * ey, vy, t2))
        self._rotation.append((et * et, vt, t2))
        if len(self._rotation) >= self.min_samples:
            self.speed = fit_stale_rate(list(self._translation), self._bounds[0])
            self.turn_rate = fit_stale_rate(list(self._rotation), self._bounds[1])
