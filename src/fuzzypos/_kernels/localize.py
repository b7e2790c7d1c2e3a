"""Localisation in an occupancy map, compiled: the scan's fit to the map's walls (point-to-line
Gauss-Newton through a lookup of each cell's nearest wall), the scan's likelihood at a pose
(the evidence between places), and the branch-and-bound search of the whole map over x, y
and θ (Cartographer's fast correlative scan matcher: max-pooled grids bound a block of
translations from above, blocks below the best leaf found are pruned). The references are
``tests/oracles/localization.py``, the same steps in numpy.

All poses and points are in the map's grid frame (metres from cell (0, 0)'s lower-left
corner, the map's origin yaw removed); cell (row, col) covers ``[col·res, (col+1)·res) ×
[row·res, (row+1)·res)``."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from ._jit import inlined, kernel

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

#: the status :func:`fit` returns
FIT_OK, FIT_TOO_FEW, FIT_SINGULAR = 0, 1, 2
#: at least this many points must pair with walls for a fit
MIN_PAIRS = 6


class WallField(NamedTuple):
    """The map's walls as the fit and the evidence read them: ``distance`` (rows, cols) from
    each cell's centre to the nearest occupied cell's centre (m, capped), ``nearest`` (rows,
    cols) the index of that cell's wall in ``wall`` (−1: none within the cap), ``wall`` (m, 4)
    each occupied cell's wall line: a point on it and its unit normal (x, y, n_x, n_y; a zero
    normal where the cell stands alone: the residual is then to the point), ``geometry``
    (resolution, cap)."""

    distance: FloatArray
    nearest: IntArray
    wall: FloatArray
    geometry: FloatArray


class SearchGrids(NamedTuple):
    """The global search's grids: ``score`` (levels, rows, cols), level ``h`` the maximum of
    level 0's likelihood over the block of 2^h × 2^h cells from (row, col) up and right (0
    past the map); ``free`` the same blocks' maximum of "the robot may stand here" (1/0)."""

    score: FloatArray
    free: FloatArray


@inlined
def _wall_residual(
    field: WallField, qx: float, qy: float, gate: float
) -> tuple[bool, float, float, float]:
    """Whether the point (qx, qy) pairs with a wall within ``gate``, the wall's normal (toward
    which the residual is signed) and the residual."""
    res = field.geometry[0]
    rows, cols = field.distance.shape
    if not (qx >= 0.0 and qy >= 0.0):
        return False, 0.0, 0.0, 0.0
    c = int(qx / res)
    r = int(qy / res)
    if r >= rows or c >= cols:
        return False, 0.0, 0.0, 0.0
    k = field.nearest[r, c]
    if k < 0 or field.distance[r, c] > gate:
        return False, 0.0, 0.0, 0.0
    wx, wy, nx, ny = field.wall[k, 0], field.wall[k, 1], field.wall[k, 2], field.wall[k, 3]
    dx, dy = qx - wx, qy - wy
    if nx == 0.0 and ny == 0.0:
        norm = math.hypot(dx, dy)
        if norm < 1e-9:
            return True, 1.0, 0.0, 0.0
        nx, ny = dx / norm, dy / norm
    e = nx * dx + ny * dy
    if abs(e) > gate:
        return False, 0.0, 0.0, 0.0
    return True, nx, ny, e


@inlined
def _normal_equations(
    points: FloatArray, pose: FloatArray, field: WallField, gate: float, sigma: float
) -> tuple[FloatArray, FloatArray, float, float, int]:
    """H = Σ w J Jᵀ and g = Σ w J e over the points paired at ``pose`` (Huber's weight at
    ``sigma``), Σ w e², Σ w and how many paired."""
    h = np.zeros((3, 3))
    g = np.zeros(3)
    c, s = math.cos(pose[2]), math.sin(pose[2])
    sse = 0.0
    wsum = 0.0
    used = 0
    for i in range(points.shape[0]):
        px, py = points[i, 0], points[i, 1]
        qx = c * px - s * py + pose[0]
        qy = s * px + c * py + pose[1]
        ok, nx, ny, e = _wall_residual(field, qx, qy, gate)
        if not ok:
            continue
        w = 1.0 if abs(e) <= sigma else sigma / abs(e)
        j0, j1 = nx, ny
        j2 = nx * (-s * px - c * py) + ny * (c * px - s * py)
        jac = (j0, j1, j2)
        for a in range(3):
            g[a] += w * jac[a] * e
            for b in range(3):
                h[a, b] += w * jac[a] * jac[b]
        sse += w * e * e
        wsum += w
        used += 1
    return h, g, sse, wsum, used


