"""A uniform grid over a point set, built once per surface, for nearest-neighbour queries from
compiled loops (the stand-in for a KD-tree query per iteration).

Cells are squares of side ``cell`` (smaller for a dense point set: about POINTS_PER_CELL
points in an occupied cell, so that a dense scanner's query looks at as few points as a
sparse one's, its scan's cost linear in its beams rather than quadratic); the points are
sorted by cell and ``start[c]:start[c + 1]`` are cell ``c``'s (``c = ix · ny + iy``) in
``order``/``xy``: the cells of one column of the grid are contiguous, so a query scans one
stretch of points per column of the square around it. It looks within one cell side first
and, only where nothing lies that near, within its whole radius (or, from a guess, within
twice the guess's distance). The cells it scanned also bound how far every other point lies:
the refinement's iterations keep a point's nearest while it stays nearer than that
(``nearest_bounded``).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from ._jit import inlined, kernel

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

#: at most this many cells per point (and this many more): a far-flung point set gets larger
#: cells rather than a grid larger than the points
CELLS_PER_POINT = 64
MIN_CELLS = 4096
#: at most about this many points in an occupied cell: a dense point set (a scanner of
#: thousands of beams puts hundreds of points in a cell of a 180-beam scan's size, each of
#: which every query near them would look at) gets smaller cells, within the budget above
POINTS_PER_CELL = 4
#: a grid's geometry and shape as scalars (:func:`frame_of`)
Frame = tuple[float, float, float, float, int, int]


#: a bound on the distance to the points beyond a box of cells is lowered by this (m): a point
#: on a cell's edge may have been rounded into the cell on either side
_ROUNDING = 1e-9


class Grid(NamedTuple):
    """A point set sorted into grid cells: ``geometry`` = (x0, y0, 1/cell, cell), ``shape`` =
    (nx, ny), ``start`` (nx·ny + 1) the first entry of each cell, ``order`` the points'
    indices sorted by cell and ``xy`` their coordinates in that order."""

    geometry: FloatArray
    shape: IntArray
    start: IntArray
    order: IntArray
    xy: FloatArray


def build_grid(xy: FloatArray, cell: float) -> Grid:
    """The grid of ``xy`` (n, 2) with cells of side ``cell`` (larger where the points spread so
    far that there would be more than CELLS_PER_POINT · n + MIN_CELLS cells)."""
    pts = np.ascontiguousarray(xy, dtype=np.float64).reshape(-1, 2)
    n = pts.shape[0]
    if n == 0:
        return Grid(
            np.array([0.0, 0.0, 1.0 / cell, cell]),
            np.array([1, 1], dtype=np.int64),
            np.zeros(2, dtype=np.int64),
            np.zeros(0, dtype=np.int64),
            np.zeros((0, 2)),
        )
    lo, hi = _extent(pts)
    w, h = float(hi[0] - lo[0]), float(hi[1] - lo[1])
    budget = CELLS_PER_POINT * n + MIN_CELLS
    # the least side s with (w/s + 1)(h/s + 1) ≤ budget: budget·s² − (w + h)·s − w·h = 0
    least = ((w + h) + math.sqrt((w + h) ** 2 + 4.0 * budget * w * h)) / (2.0 * budget)
    side = _dense_side(pts, lo, max(cell, least), least)
    nx, ny = int(w / side) + 1, int(h / side) + 1
    geometry = np.array([float(lo[0]), float(lo[1]), 1.0 / side, side])
    start, order = _sort_into_cells(pts, geometry, nx, ny)
    return Grid(geometry, np.array([nx, ny], dtype=np.int64), start, order, pts[order])


def _dense_side(pts: FloatArray, lo: tuple[float, float], side: float, least: float) -> float:
    """``side``, or where its occupied cells hold more than POINTS_PER_CELL points on average,
    a side that many times smaller (points along surfaces: a cell's count goes with its side),
    at least ``least``."""
    if pts.shape[0] <= POINTS_PER_CELL:
        return side
    ix = np.floor((pts[:, 0] - lo[0]) / side).astype(np.int64)
    iy = np.floor((pts[:, 1] - lo[1]) / side).astype(np.int64)
    occupied = np.unique(ix * (int(iy.max()) + 1) + iy).size
    per_cell = pts.shape[0] / occupied
    if per_cell <= POINTS_PER_CELL:
        return side
    return float(max(side * POINTS_PER_CELL / per_cell, least))


@kernel
def _extent(xy: FloatArray) -> tuple[tuple[float, float], tuple[float, float]]:
    """The least and the greatest x and y of ``xy`` (n ≥ 1, 2): ``xy.min(axis=0)`` and
    ``xy.max(axis=0)`` (a NaN too), without numpy's reduction's overhead."""
    x0 = x1 = xy[0, 0]
    y0 = y1 = xy[0, 1]
    for i in range(1, xy.shape[0]):
        x, y = xy[i, 0], xy[i, 1]
        if x < x0 or x != x:
            x0 = x
        if x > x1 or x != x:
            x1 = x
        if y < y0 or y != y:
            y0 = y
        if y > y1 or y != y:
            y1 = y
    return (x0, y0), (x1, y1)


@kernel
def _sort_into_cells(
    xy: FloatArray, geometry: FloatArray, nx: int, ny: int
) -> tuple[IntArray, IntArray]:
    """The cells' first entries and the points' order by cell (a counting sort)."""
    n = xy.shape[0]
    x0, y0, inv = geometry[0], geometry[1], geometry[2]
    cell_of = np.empty(n, dtype=np.int64)
    start = np.zeros(nx * ny + 1, dtype=np.int64)
    for i in range(n):
        ix = min(max(int((xy[i, 0] - x0) * inv), 0), nx - 1)
        iy = min(max(int((xy[i, 1] - y0) * inv), 0), ny - 1)
        c = ix * ny + iy
        cell_of[i] = c
        start[c + 1] += 1
    for c in range(nx * ny):
        start[c + 1] += start[c]
    fill = start[:-1].copy()
    order = np.empty(n, dtype=np.int64)
    for i in range(n):
        c = cell_of[i]
        order[fill[c]] = i
        fill[c] += 1
    return start, order


@inlined
def _cell_range(q: float, radius: float, origin: float, inv: float, n: int) -> tuple[int, int]:
    """The cells along one axis (of ``n``) that the interval ``q ± radius`` touches, clipped to
    the grid; an empty range (lo > hi) where it misses the grid (or ``q`` is not finite)."""
    a = (q - radius - origin) * inv
    b = (q + radius - origin) * inv
    if not (b >= 0.0 and a < n):
        return 1, 0
    lo = 0 if a <= 0.0 else int(a)
    hi = n - 1 if b >= n - 1 else int(b)
    return lo, hi


@kernel
def _scan_box(
    qx: float,
    qy: float,
    radius: float,
    best_d2: float,
    best: int,
    geometry: FloatArray,
    shape: IntArray,
    start: IntArray,
    xy: FloatArray,
) -> tuple[int, float]:
    """The nearest point closer than ``sqrt(best_d2)`` in the cells within ``radius`` of the
    query (else ``best``), and its squared distance."""
    x0, y0, inv = geometry[0], geometry[1], geometry[2]
    nx, ny = shape[0], shape[1]
    ix0, ix1 = _cell_range(qx, radius, x0, inv, nx)
    iy0, iy1 = _cell_range(qy, radius, y0, inv, ny)
    if iy0 > iy1:
        return best, best_d2
    for ix in range(ix0, ix1 + 1):
        row = ix * ny
        for k in range(start[row + iy0], start[row + iy1 + 1]):
            dx = xy[k, 0] - qx
            dy = xy[k, 1] - qy
            d2 = dx * dx + dy * dy
            if d2 < best_d2:
                best_d2 = d2
                best = k
    return best, best_d2


@kernel
def nearest(
    qx: float,
    qy: float,
    radius: float,
    geometry: FloatArray,
    shape: IntArray,
    start: IntArray,
    xy: FloatArray,
) -> tuple[int, float]:
    """The grid entry nearest to ``(qx, qy)`` closer than ``radius`` (−1 where none) and its
    squared distance. An index into the grid's sorted ``xy`` (``order`` maps it back)."""
    side = geometry[3]
    r2 = radius * radius
    first = min(radius, side)
    best, d2 = _scan_box(qx, qy, first, r2, -1, geometry, shape, start, xy)
    # anything outside the first square lies further than ``first`` from the query
    if radius <= side or (best >= 0 and d2 <= first * first):
        return best, d2
    return _scan_box(qx, qy, radius, r2, -1, geometry, shape, start, xy)


@kernel
def any_within(
    qx: float,
    qy: float,
    radius: float,
    geometry: FloatArray,
    shape: IntArray,
    start: IntArray,
    xy: FloatArray,
) -> bool:
    """Whether some grid point lies closer than ``radius`` to ``(qx, qy)`` (stops at the
    first)."""
    x0, y0, inv = geometry[0], geometry[1], geometry[2]
    nx, ny = shape[0], shape[1]
    r2 = radius * radius
    ix0, ix1 = _cell_range(qx, radius, x0, inv, nx)
    iy0, iy1 = _cell_range(qy, radius, y0, inv, ny)
    if iy0 > iy1:
        return False
    for ix in range(ix0, ix1 + 1):
        row = ix * ny
        for k in range(start[row + iy0], start[row + iy1 + 1]):
            dx = xy[k, 0] - qx
            dy = xy[k, 1] - qy
            if dx * dx + dy * dy < r2:
                return True
    return False


@inlined
def _clearance(
    qx: float,
    qy: float,
    ix0: int,
    ix1: int,
    iy0: int,
    iy1: int,
    frame: Frame,
) -> float:
    """A lower bound on the distance from ``(qx, qy)`` to every point outside the cells
    ``ix0..ix1`` × ``iy0..iy1`` (a box of the grid, or an empty range where the query's square
    missed it): the way to the nearest side of the box that has cells beyond it (less
    ``_ROUNDING``: a point on a cell's edge may have been rounded into either cell)."""
    x0, y0, _inv, side, nx, ny = frame
    if ix0 > ix1 or iy0 > iy1:  # off the grid: the way to its extent along either axis
        gap: float = max(x0 - qx, qx - (x0 + nx * side), y0 - qy, qy - (y0 + ny * side))
        return gap - _ROUNDING
    clear = math.inf
    if ix0 > 0:
        clear = min(clear, qx - (x0 + ix0 * side))
    if ix1 < nx - 1:
        clear = min(clear, x0 + (ix1 + 1) * side - qx)
    if iy0 > 0:
        clear = min(clear, qy - (y0 + iy0 * side))
    if iy1 < ny - 1:
        clear = min(clear, y0 + (iy1 + 1) * side - qy)
    return clear - _ROUNDING


@inlined
def _scan_box_near(
    qx: float,
    qy: float,
    box: float,
    frame: Frame,
    start: IntArray,
    xy: FloatArray,
) -> tuple[int, float, int, float, float, float]:
    """Of the cells within ``box`` of the query: the nearest point (−1 where none; the first
    of equal ones in the grid's order) and its squared distance (∞ where none), the next
    nearest and its, the squared distance of the nearest third point, and
    :func:`_clearance`, the distance beyond which the points not scanned lie."""
    x0, y0, inv, _side, nx, ny = frame
    first, first_d2, second, second_d2, third_d2 = -1, math.inf, -1, math.inf, math.inf
    ix0, ix1 = _cell_range(qx, box, x0, inv, nx)
    iy0, iy1 = _cell_range(qy, box, y0, inv, ny)
    if ix0 <= ix1 and iy0 <= iy1:
        for ix in range(ix0, ix1 + 1):
            row = ix * ny
            for k in range(start[row + iy0], start[row + iy1 + 1]):
                dx = xy[k, 0] - qx
                dy = xy[k, 1] - qy
                d2 = dx * dx + dy * dy
                # the three nearest kept without a branch on which (a select each: the
                # comparisons' outcomes, unpredictable, cost more than the arithmetic);
                # nearer than the first: it goes first, the first second, the second third;
                # else nearer than the second: it goes second, the second third; else
                # nearer than the third: it goes third (the first of equal ones kept ahead)
                third_d2 = min(third_d2, max(d2, second_d2))
                is_first, is_second = d2 < first_d2, d2 < second_d2
                if is_second:  # (a select: both sides a value)
                    second = first if is_first else k
                    second_d2 = max(d2, first_d2)
                if is_first:
                    first = k
                first_d2 = min(first_d2, d2)
    clear = _clearance(qx, qy, ix0, ix1, iy0, iy1, frame)
    return first, first_d2, second, second_d2, third_d2, clear


@inlined
def nearest_bounded(
    qx: float,
    qy: float,
    radius: float,
    guess: float,
    geometry: FloatArray,
    shape: IntArray,
    start: IntArray,
    xy: FloatArray,
) -> tuple[int, float, int, float]:
    """:func:`nearest_in` the grid of ``geometry`` and ``shape``."""
    return nearest_in(qx, qy, radius, guess, frame_of(geometry, shape), start, xy)


@inlined
def frame_of(geometry: FloatArray, shape: IntArray) -> Frame:
    """A grid's geometry and shape as scalars: (x0, y0, 1/cell, cell, nx, ny)."""
    return geometry[0], geometry[1], geometry[2], geometry[3], shape[0], shape[1]


@inlined
def nearest_in(
    qx: float,
    qy: float,
    radius: float,
    guess: float,
    frame: Frame,
    start: IntArray,
    xy: FloatArray,
) -> tuple[int, float, int, float]:
    """The nearest point to ``(qx, qy)`` (−1 where none was looked at) and its squared
    distance: :func:`nearest`'s point (the first of equal ones in the grid's order) where
    that is below ``radius``² (else every point lies at least ``radius`` away); the next
    nearest point it looked at (−1: none) and a lower bound on the distance to every point
    but those two. While the query stays nearer to one of the two than that bound less how
    far it moved, the nearer of them is its nearest. ``guess`` (∞: none), the distance to
    some point, bounds the search where it lies within ``radius``: the cells within twice
    that (at least half a cell). Else the cells within half a cell side first (a point next
    to a surface lies that near to it) and, only where their nearest might not be the
    nearest of all, all within ``radius``. ``frame``: :func:`frame_of` the grid (scalars, which
    an inlined call does not count references of, as it does an array's)."""
    side = frame[3]
    box = min(radius, max(2.0 * guess, 0.5 * side)) if guess < radius else min(radius, 0.5 * side)
    first, d2, second, _d2, third, clear = _scan_box_near(qx, qy, box, frame, start, xy)
    if box < radius and not d2 < clear * clear:
        first, d2, second, _d2, third, clear = _scan_box_near(qx, qy, radius, frame, start, xy)
    far = min(math.sqrt(third), clear)
    if not d2 < radius * radius:  # every point lies at least the radius away
        far = max(far, radius)
    return first, d2, second, far
