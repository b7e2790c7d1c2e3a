"""The numpy references of ``fuzzypos.io``'s kernels (``_kernels.text``): the code each
replaced, the tests' oracles."""

from __future__ import annotations

import functools
import sys

import numpy as np
from numpy.typing import NDArray

from fuzzypos.io import carmen, carmen_write
from fuzzypos.io.carmen_write import _INT_WIDTH, _SCALE, RANGE_DECIMALS

FloatArray = NDArray[np.float64]


@functools.cache
def _tables() -> tuple[NDArray[np.uint8], NDArray[np.bool_], NDArray[np.uint8], NDArray[np.bool_]]:
    """The text of every integer part below ``10**_INT_WIDTH`` and of every ``.dddd``
    decimal part, as fixed-width characters with the mask of the ones written (no leading
    zeros, no trailing zeros, no ``.`` for a whole number)."""
    digits = np.frombuffer(b"0123456789", dtype=np.uint8)
    q = np.arange(10**_INT_WIDTH, dtype=np.int64)[:, None]
    p = 10 ** np.arange(_INT_WIDTH - 1, -1, -1, dtype=np.int64)
    int_chars = digits[(q // p) % 10]
    int_keep = q >= p
    int_keep[:, -1] = True  # "0"
    f = np.arange(_SCALE, dtype=np.int64)[:, None]
    p = 10 ** np.arange(RANGE_DECIMALS - 1, -1, -1, dtype=np.int64)
    frac_chars = np.hstack((np.full((_SCALE, 1), ord("."), dtype=np.uint8), digits[(f // p) % 10]))
    frac_keep = np.hstack((f != 0, f % (10 * p) != 0))
    return int_chars, int_keep, frac_chars, frac_keep


def fixed_text(values: FloatArray) -> str | None:
    """The finite ``values`` as ``f"{v:.4f}".rstrip("0").removesuffix(".")`` each (to
    ``RANGE_DECIMALS``), space-separated, built as one byte matrix from tables instead of one
    string per value; None where that cannot be sure of the same text (a value within
    rounding error of a tie at the last decimal, or of ``10**_INT_WIDTH`` or more), for the
    caller's exact per-value path."""
    n = len(values)
    if n == 0:
        return ""
    with np.errstate(over="ignore", invalid="ignore"):  # inf and NaN take the exact path
        mag = np.abs(values * float(_SCALE))
    if not float(mag.max()) < 10.0 ** (_INT_WIDTH + RANGE_DECIMALS) - 1.0:
        return None
    tie = np.abs(mag - np.floor(mag) - 0.5)
    if (tie <= mag * 1e-15).any():  # too near a tie: the product's rounding may decide it
        return None
    k = np.rint(mag).astype(np.int64)  # the correctly rounded count of the last decimal
    q, f = np.divmod(k, _SCALE)
    int_chars, int_keep, frac_chars, frac_keep = _tables()
    width = 1 + _INT_WIDTH + 1 + RANGE_DECIMALS + 1
    chars = np.empty((n, width), dtype=np.uint8)
    keep = np.empty((n, width), dtype=bool)
    chars[:, 0] = ord("-")
    keep[:, 0] = np.signbit(values)
    chars[:, 1 : 1 + _INT_WIDTH] = int_chars[q]
    keep[:, 1 : 1 + _INT_WIDTH] = int_keep[q]
    chars[:, 1 + _INT_WIDTH : -1] = frac_chars[f]
    keep[:, 1 + _INT_WIDTH : -1] = frac_keep[f]
    chars[:, -1] = ord(" ")
    keep[:, -1] = True
    keep[-1, -1] = False  # no space after the last value
    return chars[keep].tobytes().decode("ascii")


#: (module, attribute, its reference) for :func:`oracles.references`: the writer's text in
#: numpy, and the reader's numbers all parsed by numpy (no list long enough for the kernel)
STAND_INS = [
    (carmen_write.__name__, "_fixed_text", fixed_text),
    (carmen.__name__, "_PARSED_FROM", sys.maxsize),
]
