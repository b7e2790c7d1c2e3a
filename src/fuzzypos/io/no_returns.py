""" "No return" codes found in a log's own readings (``[scanner] find_no_return_values``).

Some scanners report "nothing there" as a fixed reading below the maximum range a log gives
or fuzzypos infers (SICK in cm mode: 81.83 m; held-back logs: 50.0 m and 51.14 m below an
inferred 51.16 m), so the readings look valid and would become walls. :class:`RangeTally`
counts a log's readings per value in one pass (to 0.1 mm, the precision CARMEN ranges are
written at; a float32 bag's code repeats bit for bit), and :meth:`RangeTally.find` declares a
value a no-return code where

a. it is repeated in many readings: at least ``find_min_readings``, or in a shorter log at least
   ``find_min_fraction`` of them, but never fewer than ``find_floor_readings``;
b. it lies at the top of what the scanner reports: at most ``find_top_fraction`` of the log's
   other readings (those of codes already found left aside) lie above it;
c. it is a spike, not part of a continuum of ranges: it holds at least ``find_spike_ratio``
   times as many readings as all the other values within ``±find_window`` of it together (codes
   already found left aside);
d. it is seen while the robot moves: the share of its readings taken in scans whose odometry
   differs from the previous scan's is at least ``find_moving_share`` times that share over
   the whole log (a scan without odometry counts as moving). A wall seen while standing still
   repeats one value many times, but at one pose only.

(b) and (c) are judged with the codes already found left aside, over and over until no value
is added, so two codes a few centimetres apart (51.14 m beside 51.16 m) do not hide each other.
Each code found that a configured band does not hold, and whose readings ``range_max`` has
not all made invalid already, becomes a band of one tally step (``value ± 0.05 mm``,
:attr:`FoundNoReturn.band`) added to the configured ``no_return_bands`` for the run
(:func:`with_found_bands`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..config import Config, ScannerConfig
from ..scan import LaserScan, no_return_mask

__all__ = ["TALLY_STEP", "FoundNoReturn", "RangeTally", "with_found_bands"]

#: readings equal to this step (m) count as the same value: 0.1 mm, the precision of the
#: ranges fuzzypos writes to CARMEN logs (and finer than any scanner's)
TALLY_STEP = 1e-4
#: readings above this (m) are not tallied (no scanner reaches it; keeps the keys in int64)
_LARGEST = 1e9
#: buffered readings before the tally merges them
_CHUNK = 1 << 18

IntArray = NDArray[np.int64]


@dataclass(frozen=True)
class FoundNoReturn:
    """A value found to be a "no return" code: ``value_m`` (m, to :data:`TALLY_STEP`),
    ``readings`` with it in the log, ``invalid_at_range_max`` of them already invalid (at or
    above their scan's ``range_max``), and whether a configured band already holds it."""

    value_m: float
    readings: int
    invalid_at_range_max: int = 0
    in_configured_band: bool = False

    @property
    def band(self) -> tuple[float, float]:
        """The readings the tally counted as this value: ``value ± TALLY_STEP / 2`` (m)."""
        half = TALLY_STEP / 2.0
        return (round(self.value_m - half, 6), round(self.value_m + half, 6))

    def as_dict(self) -> dict[str, object]:
        return dataclasses.asdict(self)


class RangeTally:
    """How many of a log's readings (finite, ``> 0``) have each value, to :data:`TALLY_STEP`:
    all of them, those of scans taken after the robot moved, and those already invalid at
    their scan's ``range_max``. :meth:`add` one scan at a time (file order), then
    :meth:`find`."""

    def __init__(self) -> None:
        self.keys: IntArray = np.zeros(0, dtype=np.int64)
        self.total: IntArray = np.zeros(0, dtype=np.int64)
        self.moving: IntArray = np.zeros(0, dtype=np.int64)
        self.invalid: IntArray = np.zeros(0, dtype=np.int64)
        self._buf: list[tuple[IntArray, bool, NDArray[np.bool_]]] = []
        self._buffered = 0
        self._prev_odometry: object = None

    def add(self, scan: LaserScan, odometry: object = None) -> None:
        """Count one scan's readings. ``odometry`` (any value comparable with ``==``, e.g. a
        :class:`~fuzzypos.geometry.Pose2D`; None when the log has none): the scan counts as
        taken while moving unless it equals the previous scan's."""
        moved = odometry is None or self._prev_odometry is None or odometry != self._prev_odometry
        self._prev_odometry = odometry
        r = scan.ranges
        ok = np.isfinite(r) & (r > 0.0) & (r < _LARGEST)
        keys = np.rint(r[ok] / TALLY_STEP).astype(np.int64)
        self._buf.append((keys, bool(moved), r[ok] >= scan.range_max))
        self._buffered += keys.size
        if self._buffered >= _CHUNK:
            self._merge()

    def _merge(self) -> None:
        if not self._buf:
            return
        keys = np.concatenate([self.keys, *(k for k, _, _ in self._buf)])
        ones = [np.ones(k.size, dtype=np.int64) for k, _, _ in self._buf]
        moving = [np.full(k.size, int(m), dtype=np.int64) for k, m, _ in self._buf]
        invalid = [inv.astype(np.int64) for _, _, inv in self._buf]
        self._buf, self._buffered = [], 0
        self.keys, where = np.unique(keys, return_inverse=True)
        n = self.keys.size
        self.total = np.bincount(where, np.concatenate([self.total, *ones]), n).astype(np.int64)
        self.moving = np.bincount(where, np.concatenate([self.moving, *moving]), n).astype(np.int64)
        self.invalid = np.bincount(where, np.concatenate([self.invalid, *invalid]), n).astype(
            np.int64
        )

    @property
    def readings(self) -> int:
        self._merge()
        return int(self.total.sum())

    def find(self, scanner: ScannerConfig) -> list[FoundNoReturn]:
        """The values (a)-(d) of the module docstring make "no return" codes, from the top
        down; ``in_configured_band`` against ``scanner.no_return_bands``."""
        self._merge()
        total = self.total
        n = int(total.sum())
        if n == 0:
            return []
        need = max(
            scanner.find_floor_readings,
            min(scanner.find_min_readings, math.ceil(scanner.find_min_fraction * n)),
        )
        moving_share = float(self.moving.sum()) / n
        cand = np.flatnonzero(
            (total >= need) & (self.moving >= scanner.find_moving_share * moving_share * total)
        )
        found = self._peel(cand, scanner)
        out = []
        for i in sorted(found, key=lambda i: -self.keys[i]):
            value = round(float(self.keys[i]) * TALLY_STEP, 4)
            configured = bool(no_return_mask([value], scanner.no_return_bands)[0])
            out.append(FoundNoReturn(value, int(total[i]), int(self.invalid[i]), configured))
        return out

    def _peel(self, cand: IntArray, scanner: ScannerConfig) -> list[int]:
        """The candidates that pass (b) and (c) with the codes found so far left aside, found
        again until nothing changes (leaving a code aside only helps the others pass)."""
        keys, total = self.keys, self.total
        n = int(total.sum())
        below_or_at = np.cumsum(total)
        window = round(scanner.find_window / TALLY_STEP)
        lo = np.searchsorted(keys, keys[cand] - window, side="left")
        hi = np.searchsorted(keys, keys[cand] + window, side="right")
        cum0 = np.concatenate([[0], below_or_at])
        near = cum0[hi] - cum0[lo] - total[cand]  # the others within the window
        above = n - below_or_at[cand]  # the readings above each candidate
        found: list[int] = []
        while True:
            f = np.array(found, dtype=np.intp)
            fk, ft = keys[f], total[f]
            # the found codes' readings above each candidate and within its window
            above_f = (ft[None, :] * (fk[None, :] > keys[cand][:, None])).sum(axis=1)
            near_f = (ft[None, :] * (np.abs(fk[None, :] - keys[cand][:, None]) <= window)).sum(
                axis=1
            ) - np.where(np.isin(cand, f), total[cand], 0)
            others = n - int(ft.sum()) - np.where(np.isin(cand, f), 0, total[cand])
            top = (above - above_f) <= scanner.find_top_fraction * others
            spike = total[cand] >= scanner.find_spike_ratio * (near - near_f)
            now = [int(i) for i in cand[top & spike]]
            if set(now) <= set(found):
                return found
            found = sorted(set(found) | set(now))


def with_found_bands(config: Config, found: Sequence[FoundNoReturn]) -> Config:
    """``config`` with the bands of the codes ``found`` that would drop a reading added to
    ``scanner.no_return_bands`` (the configured ones first, unchanged): those no configured
    band holds and not all of whose readings ``range_max`` already made invalid (a scanner
    that reads "no return" as its maximum, as ROS asks, needs no band). ``config`` itself when
    there are none."""
    extra = tuple(
        f.band for f in found if not f.in_configured_band and f.readings > f.invalid_at_range_max
    )
    if not extra:
        return config
    scanner = dataclasses.replace(
        config.scanner, no_return_bands=tuple(config.scanner.no_return_bands) + extra
    )
    return dataclasses.replace(config, scanner=scanner)
