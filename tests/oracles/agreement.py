"""numpy reference of ``fuzzypos._kernels.agreement``: the scan's points ending on a wall,
its beams crossing one, its points ending in free space away from walls; the rays followed by
sphere tracing with numpy over all beams at once."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


def agreement(
    points: FloatArray,
    sensor: FloatArray,
    pose: FloatArray,
    distance: FloatArray,
    free: NDArray[np.bool_],
    res: float,
    near: float,
) -> tuple[int, int, int]:
    """``(hits, crossings, strays)`` as the kernel counts them."""
    n = int(points.shape[0])
    if n == 0:
        return 0, 0, 0
    dist = distance
    rows, cols = dist.shape
    size = (cols * res, rows * res)
    c, s = math.cos(pose[2]), math.sin(pose[2])
    rot = np.array([[c, -s], [s, c]])
    ends = points @ rot.T + pose[:2]
    start = rot @ np.asarray(sensor[:2], dtype=np.float64) + pose[:2]

    def lookup(q: FloatArray) -> FloatArray:
        col = np.floor(q[:, 0] / res).astype(np.int64)
        row = np.floor(q[:, 1] / res).astype(np.int64)
        inside = (row >= 0) & (row < rows) & (col >= 0) & (col < cols)
        out = np.full(q.shape[0], np.inf)
        out[inside] = dist[row[inside], col[inside]]
        return out

    at = lookup(ends)
    hits = int(np.count_nonzero(at <= near))
    col = np.floor(ends[:, 0] / res).astype(np.int64)
    row = np.floor(ends[:, 1] / res).astype(np.int64)
    on_map = np.isfinite(at)
    stray = np.zeros(n, dtype=bool)
    stray[on_map] = (at[on_map] > near) & free[row[on_map], col[on_map]]
    strays = int(np.count_nonzero(stray))
    ray = ends - start
    length = np.hypot(ray[:, 0], ray[:, 1])
    unit = ray / np.maximum(length, 1e-12)[:, None]
    side = np.column_stack((-unit[:, 1], unit[:, 0])) * near
    # a beam crosses a wall only where it and the beams beside it (±near across it) all do: a
    # wall's end drawn a cell long, or a beam grazing it, is no contradiction
    stop = np.where(length - near > near, length - near, 0.0)
    crossed = _crossed(lookup, start, unit, stop, res, size, near)
    for shift in (side, -side):
        crossed &= _crossed(lookup, start + shift, unit, stop, res, size, near)
    return hits, int(np.count_nonzero(crossed)), strays


def _clip(lo: float, hi: float, x: FloatArray, u: FloatArray, t0: FloatArray, t1: FloatArray):
    """The rays' spans [t0, t1] clipped to lo <= x + t·u <= hi."""
    flat = np.abs(u) < 1e-12
    safe = np.where(flat, 1.0, u)
    a, b = (lo - x) / safe, (hi - x) / safe
    inside = (lo <= x) & (x <= hi)
    t0 = np.where(flat, np.where(inside, t0, 1.0), np.maximum(t0, np.minimum(a, b)))
    t1 = np.where(flat, np.where(inside, t1, 0.0), np.minimum(t1, np.maximum(a, b)))
    return t0, t1


def _crossed(
    lookup: Callable[[FloatArray], FloatArray],
    start: FloatArray,
    unit: FloatArray,
    stop: FloatArray,
    res: float,
    size: tuple[float, float],
    begin: float,
) -> NDArray[np.bool_]:
    """Which rays from ``start`` along ``unit`` meet an occupied cell between ``begin`` and
    ``stop`` (m), their part over the map (``size``: width, height) followed by sphere
    tracing: each step the distance to the nearest wall less a cell and a half, at least half
    a cell; a cell on a wall (distance 0) is a crossing."""
    n = unit.shape[0]
    start = np.broadcast_to(start, unit.shape)
    t, end = _clip(0.0, size[0], start[:, 0], unit[:, 0], np.full(n, begin), stop)
    t, end = _clip(0.0, size[1], start[:, 1], unit[:, 1], t, end)
    crossed = np.zeros(n, dtype=bool)
    active = t < end
    for _ in range(100_000):
        if not active.any():
            break
        idx = np.nonzero(active)[0]
        d = lookup(start[idx] + t[idx, None] * unit[idx])
        wall = d < 0.5 * res
        crossed[idx[wall]] = True
        d = np.where(np.isinf(d), 0.0, d)
        t[idx] += np.maximum(d - 1.5 * res, 0.5 * res)
        active[idx[wall | (t[idx] >= end[idx])]] = False
    return crossed
