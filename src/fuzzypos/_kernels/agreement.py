"""Whether a scan agrees with a map at a pose, compiled: how many of its points end within
``near`` of an occupied cell (and how many end in free space farther from it), and how many
of its beams pass through one farther than ``near`` from both their ends (a robot beside a
wall, its pose a few centimetres off, starts its beams in the wall's cells), followed by
sphere tracing through the distance to the walls (:class:`~fuzzypos._kernels.localize.
WallField`'s ``distance``). A beam counts as crossing only where the beams beside it,
``near`` to either side, cross too: a wall's end drawn a cell long, or a beam grazing a
wall, contradicts nothing. The reference is ``tests/oracles/agreement.py``, the same steps
in numpy.

Poses and points as in :mod:`.localize` (the grid frame); off the map nothing stops a beam."""

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
def _entry(lo: float, hi: float, x: float, u: float, t0: float, t1: float) -> tuple[float, float]:
    """The ray x + t·u's span [t0, t1] clipped to lo <= x + t·u <= hi (Liang-Barsky)."""
    if abs(u) < 1e-12:
        return (t0, t1) if lo <= x <= hi else (1.0, 0.0)
    a, b = (lo - x) / u, (hi - x) / u
    return max(t0, min(a, b)), min(t1, max(a, b))


@inlined
def _crosses(
    distance: FloatArray,
    res: float,
    x: float,
    y: float,
    ux: float,
    uy: float,
    begin: float,
    stop: float,
) -> bool:
    """Whether the ray from (x, y) along (ux, uy) meets an occupied cell (distance below half a
    cell) between ``begin`` and ``stop`` m, its part over the map followed: each step the
    distance less a cell and a half (never past a wall unseen), at least half a cell."""
    rows, cols = distance.shape
    t, end = _entry(0.0, cols * res, x, ux, begin, stop)
    t, end = _entry(0.0, rows * res, y, uy, t, end)
    while t < end:
        d = _distance(distance, res, x + t * ux, y + t * uy)
        if d < 0.5 * res:
            return True
        if math.isinf(d):
            d = 0.0  # on the map's edge, rounding: a step of half a cell
        t += max(d - 1.5 * res, 0.5 * res)
    return False


@kernel
def agreement(
    points: FloatArray,
    sensor: FloatArray,
    pose: FloatArray,
    distance: FloatArray,
    free: NDArray[np.bool_],
    res: float,
    near: float,
) -> tuple[int, int, int]:
    """``(hits, crossings, strays)`` of the scan's ``points`` (robot frame; the beams start at
    ``sensor``, robot frame (x, y)) at ``pose`` (grid frame) against ``distance`` (the map's
    distance to its walls, cells of ``res`` m) and ``free`` (its free cells): strays are the
    points that end in free space farther than ``near`` from every wall."""
    c, s = math.cos(pose[2]), math.sin(pose[2])
    ox = c * sensor[0] - s * sensor[1] + pose[0]
    oy = s * sensor[0] + c * sensor[1] + pose[1]
    hits = 0
    crossings = 0
    strays = 0
    for i in range(points.shape[0]):
        qx = c * points[i, 0] - s * points[i, 1] + pose[0]
        qy = s * points[i, 0] + c * points[i, 1] + pose[1]
        at = _distance(distance, res, qx, qy)
        if at <= near:
            hits += 1
        elif not math.isinf(at) and free[int(qy / res), int(qx / res)]:
            strays += 1
        length = math.hypot(qx - ox, qy - oy)
        stop = length - near
        if stop <= near:
            continue
        ux, uy = (qx - ox) / length, (qy - oy) / length
        sx, sy = -uy * near, ux * near
        if (
            _crosses(distance, res, ox, oy, ux, uy, near, stop)
            and _crosses(distance, res, ox + sx, oy + sy, ux, uy, near, stop)
            and _crosses(distance, res, ox - sx, oy - sy, ux, uy, near, stop)
        ):
            crossings += 1
    return hits, crossings, strays


def warm() -> None:
    """The kernel called once on a small room, with the types the localizer hands it (so that
    a warm-up compiles, or loads, the code the localizer then runs)."""
    distance = np.full((12, 14), 0.2)
    distance[0, :] = 0.0
    free = np.ones((12, 14), dtype=np.bool_)
    points = np.array([[0.1 * k, -0.05 * (k % 3)] for k in range(8)], dtype=np.float64)
    agreement(points, np.zeros(2), np.array([0.3, 0.25, 0.1]), distance, free, 0.05, 0.2)
