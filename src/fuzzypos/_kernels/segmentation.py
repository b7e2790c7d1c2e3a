"""The segmentation stages as compiled loops over a scan's points (the references: the numpy
functions of ``tests/oracles/features.py``): break points (eq. 13), detection angles (eq. 3),
clusters (§3.3), angular points (eq. 14), segments (§3.5), the lines' least-squares fits
(eq. 5–8) and their joins at angular points (§3.5 b)). The angles themselves (atan2, sin,
cos) are left to numpy between two kernels: libm's differ from numpy's in the last bit, which
would flip ties (two equally sharp corners) and make the two paths' features differ."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from ._jit import kernel

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]


@kernel
def steps(points: FloatArray, closed: bool) -> FloatArray:
    """The distance from each point to the next (the last: to the first if ``closed``, else
    inf)."""
    n = points.shape[0]
    d = np.empty(n)
    for i in range(n - 1):
        dx = points[i + 1, 0] - points[i, 0]
        dy = points[i + 1, 1] - points[i, 1]
        d[i] = math.sqrt(dx * dx + dy * dy)
    if n:
        last = math.hypot(points[0, 0] - points[-1, 0], points[0, 1] - points[-1, 1])
        d[n - 1] = last if closed else np.inf
    return d


@kernel
def break_points(
    points: FloatArray, thresholds: FloatArray, gap_difference: float, closed: bool
) -> tuple[BoolArray, BoolArray]:
    """Eq. 13 over an ordered sequence: ``(is_break_point, split)``, ``split[j]`` a cut between
    points j and j+1 (a step longer than its T2 and by T1 than a step beside it)."""
    return break_points_of_steps(steps(points, closed), thresholds, gap_difference, closed)


@kernel
def break_points_of_steps(
    step: FloatArray, thresholds: FloatArray, gap_difference: float, closed: bool
) -> tuple[BoolArray, BoolArray]:
    """:func:`break_points` of the sequence's :func:`steps` (``closed`` as they were taken)."""
    n = step.shape[0]
    split = np.zeros(n, dtype=np.bool_)
    for j in range(n):
        s = step[j]
        if not (s > thresholds[j] and np.isfinite(s)):
            continue
        # a missing neighbour step (past an open end) never makes a difference
        before = step[j - 1] if j > 0 else (step[n - 1] if closed else np.nan)
        after = step[j + 1] if j < n - 1 else (step[0] if closed else np.nan)
        if not closed and (j == n - 1 or not np.isfinite(after)):
            after = np.nan
        split[j] = (s - before > gap_difference) or (s - after > gap_difference)
    if n and not closed:
        split[n - 1] = True  # the end of the field of view
    is_break = np.empty(n, dtype=np.bool_)
    for j in range(n):
        prev = split[j - 1] if j > 0 else (split[n - 1] if closed else True)
        is_break[j] = split[j] or prev
    return is_break, split


@kernel
def detection_terms(
    points: FloatArray, gap_after: BoolArray, closed: bool
) -> tuple[FloatArray, FloatArray, BoolArray]:
    """For β (eq. 3): |beam × step| and |beam · step| of each point's step to its neighbour on
    the same surface (i+1, else i−1), and whether it has none (gaps on both sides: β = 0).
    β = atan2 of the two, which the caller takes with numpy's arctan2, as the reference does
    (libm's atan2 differs from it in the last bit, which flips ties)."""
    n = points.shape[0]
    cross, dot = np.empty(n), np.empty(n)
    isolated = np.zeros(n, dtype=np.bool_)
    for i in range(n):
        gap_before = gap_after[i - 1] if i > 0 else (gap_after[n - 1] if closed else True)
        isolated[i] = gap_after[i] and gap_before
        use_next = not gap_after[i] and (closed or i < n - 1)
        if use_next:
            k = i + 1 if i < n - 1 else 0
            sx, sy = points[k, 0] - points[i, 0], points[k, 1] - points[i, 1]
        elif i > 0 or closed:
            k = i - 1 if i > 0 else n - 1
            sx, sy = points[i, 0] - points[k, 0], points[i, 1] - points[k, 1]
        else:
            sx, sy = np.nan, np.nan
        bx, by = points[i, 0], points[i, 1]
        cross[i] = abs(bx * sy - by * sx)
        dot[i] = abs(bx * sx + by * sy)
    return cross, dot, isolated


