"""Order statistics for the kernels without numba's sort (which is slow to compile): the k-th
smallest value (quickselect) and the median."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from ._jit import kernel

FloatArray = NDArray[np.float64]


@kernel
def kth_smallest(values: FloatArray, k: int) -> float:
    """The ``k``-th smallest (0-based) of ``values`` (``np.sort(values)[k]``; no NaN)."""
    return _select(values.copy(), k)


@kernel
def _select(a: FloatArray, k: int) -> float:
    """:func:`kth_smallest` on ``a`` itself (Hoare's quickselect, left partitioned: every
    value before ``a[k]`` is at most it)."""
    lo, hi = 0, a.shape[0] - 1
    while lo < hi:
        pivot = a[(lo + hi) // 2]
        i, j = lo, hi
        while i <= j:
            while a[i] < pivot:
                i += 1
            while a[j] > pivot:
                j -= 1
            if i <= j:
                a[i], a[j] = a[j], a[i]
                i += 1
                j -= 1
        if k <= j:
            hi = j
        elif k >= i:
            lo = i
        else:
            break
    return float(a[k])


@kernel
def median(values: FloatArray) -> float:
    """The median (the mean of the middle two of an even count), as ``_robust.median``: one
    selection, the lower middle value the largest of those it left before the upper."""
    n = values.shape[0]
    if n == 0:
        return math.nan  # (np.median's)
    mid = n // 2
    a = values.copy()
    upper = _select(a, mid)
    if n % 2:
        return upper
    lower = float(a[0])
    for i in range(1, mid):
        if a[i] > lower:
            lower = a[i]
    return 0.5 * (lower + upper)


@kernel
def kth_smallest_in(values: FloatArray, k: int, scratch: FloatArray) -> float:
    """:func:`kth_smallest` with ``scratch`` (at least as long as ``values``) for the copy, by
    quickselect with branch-free partitions (Lomuto's, about the median of three): about a
    quarter of the time of :func:`kth_smallest`'s on a few hundred values, though as slow as
    a sort where most of them are equal."""
    n = values.shape[0]
    a = scratch
    for i in range(n):
        a[i] = values[i]
    lo, hi = 0, n - 1
    while lo < hi:
        mid = (lo + hi) // 2
        x, y, z = a[lo], a[mid], a[hi]
        p = mid if (x <= y) == (y <= z) else (lo if (y <= x) == (x <= z) else hi)
        pivot = a[p]
        a[p] = a[hi]
        store = lo
        for i in range(lo, hi):  # a[lo:store] < pivot ≤ a[store:i], whichever way x goes
            x = a[i]
            a[i] = a[store]
            a[store] = x
            store += x < pivot
        a[hi] = a[store]
        a[store] = pivot
        if k < store:
            hi = store - 1
        elif k > store:
            lo = store + 1
        else:
            return float(pivot)
    return float(a[k])
