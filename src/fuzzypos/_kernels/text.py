"""The CARMEN logs' numbers as text, both ways. The writer's ranges
(``fuzzypos.io.carmen_write._fixed_text``, whose numpy reference, ``fixed_text`` of
``tests/oracles/io.py``, builds the same bytes from digit tables): each value rounded to
``decimals`` places, written without trailing zeros (``f"{v:.4f}".rstrip("0").removesuffix(".")``),
space-separated, as ASCII bytes. And the
reader's (``fuzzypos.io.carmen._numbers``, whose reference is ``np.array(tokens,
dtype=float)``): space-separated plain decimals parsed in one loop, each the correctly
rounded double ``float()`` gives, by the exact fast path of Clinger (1990): a decimal
``m · 10^e`` with an integer ``m < 2^53`` and ``|e| <= 22`` is one IEEE multiplication or
division of two exact doubles, so rounded once, correctly. Anything else (more digits, a
larger exponent, ``inf``, ``nan``, underscores, any other character) is left to the
reference."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from ._jit import kernel

FloatArray = NDArray[np.float64]

#: 10**0 … 10**22: every power of ten a double holds exactly
_POWERS = np.array([10.0**k for k in range(23)])
_EXACT = 2**53  # integers below this are exact doubles


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


@kernel
def parse_decimals(text: NDArray[np.uint8], count: int) -> tuple[bool, FloatArray]:
    """``(ok, values)``: the ``count`` numbers of ``text`` (ASCII, separated by single spaces,
    nothing before the first or after the last), each ``[+-]digits[.digits][(e|E)[+-]digits]``
    with at least one digit before the exponent, as the doubles ``float()`` makes of them;
    not ok (and no values) where a number is not of that form or is beyond the exact fast
    path (module docstring), or there are not ``count`` of them: the caller's reference
    parses those."""
    out = np.empty(count)
    none = out[:0]
    n = text.shape[0]
    pos = 0
    for i in range(count):
        if pos >= n:
            return False, none
        negative = False
        c = text[pos]
        if c == 45 or c == 43:  # "-" or "+"
            negative = c == 45
            pos += 1
        m, digits, after_point, point = 0, 0, 0, False
        while pos < n:
            c = text[pos]
            if 48 <= c <= 57:
                m = m * 10 + (c - 48)
                if m >= _EXACT:
                    return False, none
                digits += 1
                if point:
                    after_point += 1
            elif c == 46 and not point:  # "."
                point = True
            else:
                break
            pos += 1
        if digits == 0:
            return False, none
        exponent = 0
        if pos < n and (text[pos] == 101 or text[pos] == 69):  # "e" or "E"
            pos += 1
            sign = 1
            if pos < n and (text[pos] == 45 or text[pos] == 43):
                sign = -1 if text[pos] == 45 else 1
                pos += 1
            exp_digits = 0
            while pos < n and 48 <= text[pos] <= 57:
                exponent = exponent * 10 + (text[pos] - 48)
                if exponent > 1000:
                    return False, none
                exp_digits += 1
                pos += 1
            if exp_digits == 0:
                return False, none
            exponent *= sign
        if pos < n:  # the separator, then the next number
            if text[pos] != 32 or i == count - 1:
                return False, none
            pos += 1
        e = exponent - after_point
        if e < -22 or e > 22:
            if m != 0:
                return False, none
            e = 0
        v = float(m) * _POWERS[e] if e >= 0 else float(m) / _POWERS[-e]
        out[i] = -v if negative else v
    if pos != n:
        return False, none
    return True, out
