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
def slopes(g1: FloatArray, g2: FloatArray, table: FloatArray) -> tuple[FloatArray, FloatArray]:
    """What :func:`bilinear` divides by, once per rule base: the slope of each consequent
    column of ``table`` between two peaks of ``g1`` (``np.interp``'s ``(f1 − f0) / (x1 − x0)``;
    the last row unused) and the inverse width between two peaks of ``g2`` (a membership's
    slope is ±1 over it)."""
    n1, n2, m = g1.shape[0], g2.shape[0], table.shape[1]
    s1 = np.zeros((n1, m))
    for j in range(n1 - 1):
        for k in range(m):
            s1[j, k] = (table[j + 1, k] - table[j, k]) / (g1[j + 1] - g1[j])
    inverse = np.zeros(n2)
    for j in range(n2 - 1):
        inverse[j] = 1.0 / (g2[j + 1] - g2[j])
    return s1, inverse


@kernel
def bilinear(
    x1: FloatArray, x2: FloatArray, g1: FloatArray, g2: FloatArray, table: FloatArray,
    lo: float, hi: float,
) -> FloatArray:  # fmt: skip
    """``Σ_k interp(x1; g1, table[:, k]) · interp(x2; g2, e_k)`` per input pair, clamped to
    ``[lo, hi]`` as ``np.minimum(np.maximum(·, lo), hi)`` (``e_k`` the k-th unit vector: set
    k's membership; NaN inputs give NaN), each ``np.interp`` with its own arithmetic (the
    :func:`slopes` are the ones it computes). Only the one or two sets of input 2 with a
    membership are summed: the others' terms are exact zeros (finite table and grids), which
    leave the sum as it is, in the same order. (One loop: a call per pair costs twice the
    arithmetic.)"""
    n, m = x1.shape[0], table.shape[1]
    last1, last2 = g1.shape[0] - 1, g2.shape[0] - 1
    s1, inverse = slopes(g1, g2, table)
    out = np.empty(n)
    for i in range(n):
        a, b = x1[i], x2[i]
        if math.isnan(a) or math.isnan(b):
            out[i] = math.nan
            continue
        j1, j2 = _segment(a, g1), _segment(b, g2)
        k0 = 0 if j2 < 0 else j2  # the first set with a membership, then the next (if any)
        on_peak = j2 < 0 or j2 == last2 or g2[j2] == b  # a membership of 1 in set k0 alone
        k1 = k0 if on_peak else j2 + 1
        acc = 0.0
        for k in range(k0, min(k1, m - 1) + 1):
            if j1 < 0:
                u = table[0, k]
            elif j1 == last1 or g1[j1] == a:
                u = table[j1, k]
            else:
                u = s1[j1, k] * (a - g1[j1]) + table[j1, k]
                if math.isnan(u):
                    u = _value(a, g1, j1, table[j1, k], table[j1 + 1, k], table[0, k])
            if on_peak:
                w = 1.0
            elif k == j2:  # np.interp from 1 at g2[j2] down to 0 at g2[j2 + 1]
                w = -inverse[j2] * (b - g2[j2]) + 1.0
            else:  # and from 0 up to 1
                w = inverse[j2] * (b - g2[j2]) + 0.0
            acc += u * w
        if acc < lo:
            acc = lo
        if acc > hi:
            acc = hi
        out[i] = acc
    return out
