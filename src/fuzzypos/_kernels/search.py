"""The wide search's scoring as one compiled loop: every rotation, every translation, every
scored point, a grid look-up each (the reference: ``fuzzypos.matching.search.search_start``
with ``FUZZYPOS_KERNELS=numpy``, KD-tree queries over all candidates a chunk at a time)."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from ._jit import kernel
from .grid import any_within

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


@kernel
def best_candidate(
    grid: tuple[FloatArray, IntArray, IntArray, IntArray, FloatArray],
    points: FloatArray,
    thetas: FloatArray,
    tx: FloatArray,
    ty: FloatArray,
    penalty: FloatArray,
    gate: float,
    rotations: IntArray,
    translations: IntArray,
) -> tuple[int, int, float]:
    """Of every rotation ``thetas[r]`` and translation ``(tx[t], ty[t])``, the one whose
    fraction of ``points`` within ``gate`` of a grid point, less ``penalty[t]``, is highest
    (the first of equal ones, rotation-major): ``(r, t, its fraction)``. The candidates are
    scored in the order ``rotations`` × ``translations`` give (the likeliest first: a good
    best found early leaves more of the rest early), and one is left as soon as its misses
    make it unable to beat the best so far, or only equal it from later in rotation-major
    order (the result is the same in any order)."""
    geometry, shape, start, _order, gxy = grid
    n, m = points.shape[0], tx.shape[0]
    rx, ry = np.empty(n), np.empty(n)
    best_score, best_r, best_t, best_fraction, best_key = -np.inf, 0, 0, 0.0, -1
    for r in rotations:
        c, s = math.cos(thetas[r]), math.sin(thetas[r])
        for i in range(n):
            rx[i] = c * points[i, 0] - s * points[i, 1]
            ry[i] = s * points[i, 0] + c * points[i, 1]
        for t in translations:
            key = r * m + t
            hits = 0
            beaten = False
            for i in range(n):
                if any_within(rx[i] + tx[t], ry[i] + ty[t], gate, geometry, shape, start, gxy):
                    hits += 1
                else:
                    # even every point left a hit would not beat the best (a bound: the
                    # branch-and-bound of correlative matching, one level deep)
                    bound = (hits + (n - 1 - i)) / n - penalty[t]
                    if bound < best_score or (bound == best_score and key > best_key):
                        beaten = True
                        break
            if beaten:
                continue
            fraction = hits / n
            score = fraction - penalty[t]
            if score > best_score or (score == best_score and key < best_key):
                best_score, best_r, best_t, best_fraction, best_key = score, r, t, fraction, key
    return best_r, best_t, best_fraction
