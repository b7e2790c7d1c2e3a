"""numpy reference of ``fuzzypos._kernels.agreement``: the scan's points ending on a wall and
its beams crossing one, the rays followed by sphere tracing with numpy over all beams at once."""

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
    res: float,
    near: float,
) -> tuple[int, int]:
    """``(hits, crossings)`` as the kernel counts them."""
    n = int(points.shape[0])
    if n == 0:
        return 0, 0
    dist = distance
    rows, cols = dist.shape
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

    hits = int(np.count_nonzero(lookup(ends) <= near))
    ray = ends - start
    length = np.hypot(ray[:, 0], ray[:, 1])
    unit = ray / np.maximum(length, 1e-12)[:, None]
    side = np.column_stack((-unit[:, 1], unit[:, 0])) * near
    # a beam crosses a wall only where it and the beams beside it (±near across it) all do: a
    # wall's end drawn a cell long, or a beam grazing it, is no contradiction
    crossed = _crossed(lookup, start, unit, length - near, res)
    for shift in (side, -side):
        crossed &= _crossed(lookup, start + shift, unit, length - near, res)
    return hits, int(np.count_nonzero(crossed))


def _crossed(
    lookup: Callable[[FloatArray], FloatArray],
    start: FloatArray,
    unit: FloatArray,
    stop: FloatArray,
    res: float,
) -> NDArray[np.bool_]:
    """Which rays from ``start`` along ``unit`` meet an occupied cell before ``stop`` (m), by
    sphere tracing: each step the distance to the nearest wall less a cell's diagonal (never
    past a wall unseen), at least half a cell; a cell on a wall (distance 0) is a crossing."""
    n = unit.shape[0]
    start = np.broadcast_to(start, unit.shape)
    t = np.zeros(n)
    crossed = np.zeros(n, dtype=bool)
    active = stop > 0.0
    for _ in range(100_000):
        if not active.any():
            break
        idx = np.nonzero(active)[0]
        d = lookup(start[idx] + t[idx, None] * unit[idx])
        wall = d < 0.5 * res
        crossed[idx[wall]] = True
        t[idx] += np.maximum(np.minimum(d, 1e3) - 1.5 * res, 0.5 * res)
        active[idx[wall | (t[idx] >= stop[idx])]] = False
    return crossed
