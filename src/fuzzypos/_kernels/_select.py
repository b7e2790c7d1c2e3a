"""Order statistics for the kernels without numba's sort (which is slow to compile): the k-th
smallest value (quickselect) and the median."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ._jit import kernel

FloatArray = NDArray[np.float64]


@kernel
def kth_smallest(values: FloatArray, k: int) -> float:
    """The ``k``-th smallest (0-based) of ``values`` (``np.sort(values)[k]``; no NaN)."""
    a = values.copy()
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
    """The median (the mean of the middle two of an even count), as ``_robust.median``."""
    n = values.shape[0]
    mid = n // 2
    if n % 2:
        return kth_smallest(values, mid)
    return 0.5 * (kth_smallest(values, mid - 1) + kth_smallest(values, mid))
