"""The wide search's scoring as one compiled loop: every rotation, every translation, every
scored point, a grid look-up each (the reference: ``search_start`` of ``tests/oracles/matching.py``,
KD-tree queries over all candidates a chunk at a time).

The translations come grouped into square blocks of the lattice, blocks of blocks above them
(:class:`TranslationBlocks`): a block is scored first with the gate widened by its radius
(the farthest of its translations from its centre), which bounds what any of its translations
can score, so a whole block is left at once where even that bound cannot beat the best so far
(the branch and bound of correlative scan matching, over translations)."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from ._jit import inlined, kernel
from .grid import any_within

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


class TranslationBlocks(NamedTuple):
    """The candidates' translations in two levels of blocks, each level's blocks in the order
    they are scored: outer block ``b`` holds the inner blocks ``outer_start[b]:outer_start[b+1]``,
    inner block ``k`` the translations ``members[inner_start[k]:inner_start[k+1]]`` (indices
    into the candidates' ``tx``, ``ty``). For each block: its centre (x, y), its radius (m,
    the farthest of its translations from the centre, a little more for round-off), its least
    penalty and its least translation index (for ties in rotation-major order)."""

    outer_start: IntArray
    outer_centre: FloatArray
    outer_radius: FloatArray
    outer_penalty: FloatArray
    outer_first: IntArray
    inner_start: IntArray
    inner_centre: FloatArray
    inner_radius: FloatArray
    inner_penalty: FloatArray
    inner_first: IntArray
    members: IntArray


@inlined
def _can_win(
    rx: FloatArray,
    ry: FloatArray,
    x: float,
    y: float,
    radius: float,
    penalty: float,
    key: int,
    best_score: float,
    best_key: int,
    grid: tuple[FloatArray, IntArray, IntArray, IntArray, FloatArray],
) -> tuple[bool, int]:
    """How many of the rotated points ``(rx, ry)`` moved by ``(x, y)`` lie within ``radius``
    of a grid point, and whether that, less ``penalty``, can still beat the best so far (ties
    by ``key``, rotation-major): left at the first miss after which even every point left a
    hit would not (the count so far then)."""
    geometry, shape, start, _order, gxy = grid
    n = rx.shape[0]
    hits = 0
    for i in range(n):
        if any_within(rx[i] + x, ry[i] + y, radius, geometry, shape, start, gxy):
            hits += 1
        else:
            bound = (hits + (n - 1 - i)) / n - penalty
            if bound < best_score or (bound == best_score and key > best_key):
                return False, hits
    return True, hits


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
    blocks: TranslationBlocks,
) -> tuple[int, int, float]:
    """Of every rotation ``thetas[r]`` and translation ``(tx[t], ty[t])``, the one whose
    fraction of ``points`` within ``gate`` of a grid point, less ``penalty[t]``, is highest
    (the first of equal ones, rotation-major): ``(r, t, its fraction)``. The rotations are
    scored in the order ``rotations`` gives and the translations block by block in the order
    ``blocks`` gives (the likeliest first: a good best found early leaves more of the rest
    early); a block, or a translation, is left as soon as its misses make it unable to beat
    the best so far, or only equal it from later in rotation-major order (the result is the
    same in any order)."""
    b = blocks
    n, m = points.shape[0], tx.shape[0]
    rx, ry = np.empty(n), np.empty(n)
    best_score, best_r, best_t, best_fraction, best_key = -np.inf, 0, 0, 0.0, -1
    for r in rotations:
        c, s = math.cos(thetas[r]), math.sin(thetas[r])
        for i in range(n):
            rx[i] = c * points[i, 0] - s * points[i, 1]
            ry[i] = s * points[i, 0] + c * points[i, 1]
        for o in range(b.outer_penalty.shape[0]):
            cx, cy = b.outer_centre[o, 0], b.outer_centre[o, 1]
            key = r * m + b.outer_first[o]
            ok, _ = _can_win(
                rx, ry, cx, cy, gate + b.outer_radius[o], b.outer_penalty[o], key,
                best_score, best_key, grid,
            )  # fmt: skip
            if not ok:
                continue
            for k in range(b.outer_start[o], b.outer_start[o + 1]):
                cx, cy = b.inner_centre[k, 0], b.inner_centre[k, 1]
                key = r * m + b.inner_first[k]
                ok, _ = _can_win(
                    rx, ry, cx, cy, gate + b.inner_radius[k], b.inner_penalty[k], key,
                    best_score, best_key, grid,
                )  # fmt: skip
                if not ok:
                    continue
                for q in range(b.inner_start[k], b.inner_start[k + 1]):
                    t = b.members[q]
                    key = r * m + t
                    ok, hits = _can_win(
                        rx, ry, tx[t], ty[t], gate, penalty[t], key, best_score, best_key, grid
                    )
                    if not ok:
                        continue
                    fraction = hits / n
                    score = fraction - penalty[t]
                    if score > best_score or (score == best_score and key < best_key):
                        best_score, best_r, best_t = score, r, t
                        best_fraction, best_key = fraction, key
    return best_r, best_t, best_fraction
