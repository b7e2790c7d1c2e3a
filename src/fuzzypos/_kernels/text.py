"""The CARMEN writer's ranges as text (``fuzzypos.io.carmen_write._fixed_text``, whose numpy
reference builds the same bytes from digit tables): each value rounded to ``decimals``
places, written without trailing zeros (``f"{v:.4f}".rstrip("0").removesuffix(".")``),
space-separated, as ASCII bytes."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from ._jit import kernel

FloatArray = NDArray[np.float64]


@kernel
def fixed_text(
    values: FloatArray, scale: int, decimals: int, int_width: int
) -> tuple[bool, NDArray[np.uint8]]:
    """``(ok, text)``: the values as text, ``scale = 10**decimals``; not ok (and no text)
    where a value is within rounding error of a tie at the last decimal, not finite or has
    ``int_width`` or more integer digits (the caller's exact path takes it)."""
    n = values.shape[0]
    out = np.empty(n * (int_width + decimals + 3), dtype=np.uint8)
    limit = 10.0 ** (int_width + decimals) - 1.0
    fscale = float(scale)
    digits = np.empty(int_width + decimals, dtype=np.uint8)
    pos = 0
    for i in range(n):
        v = values[i]
        m = abs(v * fscale)
        if not m < limit:
            return False, out[:0]
        if abs(m - math.floor(m) - 0.5) <= m * 1e-15:
            return False, out[:0]
        k = math.floor(m + 0.5)  # not a tie: the rounding of np.rint
        q, f = k // scale, k % scale
        if i > 0:
            out[pos] = 32  # " "
            pos += 1
        if math.copysign(1.0, v) < 0.0:
            out[pos] = 45  # "-"
            pos += 1
        nd = 0
        while True:  # the integer part, at least "0"
            digits[nd] = 48 + q % 10
            nd += 1
            q //= 10
            if q == 0:
                break
        for j in range(nd - 1, -1, -1):
            out[pos] = digits[j]
            pos += 1
        if f != 0:
            width = decimals
            while f % 10 == 0:  # no trailing zeros
                f //= 10
                width -= 1
            out[pos] = 46  # "."
            pos += 1
            for j in range(width - 1, -1, -1):
                out[pos + j] = 48 + f % 10
                f //= 10
            pos += width
    return True, out[:pos]