@kernel
def fit(
    points: FloatArray,
    start: FloatArray,
    prior: FloatArray,
    prior_information: FloatArray,
    field: WallField,
    settings: FloatArray,
) -> tuple[FloatArray, FloatArray, float, float, int, int]:
    """The pose (x, y, θ) that fits ``points`` (robot frame, (n, 2)) to the walls, from
    ``start``, by Gauss-Newton on the point-to-line residuals plus the prior's
    (``prior`` with ``prior_information``, 3×3, the angle's difference wrapped).
    ``settings`` = (gate, sigma, iterations): a point pairs with a wall within the gate,
    which shrinks by 0.6 per iteration down to 3σ; Huber's weight at σ.

    Returns the pose, the final H = Σ w J Jᵀ (without the prior), Σ w e², Σ w, how many
    points paired and the status (:data:`FIT_OK`, :data:`FIT_TOO_FEW`,
    :data:`FIT_SINGULAR`)."""
    gate0, sigma, iterations = settings[0], settings[1], int(settings[2])
    pose = start.copy()
    floor = 3.0 * sigma
    status = FIT_OK
    for it in range(iterations):
        gate = max(floor, gate0 * 0.6**it)
        h, g, _, _, used = _normal_equations(points, pose, field, gate, sigma)
        if used < MIN_PAIRS:
            status = FIT_TOO_FEW
            break
        diff = pose - prior
        diff[2] = (diff[2] + math.pi) % (2.0 * math.pi) - math.pi
        h = h + prior_information
        g = g + prior_information @ diff
        if abs(np.linalg.det(h)) < 1e-12:
            status = FIT_SINGULAR
            break
        step = np.linalg.solve(h, -g)
        pose = pose + step
        pose[2] = (pose[2] + math.pi) % (2.0 * math.pi) - math.pi
        if gate <= floor and math.hypot(step[0], step[1]) < 1e-4 and abs(step[2]) < 1e-4:
            break
    h, _, sse, wsum, used = _normal_equations(points, pose, field, floor, sigma)
    if status == FIT_OK and used < MIN_PAIRS:
        status = FIT_TOO_FEW
    return pose, h, sse, wsum, used, status


@kernel
def likelihood(
    points: FloatArray, pose: FloatArray, field: WallField, sigma: float, outlier: float
) -> tuple[float, float]:
    """The scan's log-likelihood at ``pose``, Σ log(ε + (1 − ε)·exp(−d²/2σ²)) over its points
    (d the distance to the nearest wall: to its line, at least the cells' distance less one
    cell; the cap past the field), and the points' mean of exp(−d²/2σ²) (the fit, 0..1)."""
    res, cap = field.geometry[0], field.geometry[1]
    rows, cols = field.distance.shape
    c, s = math.cos(pose[2]), math.sin(pose[2])
    total = 0.0
    fit_sum = 0.0
    n = points.shape[0]
    for i in range(n):
        px, py = points[i, 0], points[i, 1]
        qx = c * px - s * py + pose[0]
        qy = s * px + c * py + pose[1]
        d = cap
        if qx >= 0.0 and qy >= 0.0:
            col = int(qx / res)
            row = int(qy / res)
            if row < rows and col < cols and field.nearest[row, col] >= 0:
                ok, _, _, e = _wall_residual(field, qx, qy, cap + res)
                cell = field.distance[row, col]
                d = max(abs(e), cell - res) if ok else cell
        p = math.exp(-0.5 * (d / sigma) ** 2)
        total += math.log(outlier + (1.0 - outlier) * p)
        fit_sum += p
    return total, fit_sum / max(n, 1)


@inlined
def _bound(offsets: IntArray, a: int, col: int, row: int, level: int, grids: SearchGrids) -> float:
    """The mean over the points (angle ``a``) of level ``level``'s score where each lands
    with the robot at cell (row, col): at level 0 the score there, above it a bound of the
    scores of every robot cell of the block from (row, col)."""
    _, rows, cols = grids.score.shape
    n = offsets.shape[1]
    size = 1 << level
    total = 0.0
    for i in range(n):
        c = col + offsets[a, i, 0]
        r = row + offsets[a, i, 1]
        # a block that starts left of (below) the grid reaches into it: its part inside lies
        # within the block at the grid's edge
        if c < 0 < c + size:
            c = 0
        if r < 0 < r + size:
            r = 0
        if 0 <= c < cols and 0 <= r < rows:
            total += float(grids.score[level, r, c])
    mean: float = total / n
    return mean


