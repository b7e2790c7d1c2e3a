"""Whether a scan agrees with a map at a pose, compiled: how many of its points end within
``near`` of an occupied cell, and how many of its beams pass through one farther than
``near`` before their end, followed by sphere tracing through the distance to the walls
(:class:`~fuzzypos._kernels.localize.WallField`'s ``distance``). A beam counts as crossing
only where the beams beside it, ``near`` to either side, cross too: a wall's end drawn a cell
long, or a beam grazing a wall, contradicts nothing. The reference is
``tests/oracles/agreement.py``, the same steps in numpy.

Poses and points as in :mod:`.localize` (the grid frame); cells off the map stop nothing."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from ._jit import inlined, kernel

FloatArray = NDArray[np.float64]


@inlined
def _distance(distance: FloatArray, res: float, qx: float, qy: float) -> float:
    """The field's distance at (qx, qy); infinite off the map."""
    rows, cols = distance.shape
    if qx < 0.0 or qy < 0.0:
        return math.inf
    col = int(qx / res)
    row = int(qy / res)
    if row >= rows or col >= cols:
        return math.inf
    return float(distance[row, col])


@inlined
def _crosses(
    distance: FloatArray, res: float, x: float, y: float, ux: float, uy: float, stop: float
) -> bool:
    """Whether the ray from (x, y) along (ux, uy) meets an occupied cell (distance below half a
    cell) before ``stop`` m: each step the distance less a cell and a half (never past a wall
    unseen), at least half a cell; a ray leaving the map crosses nothing more."""
    t = 0.0
    while t < stop:
        d = _distance(distance, res, x + t * ux, y + t * uy)
        if d < 0.5 * res:
            return True
        if math.isinf(d):
            return False
        t += max(d - 1.5 * res, 0.5 * res)
    return False


@kernel
def agreement(
    points: FloatArray,
    sensor: FloatArray,
    pose: FloatArray,
    distance: FloatArray,
    res: float,
    near: float,
) -> tuple[int, int]:
    """``(hits, crossings)`` of the scan's ``points`` (robot frame; the beams start at
    ``sensor``, robot frame (x, y)) at ``pose`` (grid frame) against ``distance`` (the map's
    distance to its walls, cells of ``res`` m)."""
    c, s = math.cos(pose[2]), math.sin(pose[2])
    ox = c * sensor[0] - s * sensor[1] + pose[0]
    oy = s * sensor[0] + c * sensor[1] + pose[1]
    hits = 0
    crossings = 0
    for i in range(points.shape[0]):
        qx = c * points[i, 0] - s * points[i, 1] + pose[0]
        qy = s * points[i, 0] + c * points[i, 1] + pose[1]
        if _distance(distance, res, qx, qy) <= near:
            hits += 1
        length = math.hypot(qx - ox, qy - oy)
        stop = length - near
        if stop <= 0.0:
            continue
        ux, uy = (qx - ox) / length, (qy - oy) / length
        sx, sy = -uy * near, ux * near
        if (
            _crosses(distance, res, ox, oy, ux, uy, stop)
            and _crosses(distance, res, ox + sx, oy + sy, ux, uy, stop)
            and _crosses(distance, res, ox - sx, oy - sy, ux, uy, stop)
        ):
            crossings += 1
    return hits, crossings
