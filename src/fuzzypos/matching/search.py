"""Beyond the paper: a wide search for a start where the prior cannot be trusted (after an
odometry jump, a gap in time or a failed match)."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .._kernels import compiled
from ..config import SearchConfig
from ._robust import FloatArray
from .surface import SurfacePoints

__all__ = ["SearchHit", "search_start"]


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
    compiled loop over the candidates and a grid look-up per point (``FUZZYPOS_KERNELS=numpy``:
    KD-tree queries over all candidates, a chunk of rotations at a time). ``settings`` (the
    search section) gives ``step`` (``angle_step``), ``gate``, ``translation_step``,
    ``max_points``, ``distance_penalty`` and ``batch_size`` (at most that many transformed points
    per KD-tree query of the numpy reference)."""
    start = np.asarray(start, dtype=float)
    if len(reference) == 0 or points.shape[0] == 0:
        return SearchHit(start, 0.0)
    pts, thetas, tx, ty, penalty = _candidates(
        points, start, settings, half_width, translation_half_width
    )
    if compiled():
        from .._kernels.search import best_candidate

        # the likeliest first, for the kernel's bound: rotations and translations nearest
        # the start's (the same best in any order)
        rotations = np.argsort(np.abs(thetas - start[2]), kind="stable")
        r, t, fraction = best_candidate(
            reference.grid, np.ascontiguousarray(pts, dtype=np.float64), thetas, tx, ty,
            penalty, float(settings.gate), rotations, np.argsort(penalty, kind="stable"),
        )  # fmt: skip
        return SearchHit(np.array([tx[t], ty[t], thetas[r]]), float(fraction))
    return _search_numpy(reference, pts, start, thetas, tx, ty, penalty, settings)


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


def _search_numpy(
    reference: SurfacePoints,
    pts: FloatArray,
    start: FloatArray,
    thetas: FloatArray,
    tx: FloatArray,
    ty: FloatArray,
    penalty: FloatArray,
    settings: SearchConfig,
) -> SearchHit:
    """The candidates scored by KD-tree queries, a chunk of rotations at a time (the compiled
    kernel's reference): the best start and its fraction."""
    gate = settings.gate
    best_score, best_fraction, best = -np.inf, 0.0, start
    chunk = max(1, settings.batch_size // (tx.size * pts.shape[0]))
    for c0 in range(0, thetas.size, chunk):  # bounded memory: a chunk of rotations at a time
        th = thetas[c0 : c0 + chunk]
        c, s = np.cos(th)[:, None], np.sin(th)[:, None]
        rx = c * pts[None, :, 0] - s * pts[None, :, 1]  # (rotations, points)
        ry = s * pts[None, :, 0] + c * pts[None, :, 1]
        qx = rx[:, None, :] + tx[None, :, None]  # (rotations, translations, points)
        qy = ry[:, None, :] + ty[None, :, None]
        dist, _ = reference.tree.query(
            np.stack((qx.ravel(), qy.ravel()), axis=1), distance_upper_bound=gate
        )
        fraction = np.isfinite(dist).reshape(th.size, tx.size, -1).mean(axis=2)
        score = fraction - penalty[None, :]
        i = int(np.argmax(score))
        if score.flat[i] > best_score:
            r, t = divmod(i, tx.size)
            best_score, best_fraction = float(score.flat[i]), float(fraction.flat[i])
            best = np.array([tx[t], ty[t], th[r]])
    return SearchHit(best, best_fraction)
