"""Eq. 4 of a two-input rule base whose sets are partitions of unity, as the bilinear
interpolation of the consequent centres on the grid of peaks (``fuzzypos.fuzzy.RuleBase``'s
``_interpolate``, its numpy reference): one loop instead of a pair of ``np.interp`` per
column, with ``np.interp``'s own arithmetic."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from ._jit import kernel

FloatArray = NDArray[np.float64]


@kernel
def _segment(x: float, xp: FloatArray) -> int:
    """Where ``np.interp`` places ``x`` on ``xp``: -1 before the first point, ``n - 1`` on
    or after the last, else ``j`` with ``xp[j] <= x < xp[j + 1]``."""
    n = xp.shape[0]
    if x < xp[0]:
        return -1
    if x >= xp[n - 1]:
        return int(n) - 1
    j = 0
    while xp[j + 1] <= x:
        j += 1
    return j


@kernel
def _value(x: float, xp: FloatArray, j: int, f0: float, f1: float, first: float) -> float:
    """``np.interp``'s value at ``x`` in segment ``j`` (:func:`_segment`) between the values
    ``f0`` at ``xp[j]`` and ``f1`` at ``xp[j + 1]`` (``first``: the value before the first
    point; on or after the last point ``f0`` is the last value)."""
    if j < 0:
        return first
    if j == xp.shape[0] - 1 or xp[j] == x:
        return f0
    slope = (f1 - f0) / (xp[j + 1] - xp[j])
    out = float(slope * (x - xp[j]) + f0)
    if math.isnan(out):
        out = float(slope * (x - xp[j + 1]) + f1)
        if math.isnan(out) and f0 == f1:
            out = f0
    return out


@kernel
def bilinear_at(
    a: float, b: float, g1: FloatArray, g2: FloatArray, table: FloatArray, lo: float, hi: float
) -> float:  # fmt: skip
    """Eq. 4 at one input pair (``a``, ``b``) as :func:`bilinear` takes it: the sum over the
    sets k of input 2 of ``interp(a; g1, table[:, k]) · μ_k(b)``, clamped to ``[lo, hi]``.
    Only the one or two sets ``b`` has a membership in are summed: the others' terms are
    exact zeros (finite table and grids), which leave the sum as it is, in the same order."""
    if math.isnan(a) or math.isnan(b):
        return math.nan
    m, last1 = table.shape[1], g1.shape[0] - 1
    j1, j2 = _segment(a, g1), _segment(b, g2)
    k0 = 0 if j2 < 0 else j2  # the first set with a membership, then the next (if any)
    k1 = k0 if j2 < 0 or j2 == g2.shape[0] - 1 else j2 + 1
    acc = 0.0
    for k in range(k0, min(k1, m - 1) + 1):
        if j1 < 0:
            u = table[0, k]
        elif j1 == last1:
            u = table[last1, k]
        else:
            u = _value(a, g1, j1, table[j1, k], table[j1 + 1, k], table[0, k])
        if j2 < 0:
            e0 = e1 = 1.0 if k == 0 else 0.0
        else:
            e0 = 1.0 if k == j2 else 0.0
            e1 = 1.0 if k == j2 + 1 else 0.0
        w = _value(b, g2, j2, e0, e1, 1.0 if k == 0 else 0.0)
        acc += u * w
    if acc < lo:
        acc = lo
    if acc > hi:
        acc = hi
    return acc


@kernel
def bilinear(
    x1: FloatArray, x2: FloatArray, g1: FloatArray, g2: FloatArray, table: FloatArray,
    lo: float, hi: float,
) -> FloatArray:  # fmt: skip
    """``Σ_k interp(x1; g1, table[:, k]) · interp(x2; g2, e_k)`` per input pair, clamped to
    ``[lo, hi]`` as ``np.minimum(np.maximum(·, lo), hi)`` (``e_k`` the k-th unit vector: set
    k's membership; NaN inputs give NaN): :func:`bilinear_at` of each pair."""
    n = x1.shape[0]
    out = np.empty(n)
    for i in range(n):
        out[i] = bilinear_at(x1[i], x2[i], g1, g2, table, lo, hi)
    return out
