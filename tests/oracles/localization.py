"""numpy references of the localisation kernels (``fuzzypos._kernels.localize``): the scan's
likelihood at a pose, the point-to-line Gauss-Newton fit to the map's walls, and the global
search done exhaustively (every angle, every cell) instead of by branch and bound."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

STAND_INS: list[tuple[str, str, object]] = []


def _moved(points: FloatArray, pose: FloatArray) -> FloatArray:
    c, s = math.cos(pose[2]), math.sin(pose[2])
    return points @ np.array([[c, s], [-s, c]]) + pose[:2]


def _pairs(field, q: FloatArray, gate: float) -> tuple[NDArray[np.bool_], FloatArray, FloatArray]:
    """Which points pair with a wall within ``gate``, their normals (n, 2) and residuals."""
    res = field.geometry[0]
    rows, cols = field.distance.shape
    c = np.floor(q[:, 0] / res).astype(np.int64)
    r = np.floor(q[:, 1] / res).astype(np.int64)
    inside = (q[:, 0] >= 0) & (q[:, 1] >= 0) & (r < rows) & (c < cols)
    rc, cc = np.where(inside, r, 0), np.where(inside, c, 0)
    k = np.where(inside, field.nearest[rc, cc], -1)
    ok = (k >= 0) & (field.distance[rc, cc] <= gate)
    wall = field.wall[np.maximum(k, 0)]
    d = q - wall[:, :2]
    n = wall[:, 2:].copy()
    alone = (n[:, 0] == 0) & (n[:, 1] == 0)
    norm = np.hypot(d[:, 0], d[:, 1])
    safe = np.where(norm < 1e-9, 1.0, norm)
    n[alone] = np.where((norm < 1e-9)[alone, None], [1.0, 0.0], d[alone] / safe[alone, None])
    e = np.sum(n * d, axis=1)
    e = np.where(alone & (norm < 1e-9), 0.0, e)
    ok &= np.abs(e) <= gate
    return ok, n, e


def likelihood(points, pose, field, sigma, outlier) -> tuple[float, float]:
    res, cap = field.geometry
    q = _moved(points, pose)
    rows, cols = field.distance.shape
    c = np.floor(q[:, 0] / res).astype(np.int64)
    r = np.floor(q[:, 1] / res).astype(np.int64)
    inside = (q[:, 0] >= 0) & (q[:, 1] >= 0) & (r < rows) & (c < cols)
    rc, cc = np.where(inside, r, 0), np.where(inside, c, 0)
    has = inside & (field.nearest[rc, cc] >= 0)
    ok, _, e = _pairs(field, q, cap + res)
    cell = field.distance[rc, cc]
    d = np.where(has, np.where(ok, np.maximum(np.abs(e), cell - res), cell), cap)
    p = np.exp(-0.5 * (d / sigma) ** 2)
    return float(np.sum(np.log(outlier + (1 - outlier) * p))), float(np.mean(p))


def _normal_equations(points, pose, field, gate, sigma):
    q = _moved(points, pose)
    ok, n, e = _pairs(field, q, gate)
    c, s = math.cos(pose[2]), math.sin(pose[2])
    px, py = points[:, 0], points[:, 1]
    j = np.column_stack(
        (n[:, 0], n[:, 1], n[:, 0] * (-s * px - c * py) + n[:, 1] * (c * px - s * py))
    )
    w = np.where(np.abs(e) <= sigma, 1.0, sigma / np.maximum(np.abs(e), 1e-300))
    j, w, e = j[ok], w[ok], e[ok]
    h = (j * w[:, None]).T @ j
    g = (j * w[:, None]).T @ e
    return h, g, float(np.sum(w * e * e)), float(np.sum(w)), int(ok.sum())


def fit(points, start, prior, prior_information, field, settings):
    gate0, sigma, iterations = settings[0], settings[1], int(settings[2])
    pose = start.astype(np.float64).copy()
    floor = 3.0 * sigma
    status = 0
    for it in range(iterations):
        gate = max(floor, gate0 * 0.6**it)
        h, g, _, _, used = _normal_equations(points, pose, field, gate, sigma)
        if used < 6:
            status = 1
            break
        diff = pose - prior
        diff[2] = (diff[2] + math.pi) % (2 * math.pi) - math.pi
        h = h + prior_information
        g = g + prior_information @ diff
        if abs(np.linalg.det(h)) < 1e-12:
            status = 2
            break
        step = np.linalg.solve(h, -g)
        pose = pose + step
        pose[2] = (pose[2] + math.pi) % (2 * math.pi) - math.pi
        if gate <= floor and math.hypot(step[0], step[1]) < 1e-4 and abs(step[2]) < 1e-4:
            break
    h, _, sse, wsum, used = _normal_equations(points, pose, field, floor, sigma)
    if status == 0 and used < 6:
        status = 1
    return pose, h, sse, wsum, used, status


def exhaustive_search(offsets, grids, window, min_score, ratio) -> FloatArray:
    """Every (angle, col, row) of the window on a free cell scoring at least ``min_score``
    and ``ratio`` × the best, scored at level 0 (the branch and bound's answer, found by
    trying them all)."""
    col0, col1, row0, row1 = (int(v) for v in window[:4])
    score = grids.score[0]
    rows, cols = score.shape
    out = []
    for a in range(offsets.shape[0]):
        for c in range(col0, col1):
            for r in range(row0, row1):
                if grids.free[0, r, c] <= 0:
                    continue
                cc, rr = c + offsets[a, :, 0], r + offsets[a, :, 1]
                inside = (cc >= 0) & (cc < cols) & (rr >= 0) & (rr < rows)
                s = float(np.sum(score[rr[inside], cc[inside]])) / offsets.shape[1]
                out.append((a, c, r, s))
    table = np.array(out).reshape(-1, 4)
    if not table.size:
        return table
    best = table[:, 3].max()
    return table[table[:, 3] >= max(min_score, ratio * best)]
