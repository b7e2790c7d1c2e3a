"""What the simulator's modules share, below :mod:`.world` and :mod:`.worldfile`: the error,
the float arrays and a polygon's edges as segments."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..errors import FuzzyposError

FloatArray = NDArray[np.float64]

__all__ = ["FloatArray", "SimError"]


class SimError(FuzzyposError, ValueError):
    """Invalid simulator input: a malformed world, scanner model or ray query."""

    __module__ = "fuzzypos.sim"  # where it is imported from (and pickled as)


def _polygon_segments(v: FloatArray, closed: bool) -> FloatArray:
    end = np.roll(v, -1, axis=0) if closed else v[1:]
    start = v if closed else v[:-1]
    return np.hstack([start, end])