@kernel
def clusters(split: BoolArray, min_points: int) -> IntArray:
    """§3.3: labels 0, 1, … of the runs between cuts (``split[j]``: after point j); −1 for a
    run of fewer than ``min_points``."""
    n = split.shape[0]
    label = np.full(n, -1, dtype=np.int64)
    next_id, first = 0, 0
    for i in range(n):
        if i == n - 1 or split[i]:  # a run ends at i
            if i + 1 - first >= min_points:
                label[first : i + 1] = next_id
                next_id += 1
            first = i + 1
    return label


@kernel
def _cluster_bounds(cluster: IntArray) -> tuple[IntArray, IntArray]:
    """The first and last index of each point's run of equal cluster labels."""
    n = cluster.shape[0]
    start, end = np.empty(n, dtype=np.int64), np.empty(n, dtype=np.int64)
    first = 0
    for i in range(n):
        if i > 0 and cluster[i] != cluster[i - 1]:
            first = i
        start[i] = first
    last = n - 1
    for i in range(n - 1, -1, -1):
        if i < n - 1 and cluster[i] != cluster[i + 1]:
            last = i
        end[i] = last
    return start, end


@kernel
def corner_arms(
    points: FloatArray,
    cluster: IntArray,
    step_spacing: FloatArray,
    neighbour_distance: float,
    neighbour_step: int,
) -> tuple[FloatArray, FloatArray, BoolArray]:
    """For eq. 14: the cross and dot products of the arms from each point to its k-step
    neighbours (k widened to ``neighbour_distance``, at most 4 × ``neighbour_step``, clipped
    at its cluster's ends), and whether the point is inside its cluster with both arms at
    least half that distance long. The interior angle is |atan2| of the two (numpy's, in the
    caller: see :func:`detection_terms`), π outside."""
    n = points.shape[0]
    start, end = _cluster_bounds(cluster)
    min_arm2 = (0.5 * neighbour_distance) * (0.5 * neighbour_distance)
    cross, dot = np.empty(n), np.empty(n)
    inside = np.empty(n, dtype=np.bool_)
    for i in range(n):
        wanted = math.ceil(neighbour_distance / max(step_spacing[i], 1e-9))
        k = int(min(max(wanted, neighbour_step), 4 * neighbour_step))
        lo, hi = max(i - k, start[i]), min(i + k, end[i])
        ax, ay = points[lo, 0] - points[i, 0], points[lo, 1] - points[i, 1]
        bx, by = points[hi, 0] - points[i, 0], points[hi, 1] - points[i, 1]
        inside[i] = (
            cluster[i] >= 0
            and lo < i < hi
            and ax * ax + ay * ay >= min_arm2
            and bx * bx + by * by >= min_arm2
        )
        cross[i] = ax * by - ay * bx
        dot[i] = ax * bx + ay * by
    return cross, dot, inside


@kernel
def sharpest_of_runs(angle: FloatArray, cluster: IntArray, threshold: float) -> BoolArray:
    """Eq. 14's corners: of each run of consecutive points of one cluster whose interior
    angle is at most ``threshold``, the first of the sharpest."""
    n = angle.shape[0]
    is_corner = np.zeros(n, dtype=np.bool_)
    i = 0
    while i < n:
        if not angle[i] <= threshold:
            i += 1
            continue
        best, j = i, i + 1  # a run: consecutive candidates of one cluster
        while j < n and angle[j] <= threshold and cluster[j] == cluster[j - 1]:
            if angle[j] < angle[best]:
                best = j
            j += 1
        is_corner[best] = True
        i = j
    return is_corner


