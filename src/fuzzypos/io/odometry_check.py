"""Whether a log's odometry covers its scans (issue 35): odometry that is missing at some scans,
or that stands still while the scans show the robot moving, must not freeze the estimate.

:class:`OdometryCoverage` takes a log's records in file order (:meth:`~OdometryCoverage.add`,
then :meth:`~OdometryCoverage.finish`) and finds the scans whose odometry does not cover them:

- ``missing``: scans without odometry in a log that has odometry at other scans: a CARMEN
  FLASER line whose odometry fields are not finite, a bag's scan outside the odometry's time
  span (the readers give them ``odometry=None``; the readers' notes say which);
- ``stuck``: scans inside a stretch of at least :data:`MIN_STUCK_SCANS` consecutive scans
  whose odometry pose is *exactly* the same (the wheels did not turn) while the scans show
  the robot moving: the median over the beams (valid in both scans) of the absolute range
  difference between the stretch's first scan and a later one exceeds both
  :data:`MOVED_M` and :data:`MOVED_RATIO` times the median of the same difference between
  consecutive scans of the stretch (what the scanner's noise and the world's own motion give
  a robot that stands still). A stretch whose odometry is all zeros while the robot drives
  (a log written without odometry), or odometry that starts late (a constant pose before its
  first message), is one such stretch.

The run positions the scans not covered without odometry (``odom=None``: from the scans,
with the positioner's broad prior), never frozen by odometry that says "standing still"
(:meth:`OdometryCoverage.records`); ``summary.json`` gets :meth:`~OdometryCoverage.as_dict`
as ``odometry_coverage`` and a note (:meth:`~OdometryCoverage.note`); ``fuzzypos info`` says
what it found instead of "odometry yes".
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..scan import LaserScan
from ._common import LogRecord

__all__ = ["MIN_STUCK_SCANS", "MOVED_M", "MOVED_RATIO", "OdometryCoverage"]

#: a stretch of exactly constant odometry is judged from this many scans on: shorter ones
#: (a robot pausing for a second at 10 Hz) cost little even where the odometry is wrong, and
#: their scans give too few differences to tell motion from noise
MIN_STUCK_SCANS = 10
#: the scans show motion when they differ from the stretch's first by more than 0.10 m
#: (median over the beams): several times the range noise of 2D lidars (1–3 cm), and a
#: median, so people walking through part of the view do not count
MOVED_M = 0.10
#: ... and by more than 5 times what consecutive scans of the stretch differ by (for a robot
#: standing still both are the scanner's noise, ratio about 1)
MOVED_RATIO = 5.0
#: how many indices of scans without odometry ``summary.json`` lists
_KEPT_INDICES = 100
#: beams valid in both scans needed to compare them
_MIN_COMMON_BEAMS = 5


def _difference(a: LaserScan, b: LaserScan) -> float | None:
    """The median absolute range difference over the beams valid in both (None: not
    comparable: other beam counts, or too few common beams)."""
    if a.n_beams != b.n_beams:
        return None
    both = a.valid & b.valid
    if int(np.count_nonzero(both)) < _MIN_COMMON_BEAMS:
        return None
    return float(np.median(np.abs(a.ranges[both] - b.ranges[both])))


@dataclass
class _Stretch:
    """Consecutive scans with exactly the same odometry pose."""

    first: int
    pose: tuple[float, float, float]
    reference: LaserScan
    previous: LaserScan
    length: int = 1
    steps: list[float] = field(default_factory=list)
    moved: float = 0.0

    def add(self, scan: LaserScan) -> None:
        step = _difference(self.previous, scan)
        if step is not None:
            self.steps.append(step)
        far = _difference(self.reference, scan)
        if far is not None:
            self.moved = max(self.moved, far)
        self.previous = scan
        self.length += 1

    def stuck(self) -> bool:
        if self.length < MIN_STUCK_SCANS or not self.steps:
            return False
        noise = float(np.median(self.steps))
        return self.moved > max(MOVED_M, MOVED_RATIO * noise)


@dataclass
class OdometryCoverage:
    """The scans a log's odometry does not cover (module docstring); add every record in
    file order, then :meth:`finish`."""

    #: whether the log has odometry (a bag without an odometry topic has none, and then no
    #: scan misses it); a scan without odometry in a log that has some is not covered
    expected: bool = True
    scans: int = 0
    with_odometry: int = 0
    #: ``(first, last)`` 0-based scan indices (file order) of the stuck stretches
    stuck: list[tuple[int, int]] = field(default_factory=list)
    #: the 0-based indices of the first :data:`_KEPT_INDICES` scans without odometry
    without: list[int] = field(default_factory=list)
    _open: _Stretch | None = field(default=None, repr=False)

    def add(self, rec: LogRecord) -> None:
        k = self.scans
        self.scans += 1
        odom = rec.odometry
        if odom is None:
            if self.expected and len(self.without) < _KEPT_INDICES:
                self.without.append(k)
            self._close()
            return
        self.with_odometry += 1
        pose = (odom.x, odom.y, odom.theta)
        s = self._open
        if s is not None and s.pose == pose:
            s.add(rec.scan)
            return
        self._close()
        self._open = _Stretch(k, pose, rec.scan, rec.scan)

    def _close(self) -> None:
        s = self._open
        if s is not None and s.stuck():
            self.stuck.append((s.first, s.first + s.length - 1))
        self._open = None

    def finish(self) -> OdometryCoverage:
        self._close()
        return self

    @property
    def missing(self) -> int:
        """Scans without odometry in a log that has odometry (0 in a log without any:
        :attr:`expected`)."""
        return self.scans - self.with_odometry if self.expected else 0

    @property
    def stuck_scans(self) -> int:
        return sum(last - first + 1 for first, last in self.stuck)

    @property
    def uncovered(self) -> int:
        """Scans whose odometry does not cover them (missing or stuck)."""
        return self.missing + self.stuck_scans

    @property
    def covered(self) -> int:
        """Scans with odometry that covers them."""
        return self.with_odometry - self.stuck_scans

    def records(self, records: Iterator[LogRecord]) -> Iterator[LogRecord]:
        """``records`` (the same log, from its start) with the stuck scans' odometry dropped."""
        stuck = iter(self.stuck)
        span = next(stuck, None)
        for k, rec in enumerate(records):
            while span is not None and k > span[1]:
                span = next(stuck, None)
            if span is not None and span[0] <= k <= span[1] and rec.odometry is not None:
                rec = rec._replace(odometry=None)
            yield rec

    def note(self) -> str | None:
        """One sentence on the scans not covered (None when every scan is)."""
        if not self.uncovered:
            return None
        parts = []
        if self.missing:
            parts.append(f"{self.missing:,} have no odometry")
        if self.stuck:
            first, last = self.stuck[0]
            parts.append(
                f"{self.stuck_scans:,} lie in {len(self.stuck)} stretch(es) where the odometry "
                f"stands exactly still while the scans show the robot moving (the first: scans "
                f"{first:,} to {last:,}, counting from 0)"
            )
        return (
            f"odometry coverage: {self.uncovered:,} of {self.scans:,} scans are not covered by "
            f"the odometry ({'; '.join(parts)}): they are positioned from the scans alone, "
            "without an odometry prior"
        )

    def as_dict(self) -> dict[str, Any]:
        """``summary.json``'s ``odometry_coverage``."""
        return {
            "scans": self.scans,
            "scans_not_covered": self.uncovered,
            "scans_without_odometry": self.missing,
            "without_odometry_first": list(self.without),
            "scans_with_stuck_odometry": self.stuck_scans,
            "stuck_stretches": [list(s) for s in self.stuck],
            "thresholds": {
                "min_stuck_scans": MIN_STUCK_SCANS,
                "moved_m": MOVED_M,
                "moved_ratio": MOVED_RATIO,
            },
        }
