"""Small robust statistics shared by the matchers: the median, the MAD outlier rule, the index
pairs of every two items."""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]

#: the median absolute deviation times this is the standard deviation of normal noise
MAD_TO_SIGMA = 1.4826
#: the outlier rule: further than this many robust standard deviations from the median
OUTLIER_SIGMAS = 3.0


@lru_cache(maxsize=256)
def index_pairs(m: int) -> tuple[IntArray, IntArray]:
    """All ``(i, j)`` with ``i < j < m`` (np.triu_indices, cached: it is slow to build)."""
    i, j = np.triu_indices(m, 1)
    i.flags.writeable = False
    j.flags.writeable = False
    return i.astype(np.int64, copy=False), j.astype(np.int64, copy=False)


def median(values: FloatArray) -> float:
    """The median of a short 1-D array (np.median's generality costs more than the sort)."""
    v = np.sort(values)
    mid = v.shape[0] // 2
    return float(v[mid]) if v.shape[0] % 2 else 0.5 * float(v[mid - 1] + v[mid])


def outlier_cut(deviations: FloatArray, floor: float) -> float:
    """The outlier rule's cut for absolute ``deviations``: 3 robust standard deviations
    (1.4826 × their median), never tighter than ``floor``."""
    return max(OUTLIER_SIGMAS * MAD_TO_SIGMA * median(deviations), floor)