@kernel
def segments(
    cluster: IntArray, is_corner: BoolArray, corner_exclusion: int, ring: bool
) -> tuple[IntArray, IntArray]:
    """§3.5: the raw segment id of each point (a new one at each cluster start and after each
    angular point) and the segment id used for line fits (−1 for a point of a dropped cluster,
    an angular point and its ``corner_exclusion`` neighbours, circularly for a ``ring``)."""
    n = cluster.shape[0]
    raw = np.empty(n, dtype=np.int64)
    count = -1
    for i in range(n):
        if i == 0 or cluster[i] != cluster[i - 1] or is_corner[i - 1]:
            count += 1
        raw[i] = count
    out = raw.copy()
    for i in range(n):
        if cluster[i] < 0:
            out[i] = -1
        if not is_corner[i]:
            continue
        out[i] = -1
        for s in range(1, corner_exclusion + 1):
            for j in (i - s, i + s):
                if ring:
                    out[j % n] = -1
                elif 0 <= j < n:
                    out[j] = -1
    return raw, out


@kernel
def segment_sums(
    points: FloatArray, uncertainty: FloatArray, segment: IntArray
) -> tuple[FloatArray, IntArray, IntArray]:
    """Eq. 5–6's sums per segment (ids non-decreasing, −1 unused), in the points' order (as
    ``np.bincount`` adds them): a (nseg, 7) table of (count, mean x, mean y, Σdx², Σdy²,
    Σdx·dy, Σu), and each segment's first and last point (−1: none)."""
    n = points.shape[0]
    nseg = 0
    for i in range(n):
        nseg = max(nseg, segment[i] + 1)
    t = np.zeros((nseg, 7))
    sx, sy = np.zeros(nseg), np.zeros(nseg)
    first, last = np.empty(nseg, dtype=np.int64), np.empty(nseg, dtype=np.int64)
    for s in range(nseg):
        first[s], last[s] = -1, -1
    for i in range(n):
        s = segment[i]
        if s < 0:
            continue
        t[s, 0] += 1.0
        sx[s] += points[i, 0]
        sy[s] += points[i, 1]
        t[s, 6] += uncertainty[i]
        if first[s] < 0:
            first[s] = i
        last[s] = i
    for s in range(nseg):
        safe = max(t[s, 0], 1.0)
        t[s, 1], t[s, 2] = sx[s] / safe, sy[s] / safe
    for i in range(n):
        s = segment[i]
        if s >= 0:
            dx, dy = points[i, 0] - t[s, 1], points[i, 1] - t[s, 2]
            t[s, 3] += dx * dx
            t[s, 4] += dy * dy
            t[s, 5] += dx * dy
    return t, first, last


@kernel
def finish_lines(
    points: FloatArray,
    segment: IntArray,
    sums: FloatArray,
    first: IntArray,
    last: IntArray,
    normal: FloatArray,
    min_points: int,
    min_length: float,
    min_noise: float,
) -> tuple[IntArray, FloatArray, IntArray]:
    """Eq. 5–8: the total-least-squares lines from :func:`segment_sums` and each segment's
    normal (−sin φ, cos φ) of its principal direction φ, turned to point away from the robot
    (d ≥ 0); those of at least ``min_points`` points spanning ``min_length``. Returns the
    kept segment ids, a (m, 12) table of (n_x, n_y, d, start x, y, end x, y, σ, δ, angle
    variance, distance variance, point count) and the index of each one's first point."""
    nseg = sums.shape[0]
    table = np.empty((nseg, 7))
    for s in range(nseg):
        nx, ny = normal[s, 0], normal[s, 1]
        d = nx * sums[s, 1] + ny * sums[s, 2]
        if d < 0:
            nx, ny, d = -nx, -ny, -d
        table[s, 0], table[s, 1], table[s, 2] = nx, ny, d
        for e in (3, 5):  # the extreme points projected on the line
            k = max(first[s] if e == 3 else last[s], 0)
            off = points[k, 0] * nx + points[k, 1] * ny - d
            table[s, e], table[s, e + 1] = points[k, 0] - off * nx, points[k, 1] - off * ny
    resid, resid2 = np.zeros(nseg), np.zeros(nseg)
    for i in range(points.shape[0]):
        s = segment[i]
        if s >= 0:
            r = abs(table[s, 0] * points[i, 0] + table[s, 1] * points[i, 1] - table[s, 2])
            resid[s] += r
            resid2[s] += r * r
    keep = np.zeros(nseg, dtype=np.bool_)
    m = 0
    for s in range(nseg):
        spx, spy = table[s, 5] - table[s, 3], table[s, 6] - table[s, 4]
        keep[s] = sums[s, 0] >= min_points and spx * spx + spy * spy >= min_length * min_length
        m += keep[s]
    ids, firsts, out = np.empty(m, dtype=np.int64), np.empty(m, dtype=np.int64), np.empty((m, 12))
    k = 0
    for s in range(nseg):
        if not keep[s]:
            continue
        c = sums[s, 0]
        s2 = max(resid2[s] / max(c - 2.0, 1.0), min_noise * min_noise)
        var_phi = s2 / max(sums[s, 3] + sums[s, 4] - resid2[s], 1e-12)
        along = sums[s, 1] * table[s, 1] - sums[s, 2] * table[s, 0]
        for e in range(7):
            out[k, e] = table[s, e]
        out[k, 7], out[k, 8] = resid[s] / c, sums[s, 6] / c  # eq. 8 (σ), eq. 6 (δ)
        out[k, 9], out[k, 10] = var_phi, s2 / c + var_phi * along * along
        out[k, 11] = c
        ids[k], firsts[k] = s, first[s]
        k += 1
    return ids, out, firsts


