"""A running window of the last values and its median, kept sorted as values come and go
(one insertion and one removal per value, instead of a sort of the window per median)."""

from __future__ import annotations

import bisect
import math
from collections import deque
from collections.abc import Iterator

import numpy as np

__all__ = ["Window", "median_of", "quantile_of"]


def median_of(values: deque[float] | list[float]) -> float:
    """``np.median`` of the values (the reference of :meth:`Window.median`; NaN sorts last)."""
    a = np.sort(np.fromiter(values, dtype=float, count=len(values)))
    n = len(a)
    return float(a[n // 2]) if n % 2 else float(0.5 * (a[n // 2 - 1] + a[n // 2]))


def quantile_of(values: deque[float] | list[float], q: float) -> float:
    """``np.quantile(values, q, method="higher")`` (the reference of :meth:`Window.quantile`)."""
    a = np.fromiter(values, dtype=float, count=len(values))
    return float(np.quantile(a, q, method="higher"))


class Window:
    """The last ``maxlen`` values appended (like ``deque(maxlen=...)``) and their median, as
    :func:`median_of` gives it."""

    def __init__(self, maxlen: int) -> None:
        self._values: deque[float] = deque(maxlen=maxlen)
        self._sorted: list[float] = []
        self._nans = 0
        self._median: float | None = None

    def __len__(self) -> int:
        return len(self._values)

    def __iter__(self) -> Iterator[float]:
        return iter(self._values)

    def append(self, value: float) -> None:
        value = float(value)
        values, ordered = self._values, self._sorted
        # (x != x: NaN, without math.isnan's lookups; four appends a scan)
        if len(values) == values.maxlen:
            old = values[0]
            if old != old:
                self._nans -= 1
            else:
                del ordered[bisect.bisect_left(ordered, old)]
        values.append(value)
        if value != value:
            self._nans += 1
        else:
            bisect.insort(ordered, value)
        self._median = None

    def median(self) -> float:
        """The median of the (non-empty) window, as :func:`median_of` gives it."""
        if self._median is None:
            if self._nans:
                self._median = median_of(self._values)
            else:
                a, n = self._sorted, len(self._sorted)
                self._median = a[n // 2] if n % 2 else 0.5 * (a[n // 2 - 1] + a[n // 2])
        return self._median

    def quantile(self, q: float) -> float:
        """The ``q``-quantile of the (non-empty) window, the higher of the two values it lies
        between (as :func:`quantile_of` gives it; q in [0, 1])."""
        if self._nans:
            return quantile_of(self._values, q)
        a = self._sorted
        return a[math.ceil(q * (len(a) - 1))]
