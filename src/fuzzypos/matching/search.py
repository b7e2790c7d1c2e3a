"""Beyond the paper: a wide search for a start where the prior cannot be trusted (after an
odometry jump, a gap in time or a failed match)."""

from __future__ import annotations

from functools import lru_cache
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from ..config import SearchConfig
from ._robust import FloatArray, IntArray
from .surface import SurfacePoints

if TYPE_CHECKING:  # the kernel module imports numba: on first use only
    from .._kernels.search import TranslationBlocks

__all__ = ["SearchHit", "search_start", "translation_blocks"]

#: the compiled search's blocks of translations: squares of 4 × 4 lattice steps, each of
#: 2 × 2 ones (a block is scored first with its gate widened by its radius)
BLOCK_SIDES = (4, 2)


class SearchHit(NamedTuple):
    """The best start the search found and its score: the fraction of the scored points that
    land within the gate of a reference point (without the distance penalty)."""

    start: FloatArray
    score: float


def search_start(
    reference: SurfacePoints,
    points: FloatArray,
    start: FloatArray,
    settings: SearchConfig,
    *,
    half_width: float,
    translation_half_width: float,
) -> SearchHit:
    """A wider search where the prior cannot be trusted (an odometry jump, a failed match):
    rotations ``start[2] ± half_width`` in steps of ``step`` and translations within
    ``± translation_half_width`` of the start's in steps of ``translation_step``, each scored by
    the fraction of (at most ``max_points``, evenly picked) ``points`` that land within ``gate``
    of a reference point, less ``distance_penalty`` per metre of translation from the start's
    (of near-equal scores, e.g. along a corridor's repeating doors, the one nearest the start
    wins). Returns the best start and its score (the fraction, without the penalty). One
    compiled loop over the candidates and a grid look-up per point. ``settings`` (the search
    section) gives ``step`` (``angle_step``), ``gate``, ``translation_step``, ``max_points``
    and ``distance_penalty`` (its ``batch_size`` bounds the numpy reference's KD-tree queries,
    in the tests)."""
    start = np.asarray(start, dtype=float)
    if len(reference) == 0 or points.shape[0] == 0:
        return SearchHit(start, 0.0)
    pts, thetas, tx, ty, penalty = _candidates(
        points, start, settings, half_width, translation_half_width
    )
    from .._kernels.search import best_candidate

    # the likeliest first, for the kernel's bound: rotations and translations nearest
    # the start's (the same best in any order)
    rotations = np.argsort(np.abs(thetas - start[2]), kind="stable")
    m = round(translation_half_width / settings.translation_step)
    blocks = _lattice_blocks(m, settings.translation_step, settings.distance_penalty)
    blocks = blocks._replace(
        outer_centre=blocks.outer_centre + start[:2],
        inner_centre=blocks.inner_centre + start[:2],
    )
    r, t, fraction = best_candidate(
        reference.grid, np.ascontiguousarray(pts, dtype=np.float64), thetas, tx, ty,
        penalty, float(settings.gate), rotations, blocks,
    )  # fmt: skip
    return SearchHit(np.array([tx[t], ty[t], thetas[r]]), float(fraction))