@kernel
def join_at_corners(
    normal: FloatArray,
    distance: FloatArray,
    start: FloatArray,
    end: FloatArray,
    segment: IntArray,
    before: IntArray,
    after: IntArray,
    min_sine: float,
) -> tuple[
    int, FloatArray, FloatArray, FloatArray, FloatArray, BoolArray, IntArray, IntArray, FloatArray
]:
    """§3.5 b), ``fuzzypos.features.extract.join_at_corners``: the lines (``segment`` their segment
    ids) on either side of each angular point (``before``/``after``: segment ids) that meet
    at least at ``min_sine`` are joined at their intersection (eq. 15–16 in normal form).
    Returns how many angular points have a line on both sides, the lines' new start and end
    points, per angular point the intersection and whether it was joined, and of the joined
    the two line indices and d_v (eq. 10)."""
    m, n_lines = before.shape[0], normal.shape[0]
    size = 0
    for k in range(n_lines):
        size = max(size, segment[k] + 1)
    for k in range(m):
        size = max(size, before[k] + 1, after[k] + 1)
    line_of = np.full(size, -1, dtype=np.int64)
    for k in range(n_lines):
        line_of[segment[k]] = k
    new_start, new_end = start.copy(), end.copy()
    xy = np.full((m, 2), np.nan)
    ok = np.zeros(m, dtype=np.bool_)
    ia, ib = np.empty(m, dtype=np.int64), np.empty(m, dtype=np.int64)
    px, py = np.empty(m), np.empty(m)
    have, joined = 0, 0
    for k in range(m):
        a, b = line_of[before[k]], line_of[after[k]]
        if a < 0 or b < 0:
            continue
        have += 1
        det = normal[a, 0] * normal[b, 1] - normal[a, 1] * normal[b, 0]
        if not abs(det) >= min_sine:
            continue
        safe = det if abs(det) > 1e-12 else 1.0
        x = (distance[a] * normal[b, 1] - distance[b] * normal[a, 1]) / safe
        y = (normal[a, 0] * distance[b] - normal[b, 0] * distance[a]) / safe
        new_end[a, 0], new_end[a, 1] = x, y
        new_start[b, 0], new_start[b, 1] = x, y
        xy[k, 0], xy[k, 1], ok[k] = x, y, True
        ia[joined], ib[joined], px[joined], py[joined] = a, b, x, y
        joined += 1
    centre = np.empty((n_lines, 2))
    for k in range(n_lines):
        centre[k, 0] = 0.5 * (new_start[k, 0] + new_end[k, 0])
        centre[k, 1] = 0.5 * (new_start[k, 1] + new_end[k, 1])
    dv = np.empty(joined)
    for k in range(joined):  # eq. 10: the mean distance to the two lines' centres
        a, b = ia[k], ib[k]
        dv[k] = 0.5 * (
            math.hypot(px[k] - centre[a, 0], py[k] - centre[a, 1])
            + math.hypot(px[k] - centre[b, 0], py[k] - centre[b, 1])
        )
    return have, new_start, new_end, centre, xy, ok, ia[:joined].copy(), ib[:joined].copy(), dv