@kernel
def branch_and_bound(
    offsets: IntArray,
    grids: SearchGrids,
    window: IntArray,
    min_score: float,
    ratio: float,
    capacity: int,
) -> FloatArray:
    """Every (angle, col, row) whose score is at least ``min_score`` and ``ratio`` × the
    best's, found by branch and bound: ``offsets`` (angles, n, 2) the points' cells (col,
    row) relative to the robot's for each angle; ``window`` = (col0, col1, row0, row1, top
    level): the robot's cells searched, in blocks of 2^top. A block is split into its four
    quarters while its bound (its level's score) reaches the threshold, best first, so that
    the best leaves raise the threshold early. Returns (m, 4): angle index, col, row, score,
    at most ``capacity`` rows (the best of them where more passed)."""
    col0, col1, row0, row1, top = window[0], window[1], window[2], window[3], window[4]
    n_angles = offsets.shape[0]
    step = 1 << top
    nc = (col1 - col0 + step - 1) // step
    nr = (row1 - row0 + step - 1) // step
    n_roots = n_angles * nc * nr
    root = np.empty((n_roots, 4))
    k = 0
    for a in range(n_angles):
        for i in range(nc):
            for j in range(nr):
                c, r = col0 + i * step, row0 + j * step
                s = -1.0
                if grids.free[top, r, c] > 0.0:
                    s = _bound(offsets, a, c, r, top, grids)
                root[k, 0], root[k, 1], root[k, 2], root[k, 3] = a, c, r, s
                k += 1
    order = np.argsort(root[:, 3])
    size = n_roots + 4 * (top + 2)
    stack = np.empty((size, 5))
    sp = 0
    for k in order:
        if root[k, 3] >= min_score:
            stack[sp, 0:4] = root[k]
            stack[sp, 4] = top
            sp += 1
    leaves = np.empty((capacity, 4))
    m = 0
    best = 0.0
    threshold = min_score
    child = np.empty((4, 4))
    while sp > 0:
        sp -= 1
        a, c, r, s, level = (
            int(stack[sp, 0]), int(stack[sp, 1]), int(stack[sp, 2]), stack[sp, 3],
            int(stack[sp, 4]),
        )  # fmt: skip
        if s < threshold:
            continue
        if level == 0:
            if m < capacity:
                leaves[m, 0], leaves[m, 1], leaves[m, 2], leaves[m, 3] = a, c, r, s
                m += 1
            else:  # full: replace the weakest
                w = int(np.argmin(leaves[:, 3]))
                if leaves[w, 3] < s:
                    leaves[w, 0], leaves[w, 1], leaves[w, 2], leaves[w, 3] = a, c, r, s
            if s > best:
                best = s
                threshold = max(min_score, ratio * best)
            continue
        level -= 1
        half = 1 << level
        nk = 0
        for dc in (0, half):
            for dr in (0, half):
                cc, rr = c + dc, r + dr
                if cc >= col1 or rr >= row1 or grids.free[level, rr, cc] <= 0.0:
                    continue
                child[nk, 0], child[nk, 1], child[nk, 2] = a, cc, rr
                child[nk, 3] = _bound(offsets, a, cc, rr, level, grids)
                nk += 1
        idx = np.argsort(child[:nk, 3])
        for q in idx:
            if child[q, 3] >= threshold:
                stack[sp, 0:4] = child[q]
                stack[sp, 4] = level
                sp += 1
    out = leaves[:m]
    found: FloatArray = out[out[:, 3] >= threshold].copy()
    return found


def warm() -> None:
    """Each kernel called once on a small room, with the types the localizer hands them (so
    that a warm-up compiles, or loads, the code the localizer then runs)."""
    rows, cols = 12, 14
    distance = np.full((rows, cols), 0.2)
    nearest = np.full((rows, cols), -1, dtype=np.int64)
    nearest[1:-1, 1:-1] = 0
    wall = np.array([[0.05, 0.3, 0.0, 1.0]])
    field = WallField(distance, nearest, wall, np.array([0.05, 1.0]))
    points = np.array([[0.1 * k, 0.05 * (k % 3)] for k in range(8)], dtype=np.float64)
    pose = np.array([0.3, 0.25, 0.1])
    fit(points, pose, pose.copy(), np.eye(3), field, np.array([0.5, 0.05, 3.0]))
    likelihood(points, pose, field, 0.1, 0.2)
    score = np.zeros((2, rows, cols))
    score[:, 2:5, 2:5] = 1.0
    grids = SearchGrids(score, np.ones((2, rows, cols)))
    offsets = np.zeros((2, points.shape[0], 2), dtype=np.int64)
    branch_and_bound(offsets, grids, np.array([0, cols, 0, rows, 1], dtype=np.int64), 0.1, 0.75, 16)