def translation_blocks(
    lattice: IntArray,
    tx: FloatArray,
    ty: FloatArray,
    penalty: FloatArray,
    priority: FloatArray,
    sides: tuple[int, int] = BLOCK_SIDES,
) -> TranslationBlocks:
    """The translations ``(tx, ty)`` at integer ``lattice`` positions (n, 2) grouped for the
    compiled search (:class:`~fuzzypos._kernels.search.TranslationBlocks`): squares of
    ``sides[1]`` lattice steps inside squares of ``sides[0]`` (a multiple of it), each scored in
    the order of the least ``priority`` among its translations (ties by index), the
    translations of an inner block likewise."""
    from .._kernels.search import TranslationBlocks

    outer_side, inner_side = sides
    if outer_side % inner_side:
        raise ValueError(f"the outer blocks' side {outer_side} is no multiple of {inner_side}")
    lattice = np.asarray(lattice, dtype=np.int64)
    corner = lattice - lattice.min(axis=0)
    inner_id = _block_ids(corner // inner_side)
    outer_id = _block_ids(corner // outer_side)
    rank = np.empty(len(tx), dtype=np.int64)
    rank[np.lexsort((np.arange(len(tx)), priority))] = np.arange(len(tx))
    # every translation's inner block ranked by its first member, outer block likewise
    inner_rank = np.full(inner_id.max() + 1, len(tx), dtype=np.int64)
    np.minimum.at(inner_rank, inner_id, rank)
    outer_rank = np.full(outer_id.max() + 1, len(tx), dtype=np.int64)
    np.minimum.at(outer_rank, outer_id, rank)
    members = np.lexsort((rank, inner_rank[inner_id], outer_rank[outer_id]))
    inner_of, outer_of = inner_id[members], outer_id[members]
    inner_begin = np.flatnonzero(np.r_[True, inner_of[1:] != inner_of[:-1]])
    inner = _describe(members, inner_begin, tx, ty, penalty)
    outer_of_inner = outer_of[inner_begin]
    outer_begin = np.flatnonzero(np.r_[True, outer_of_inner[1:] != outer_of_inner[:-1]])
    outer = _describe(members, inner_begin[outer_begin], tx, ty, penalty)
    return TranslationBlocks(
        np.r_[outer_begin, len(inner_begin)].astype(np.int64), *outer,
        np.r_[inner_begin, len(members)].astype(np.int64), *inner, members.astype(np.int64),
    )  # fmt: skip


def _block_ids(cells: IntArray) -> IntArray:
    """A block index per row of integer block coordinates ``cells`` (n, 2)."""
    _, ids = np.unique(cells, axis=0, return_inverse=True)
    return np.asarray(ids, dtype=np.int64).reshape(-1)


def _describe(
    members: IntArray, begin: IntArray, tx: FloatArray, ty: FloatArray, penalty: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray, IntArray]:
    """The centre, radius, least penalty and least index of each run of ``members`` that
    starts at ``begin``."""
    end = np.r_[begin[1:], len(members)]
    count = (end - begin).astype(float)
    x, y = tx[members], ty[members]
    centre = np.column_stack((np.add.reduceat(x, begin), np.add.reduceat(y, begin)))
    centre /= count[:, None]
    block = np.repeat(np.arange(len(begin)), end - begin)
    far = np.hypot(x - centre[block, 0], y - centre[block, 1])
    radius = np.maximum.reduceat(far, begin) * (1.0 + 1e-9) + 1e-9  # round-off's margin
    return (
        centre,
        radius,
        np.minimum.reduceat(penalty[members], begin),
        np.minimum.reduceat(members, begin).astype(np.int64),
    )


@lru_cache(maxsize=16)
def _lattice_blocks(m: int, step: float, distance_penalty: float) -> TranslationBlocks:
    """The blocks of the search's (2m + 1)² translations about a start at the origin (the
    order :func:`_candidates` makes them in), likeliest (least penalty) first."""
    offs = step * np.arange(-m, m + 1)
    tx, ty = (a.ravel() for a in np.meshgrid(offs, offs, indexing="ij"))
    k = np.arange(-m, m + 1)
    lattice = np.column_stack([a.ravel() for a in np.meshgrid(k, k, indexing="ij")])
    penalty = distance_penalty * np.hypot(tx, ty)
    blocks = translation_blocks(lattice, tx, ty, penalty, penalty)
    for a in blocks:
        a.setflags(write=False)  # shared by every search of this size
    return blocks


def _candidates(
    points: FloatArray,
    start: FloatArray,
    settings: SearchConfig,
    half_width: float,
    translation_half_width: float,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
    """What :func:`search_start` scores: the evenly picked points, the rotations, the
    translations (x and y, flattened) and each translation's penalty."""
    step, translation_step = settings.angle_step, settings.translation_step
    pts = points[:: max(1, points.shape[0] // settings.max_points)]
    k = round(half_width / step)
    thetas = start[2] + step * np.arange(-k, k + 1)
    m = round(translation_half_width / translation_step)
    offs = translation_step * np.arange(-m, m + 1)
    tx, ty = np.meshgrid(start[0] + offs, start[1] + offs, indexing="ij")
    tx, ty = tx.ravel(), ty.ravel()
    penalty = settings.distance_penalty * np.hypot(tx - start[0], ty - start[1])
    return pts, thetas, tx, ty, penalty
