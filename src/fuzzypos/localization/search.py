"""The search of the map for the places that explain one scan: the scan's points thinned,
turned through every angle of a step the search grid's cell subtends at the farthest point,
and each angle's translations searched by branch and bound
(:func:`fuzzypos._kernels.localize.branch_and_bound`); the leaves that pass become a few
distinct candidates (the best of each neighbourhood)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .._kernels.localize import SearchGrids, branch_and_bound
from ..config.localization import LocalizationConfig
from .field import MapField

__all__ = ["Candidate", "GlobalSearch", "thin"]

FloatArray = NDArray[np.float64]
#: a scan with fewer points than this (within search_range) is not searched for
MIN_POINTS = 5
#: at most this many leaves are kept by one search (the best)
_CAPACITY = 200_000


@dataclass(frozen=True)
class Candidate:
    """A place found: its pose in the grid frame and its score (the points' mean likelihood
    on the search grid)."""

    pose: FloatArray
    score: float


def thin(points: FloatArray, cell: float, limit: int) -> FloatArray:
    """One point per ``cell`` × ``cell`` square (the first), then every k-th so that at most
    ``limit`` remain."""
    if points.shape[0] == 0:
        return points
    keys = np.floor(points / cell).astype(np.int64)
    _, first = np.unique(keys, axis=0, return_index=True)
    kept = points[np.sort(first)]
    if kept.shape[0] > limit:
        kept = kept[np.linspace(0, kept.shape[0] - 1, limit).round().astype(np.int64)]
    return np.ascontiguousarray(kept)


def _levels(cells: int) -> int:
    """The top level of blocks for a span of ``cells``: blocks of about an eighth of it."""
    return int(np.clip(math.floor(math.log2(max(cells, 1) / 8.0)), 0, 7)) if cells > 8 else 0


class GlobalSearch:
    """The search over one map (its grids are built once, on first use)."""

    def __init__(self, field: MapField, cfg: LocalizationConfig) -> None:
        self._field = field
        self._cfg = cfg
        self._grids: SearchGrids | None = None
        self._cell = 0.0
        rows, cols = field.free.shape
        self._top = _levels(
            max(rows, cols) // max(1, round(cfg.search_resolution / field.resolution))
        )

    def grids(self) -> tuple[SearchGrids, float]:
        if self._grids is None:
            sigma = max(self._cfg.hit_sigma, 0.5 * self._cfg.search_resolution)
            self._grids, factor = self._field.search_grids(
                self._cfg.search_resolution, sigma, self._top
            )
            self._cell = factor * self._field.resolution
        return self._grids, self._cell

    def points(self, points: FloatArray) -> FloatArray:
        """The scan's points the search uses (within search_range, thinned)."""
        cfg = self._cfg
        near = points[np.hypot(points[:, 0], points[:, 1]) <= cfg.search_range]
        _, cell = self.grids()
        return thin(near, cell, cfg.search_points)

    def search(
        self,
        points: FloatArray,
        around: FloatArray | None = None,
        reach: tuple[float, float] = (0.0, 0.0),
        limit: int | None = None,
    ) -> list[Candidate]:
        """The distinct places (best first, at most ``limit``, default max_hypotheses) where
        the scan's ``points`` (robot frame) fit: over the whole map, or within ``reach`` =
        (metres, radians) of the grid-frame pose ``around``."""
        cfg = self._cfg
        grids, cell = self.grids()
        pts = self.points(points)
        if pts.shape[0] < MIN_POINTS:
            return []
        far = float(np.max(np.hypot(pts[:, 0], pts[:, 1])))
        step = min(cell / max(far, cell), math.radians(5.0))
        _, rows, cols = grids.score.shape
        if around is None:
            angles = np.arange(-math.pi, math.pi, step)
            window = (0, cols, 0, rows)
            top = self._top
        else:
            half = max(reach[1], step)
            angles = around[2] + np.arange(-half, half + step / 2, step)
            span = math.ceil(reach[0] / cell)
            c, r = int(around[0] // cell), int(around[1] // cell)
            window = (
                max(0, c - span),
                min(cols, c + span + 1),
                max(0, r - span),
                min(rows, r + span + 1),
            )
            if window[0] >= window[1] or window[2] >= window[3]:
                return []
            top = min(self._top, _levels(max(window[1] - window[0], window[3] - window[2]) * 8))
        c_, s_ = np.cos(angles)[:, None], np.sin(angles)[:, None]
        x = c_ * pts[None, :, 0] - s_ * pts[None, :, 1]
        y = s_ * pts[None, :, 0] + c_ * pts[None, :, 1]
        offsets = np.stack((np.floor(x / cell + 0.5), np.floor(y / cell + 0.5)), axis=-1)
        leaves = branch_and_bound(
            np.ascontiguousarray(offsets.astype(np.int64)),
            grids,
            np.array([*window, top], dtype=np.int64),
            float(cfg.search_min_score),
            float(cfg.search_ratio),
            _CAPACITY,
        )
        return self._distinct(leaves, angles, cell, cfg.max_hypotheses if limit is None else limit)

    def _distinct(
        self, leaves: FloatArray, angles: FloatArray, cell: float, limit: int
    ) -> list[Candidate]:
        """The best leaf of each neighbourhood (separation, separation_angle), best first."""
        cfg = self._cfg
        poses = np.column_stack(
            (
                (leaves[:, 1] + 0.5) * cell,
                (leaves[:, 2] + 0.5) * cell,
                angles[leaves[:, 0].astype(np.int64)],
            )
        )
        scores = leaves[:, 3].copy()
        out: list[Candidate] = []
        while len(out) < limit and scores.size and scores.max() > -np.inf:
            k = int(np.argmax(scores))
            pose = poses[k].copy()
            out.append(Candidate(pose, float(scores[k])))
            turn = np.abs((poses[:, 2] - pose[2] + math.pi) % (2.0 * math.pi) - math.pi)
            near = (np.hypot(poses[:, 0] - pose[0], poses[:, 1] - pose[1]) < cfg.separation) & (
                turn < cfg.separation_angle
            )
            scores[near] = -np.inf
        return out


def _near(a: FloatArray, b: FloatArray, distance: float, angle: float) -> bool:
    """Whether two poses are within ``distance`` and ``angle`` of each other."""
    turn = abs((a[2] - b[2] + math.pi) % (2.0 * math.pi) - math.pi)
    return math.hypot(a[0] - b[0], a[1] - b[1]) < distance and turn < angle
