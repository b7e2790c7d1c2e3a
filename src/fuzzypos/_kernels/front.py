"""The front of feature extraction (§3.1–3.5 up to the line fits) as one compiled call: the
scan's usable points, gap thresholds, detection angles (eq. 3), point uncertainty (eq. 4 by
the rule base's bilinear interpolation), filtering (§3.1), break points (eq. 13), clusters
(§3.3), angular points (eq. 14) and segment ids, each through the stage kernels of
``_kernels.segmentation`` and ``_kernels.fuzzy``; a gapless 360° ring's seam at its sharpest
corner. Its reference is the staged chain in numpy (``segment_scan`` of
``tests/oracles/features.py``); here the stages follow each other without returning to
Python in between. The angles are libm's ``atan2``, which may differ from numpy's
``arctan2`` (SIMD) in the last bit: the two agree except at exact ties."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from ._jit import inlined, kernel
from ._select import kth_smallest
from .fuzzy import bilinear
from .segmentation import (
    break_points,
    break_points_of_steps,
    clusters,
    corner_arms,
    detection_terms,
    finish_lines,
    join_at_corners,
    segment_sums,
    segments,
    sharpest_of_runs,
    steps,
)

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]

#: ``params`` of :func:`scan_front`, in order
PARAMS = (
    "gap_distance",
    "gap_distance_per_metre",
    "gap_difference",
    "detection_angle_threshold",
    "min_cluster_points",
    "neighbour_distance",
    "neighbour_step",
    "interior_angle_threshold",
    "corner_exclusion",
    "distance_scale_reference",
    "distance_scale_quantile",
    "scan_scale",
)


@kernel
def beam_directions(angles: FloatArray) -> FloatArray:
    """The cosine and sine of each beam's bearing, a (2, n) table: the same for every scan of
    one scanner (``angle_min``, ``angle_increment`` and the beam count), so computed once."""
    n = angles.shape[0]
    out = np.empty((2, n))
    for i in range(n):
        out[0, i] = math.cos(angles[i])
        out[1, i] = math.sin(angles[i])
    return out


@kernel
def valid_points(
    ranges: FloatArray,
    angles: FloatArray,
    valid: BoolArray,
    band_lo: FloatArray,
    band_hi: FloatArray,
    angle_increment: float,
    sensor_pose: FloatArray,
) -> tuple[IntArray, FloatArray, FloatArray, FloatArray]:
    """The oracle's ``_valid_points``: the beams that are valid and in no "no return" band
    (``scan.usable``), counter-clockwise; their indices, ranges, points in the sensor and in
    the robot frame (moved by ``sensor_pose``)."""
    return usable_points(
        ranges, beam_directions(angles), valid, band_lo, band_hi, angle_increment,
        sensor_pose[0], sensor_pose[1], sensor_pose[2],
    )  # fmt: skip


@kernel
def usable_points(
    ranges: FloatArray,
    directions: FloatArray,
    valid: BoolArray,
    band_lo: FloatArray,
    band_hi: FloatArray,
    angle_increment: float,
    sensor_x: float,
    sensor_y: float,
    sensor_theta: float,
) -> tuple[IntArray, FloatArray, FloatArray, FloatArray]:
    """:func:`valid_points` with the beams' :func:`beam_directions` and the sensor's pose on
    the robot as three numbers."""
    n = ranges.shape[0]
    keep = np.empty(n, dtype=np.bool_)
    count = 0
    for i in range(n):
        ok = valid[i]
        if ok:
            r = ranges[i]
            for b in range(band_lo.shape[0]):
                if band_lo[b] <= r <= band_hi[b]:
                    ok = False
                    break
        keep[i] = ok
        count += ok
    index = np.empty(count, dtype=np.int64)
    k = 0
    for i in range(n):
        if keep[i]:
            index[k] = i
            k += 1
    if angle_increment < 0:
        index = index[::-1].copy()
    r = np.empty(count)
    p_sensor = np.empty((count, 2))
    for k in range(count):
        i = index[k]
        r[k] = ranges[i]
        p_sensor[k, 0] = ranges[i] * directions[0, i]
        p_sensor[k, 1] = ranges[i] * directions[1, i]
    if sensor_x == 0.0 and sensor_y == 0.0 and sensor_theta == 0.0:
        return index, r, p_sensor, p_sensor
    c, s = math.cos(sensor_theta), math.sin(sensor_theta)
    points = np.empty((count, 2))
    for k in range(count):
        x, y = p_sensor[k, 0], p_sensor[k, 1]
        points[k, 0] = sensor_x + c * x - s * y
        points[k, 1] = sensor_y + s * x + c * y
    return index, r, p_sensor, points


@kernel
def distance_scale(ranges: FloatArray, reference: float, quantile: float) -> float:
    """``segmentation.distance_scale`` with ``distance_scale = "scan"``."""
    n = ranges.shape[0]
    if n == 0:
        return 1.0
    k = min(math.ceil(quantile * (n - 1)) + 1, n - 1)
    within = 0
    for i in range(n):
        within += ranges[i] <= reference
    if within >= k + 1:
        return 1.0
    # np.quantile's linear interpolation between two order statistics (numba's own
    # np.quantile and np.sort take seconds to compile)
    h = quantile * (n - 1)
    j = int(math.floor(h))  # noqa: RUF046 (numba: an int64 for the index)
    t = h - j
    a = kth_smallest(ranges, j)
    if t == 0.0 or j + 1 >= n:
        return max(1.0, a / reference)
    b = kth_smallest(ranges, j + 1)
    q = a + (b - a) * t if t < 0.5 else b - (b - a) * (1.0 - t)
    return float(max(1.0, q / reference))


@kernel
def _sorted(values: FloatArray) -> FloatArray:
    """``np.sort`` of a float array without NaN: a natural merge sort (the runs of a scan's
    ranges along a wall, falling ones turned around, merged in pairs), about twice as fast
    as a heapsort on a scan's ranges (whose comparisons the processor cannot foresee)."""
    n = values.shape[0]
    a: FloatArray = values.copy()
    if n < 2:
        return a
    bounds = np.empty(n + 1, dtype=np.int64)  # where each run starts, then n
    runs, i = 0, 0
    while i < n:
        j = i + 1
        if j < n and a[j] < a[i]:  # a falling run, turned around
            while j < n and a[j] < a[j - 1]:
                j += 1
            lo, hi = i, j - 1
            while lo < hi:
                a[lo], a[hi] = a[hi], a[lo]
                lo += 1
                hi -= 1
        else:
            while j < n and a[j] >= a[j - 1]:
                j += 1
        bounds[runs] = i
        runs += 1
        i = j
    bounds[runs] = n
    src, dst = a, np.empty(n)
    while runs > 1:  # merge the runs in pairs, from one buffer into the other
        merged = 0
        for r in range(0, runs, 2):
            lo, mid = bounds[r], bounds[r + 1]
            hi = bounds[r + 2] if r + 1 < runs else mid
            i, j, t = lo, mid, lo
            while i < mid and j < hi:
                if src[j] < src[i]:
                    dst[t] = src[j]
                    j += 1
                else:
                    dst[t] = src[i]
                    i += 1
                t += 1
            while i < mid:
                dst[t] = src[i]
                i += 1
                t += 1
            while j < hi:
                dst[t] = src[j]
                j += 1
                t += 1
            bounds[merged] = lo
            merged += 1
        bounds[merged] = n
        runs = merged
        src, dst = dst, src
    return src


@kernel
def interior_angles(
    cross: FloatArray, dot: FloatArray, inside: BoolArray, threshold: float
) -> FloatArray:
    """Eq. 14's interior angles |atan2(cross, dot)| of the points ``inside`` their clusters, π
    outside; π also where the angle is surely wider than ``threshold``: its cosine below the
    threshold's by 1e-6, the angle then wider by as much (arccos is at least that steep), far
    beyond atan2's rounding. Only whether an angle is within the threshold, and which is the
    sharpest of those, matters (``sharpest_of_runs``), and most points lie along walls (near
    π), where atan2 would cost the most of this."""
    n = cross.shape[0]
    wider = math.cos(threshold) - 1e-6
    angle = np.empty(n)
    for j in range(n):
        x, y = dot[j], cross[j]
        if not inside[j] or x < wider * math.sqrt(x * x + y * y):
            angle[j] = math.pi
        else:
            angle[j] = abs(math.atan2(y, x))
    return angle


@inlined
def sharpest_ring_corner(points: FloatArray, k: int, threshold: float) -> tuple[int, bool]:
    """For a gapless 360° ring of points: the index of its sharpest angular point (eq. 14 with
    neighbours ``k`` steps away, modulo the ring; the first of equals) and whether it is
    sharp enough (within ``threshold``) to be one."""
    n = points.shape[0]
    if n < 2 * k + 1:
        return 0, False
    best, best_angle = 0, math.inf
    for i in range(n):
        p, q = (i - k) % n, (i + k) % n
        ax, ay = points[p, 0] - points[i, 0], points[p, 1] - points[i, 1]
        bx, by = points[q, 0] - points[i, 0], points[q, 1] - points[i, 1]
        angle = abs(math.atan2(ax * by - ay * bx, ax * bx + ay * by))
        if angle < best_angle or (math.isnan(angle) and not math.isnan(best_angle)):
            best, best_angle = i, angle
    return best, bool(best_angle <= threshold)


@kernel
def scan_front(
    p_sensor: FloatArray,
    points: FloatArray,
    ranges: FloatArray,
    angle_increment: float,
    closed: bool,
    params: FloatArray,
    g1: FloatArray,
    g2: FloatArray,
    table: FloatArray,
    lo: float,
    hi: float,
) -> tuple[
    float, FloatArray, FloatArray, BoolArray, IntArray, BoolArray, BoolArray, IntArray,
    BoolArray, IntArray, IntArray, bool,
]:  # fmt: skip
    """Steps 1–5 of ``extract_features`` and the segment ids of step 6 (``params`` as
    :data:`PARAMS`; ``scan_scale`` 1: the distance scale of the scan's ranges, 0: fixed;
    ``g1``–``hi`` the point rule base's interpolation, :func:`~.fuzzy.bilinear`, or, where
    ``g1`` is empty, a rule base of another kind, whose grades the caller computes: then the
    uncertainty is zeros). Returns the distance scale, β, the uncertainty, the kept mask,
    the kept indices (in the order of the sequence), the break points, the field of view's
    edges, the clusters, the angular points, the raw and line segment ids and whether the
    scan is a gapless ring whose seam sits on its sharpest corner."""
    gap_distance, per_metre, gap_difference = params[0], params[1], params[2]
    n = ranges.shape[0]
    scale = 1.0
    if params[11] != 0.0:
        scale = distance_scale(ranges, params[9], params[10])
    t2_valid = np.empty(n)
    spacing = per_metre * abs(angle_increment)
    for i in range(n):
        t2_valid[i] = max(gap_distance, spacing * ranges[i])
    # 1. gaps among the valid points, then β (eq. 3), then 2. uncertainty (eq. 4)
    _, gap_after = break_points(p_sensor, t2_valid, gap_difference, closed)
    cross, dot, isolated = detection_terms(p_sensor, gap_after, closed)
    beta = np.empty(n)
    for i in range(n):
        beta[i] = 0.0 if isolated[i] else math.atan2(cross[i], dot[i])
    # (the ranges themselves at a scale of 1: r / 1 is r, and no array to allocate)
    u = np.zeros(n)
    if g1.shape[0]:
        u = bilinear(ranges if scale == 1.0 else ranges / scale, beta, g1, g2, table, lo, hi)
    # 3. filtering (§3.1)
    kept = beta > params[3]
    kept_index = np.nonzero(kept)[0]
    kp = points[kept_index]
    t2 = t2_valid[kept_index]
    # 4. break points (eq. 13) and clusters (§3.3) on the filtered points
    kp_steps = steps(kp, closed)  # (also the arms' spacing below, where the scan is open)
    is_break, split = break_points_of_steps(kp_steps, t2, gap_difference, closed)
    m = kept_index.shape[0]
    ring_corner = False
    if closed and m:
        # a 360° scan wraps around (the paper's "indices additive modulo m"): start the
        # sequence after a gap, or, with no gap at all, at the sharpest corner of the ring
        first = -1
        for j in range(m):
            if split[j]:
                first = j + 1
                break
        if first < 0:
            first, ring_corner = sharpest_ring_corner(kp, int(params[6]), params[7])
        order = np.empty(m, dtype=np.int64)
        for j in range(m):
            order[j] = (j + first) % m
        kept_index, kp = kept_index[order], kp[order]
        is_break, split = is_break[order], split[order]
        split[m - 1] = True
    fov_edge = np.zeros(m, dtype=np.bool_)
    if m and not closed:
        fov_edge[0] = True
        fov_edge[m - 1] = True
    cluster = clusters(split, int(params[4]))
    # 5. angular points (eq. 14)
    # (kp turned to the seam; ``not closed``, False there, typed a bool: a literal False would
    # compile ``steps`` once more)
    arm_spacing = kp_steps if not closed else steps(kp, not closed)
    arms_cross, arms_dot, inside = corner_arms(kp, cluster, arm_spacing, params[5], int(params[6]))
    angle = interior_angles(arms_cross, arms_dot, inside, params[7])
    is_corner = sharpest_of_runs(angle, cluster, params[7])
    if ring_corner and m and cluster[0] >= 0:
        is_corner[0] = True  # the seam of a gapless ring sits on its sharpest corner
    # 6. the segments lines are fitted to (§3.5)
    raw_seg, segment = segments(cluster, is_corner, int(params[8]), ring_corner)
    return (
        scale, beta, u, kept, kept_index, is_break, fov_edge, cluster, is_corner, raw_seg,
        segment, ring_corner,
    )  # fmt: skip


@kernel
def line_distance_scale(
    line_ranges: FloatArray, point_scale: float, reference: float, quantile: float
) -> float:
    """``segmentation.line_distance_scale`` with ``line_distance_scale = "structure"``: the
    quantile of the lines' points' ranges weighted by range, over the reference, at least
    ``point_scale``."""
    n = line_ranges.shape[0]
    if n == 0:
        return point_scale
    # sorted only where it is needed: not where the farthest range (the sorted ranges' last)
    # is within the reference's stretch, nor where the ranges under it (less a margin) weigh
    # more than the quantile's target by far more than the sums' rounding (the target is then
    # reached before the first range past the stretch: the scale is the points')
    stretch = reference * point_scale
    under = stretch * (1.0 - 1e-6)
    farthest, total, below, top_below = line_ranges[0], 0.0, 0.0, 0.0
    for i in range(n):
        v = line_ranges[i]
        farthest = max(farthest, v)
        total += v
        if v < under:
            below += v
            top_below = max(top_below, v)
    if farthest <= stretch:
        return point_scale
    if below - 0.5 * top_below > quantile * total * (1.0 + 1e-6):  # w at the last range under
        return point_scale
    r = _sorted(line_ranges)
    # the weighted quantile: the range where the cumulative weight (midpoint rule) reaches q,
    # interpolated as np.interp does (loops: numba's cumsum and interp are slow to compile)
    w = np.empty(n)
    acc = 0.0
    for i in range(n):
        acc += r[i]
        w[i] = acc - 0.5 * r[i]
    target = quantile * acc
    if target <= w[0]:
        q = r[0]
    elif target >= w[n - 1]:
        q = r[n - 1]
    else:
        j = 0
        while w[j + 1] <= target:
            j += 1
        q = (r[j + 1] - r[j]) / (w[j + 1] - w[j]) * (target - w[j]) + r[j]
    return float(max(point_scale, q / reference))


@kernel
def fit_lines(
    points: FloatArray,
    ranges: FloatArray,
    beta: FloatArray,
    uncertainty: FloatArray,
    segment: IntArray,
    point_scale: float,
    params: FloatArray,
    point_tables: tuple[FloatArray, FloatArray, FloatArray, float, float],
    line_tables: tuple[FloatArray, FloatArray, FloatArray, float, float],
) -> tuple[float, FloatArray, IntArray, FloatArray, IntArray, FloatArray]:
    """Step 6 of ``extract_features`` on the kept points: the scale the lines are graded on
    (``segmentation.line_distance_scale``; ``params[3]`` 0: the points' own), the points'
    uncertainty re-graded on it (eq. 4; ``uncertainty`` itself where the scale is the
    points'), then the total-least-squares lines (eq. 5–8, ``segment_sums`` and
    ``finish_lines``) and their uncertainty (eq. 9). ``params``: (min_points, min_length,
    min_noise, structure scale on, reference, quantile). Returns the scale, the
    uncertainties, the kept segment ids, ``finish_lines``'s table, each line's first point
    and its uncertainty (zeros where ``line_tables``' grids are empty: a rule base of another
    kind, which the caller evaluates; the point rule base's must then not be needed, the
    lines graded on ``point_scale``)."""
    line_scale = point_scale
    if params[3] != 0.0:
        count = 0
        for i in range(segment.shape[0]):
            count += segment[i] >= 0
        used = np.empty(count)
        k = 0
        for i in range(segment.shape[0]):
            if segment[i] >= 0:
                used[k] = ranges[i]
                k += 1
        line_scale = line_distance_scale(used, point_scale, params[4], params[5])
    lu = uncertainty
    if line_scale != point_scale and ranges.shape[0]:
        g1, g2, table, lo, hi = point_tables
        lu = bilinear(ranges / line_scale, beta, g1, g2, table, lo, hi)
    sums, first, last = segment_sums(points, lu, segment)
    nseg = sums.shape[0]
    normal = np.empty((nseg, 2))
    for s in range(nseg):  # the principal direction φ of each scatter
        phi = 0.5 * math.atan2(2.0 * sums[s, 5], sums[s, 3] - sums[s, 4])
        normal[s, 0], normal[s, 1] = -math.sin(phi), math.cos(phi)
    ids, out, firsts = finish_lines(
        points, segment, sums, first, last, normal, int(params[0]), params[1], params[2]
    )
    f_line = np.zeros(ids.shape[0])
    g1, g2, table, lo, hi = line_tables
    if ids.shape[0] and g1.shape[0]:  # (no grids: the caller's rule base grades them)
        f_line = bilinear(out[:, 8].copy(), out[:, 7].copy(), g1, g2, table, lo, hi)
    return line_scale, lu, ids, out, firsts, f_line


@kernel
def _corners(
    is_corner: BoolArray,
    raw: IntArray,
    normal: FloatArray,
    distance: FloatArray,
    start: FloatArray,
    end: FloatArray,
    ids: IntArray,
    min_sine: float,
) -> tuple[
    IntArray, IntArray, IntArray, FloatArray, BoolArray, IntArray, IntArray, FloatArray,
    FloatArray, FloatArray,
]:  # fmt: skip
    """:func:`scan_features`' angular points (``is_corner`` of the kept points, ``raw`` their
    raw segment ids) and the lines on either side of each (circularly, for the ring's seam),
    joined by ``_kernels.segmentation.join_at_corners`` (§3.5 b)): the angular points'
    indices, the segments before and after each, their intersections, which were joined,
    the joined ones' two lines and d_v, and the lines' start and end points."""
    m, n_lines = is_corner.shape[0], ids.shape[0]
    n_corners = 0
    for j in range(m):
        n_corners += is_corner[j]
    corner_index = np.empty(n_corners, dtype=np.int64)
    before, after = np.empty(n_corners, dtype=np.int64), np.empty(n_corners, dtype=np.int64)
    c = 0
    wrap = max(m, 1)
    for j in range(m):
        if is_corner[j]:
            corner_index[c] = j
            before[c], after[c] = raw[(j - 1) % wrap], raw[(j + 1) % wrap]
            c += 1
    corner_xy = np.full((n_corners, 2), np.nan)
    joined = np.zeros(n_corners, dtype=np.bool_)
    corner_a, corner_b = np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    corner_dv = np.zeros(0)
    if n_corners and n_lines >= 2:
        have, new_start, new_end, _centre, xy, ok, ia, ib, dv = join_at_corners(
            normal, distance, start, end, ids, before, after, min_sine
        )
        corner_xy, joined = xy, ok
        if have:
            start, end = new_start, new_end
            corner_a, corner_b, corner_dv = ia, ib, dv
    return corner_index, before, after, corner_xy, joined, corner_a, corner_b, corner_dv, start, end


@kernel
def _floats(
    points: FloatArray,
    rng: FloatArray,
    beta: FloatArray,
    u: FloatArray,
    kp: FloatArray,
    ku: FloatArray,
    kr: FloatArray,
    normal: FloatArray,
    distance: FloatArray,
    start: FloatArray,
    end: FloatArray,
    lt: FloatArray,
    f_line: FloatArray,
    corner_xy: FloatArray,
    corner_dv: FloatArray,
) -> FloatArray:
    """:func:`scan_features`' floats end to end: points (n, 2), ranges, β, uncertainty; the
    kept points (m, 2), their uncertainty and ranges; the lines' normal (L, 2), distance,
    start (L, 2), end (L, 2), centre (L, 2), σ, δ, uncertainty, angle and distance variance
    (``lt``: ``finish_lines``' table) and the length (``Lines.length``, for line matching:
    libm's ``hypot``, numpy's too; the normal's angle is left to numpy, whose ``arctan2`` is
    not libm's); the angular points' intersections (C, 2) and the joined ones' d_v."""
    n, m, nl = rng.shape[0], ku.shape[0], f_line.shape[0]
    n_corners, n_joined = corner_xy.shape[0], corner_dv.shape[0]
    fl = np.empty(5 * n + 4 * m + 15 * nl + 2 * n_corners + n_joined)
    for i in range(n):
        fl[2 * i], fl[2 * i + 1] = points[i, 0], points[i, 1]
        fl[2 * n + i], fl[3 * n + i], fl[4 * n + i] = rng[i], beta[i], u[i]
    o = 5 * n
    for j in range(m):
        fl[o + 2 * j], fl[o + 2 * j + 1] = kp[j, 0], kp[j, 1]
        fl[o + 2 * m + j], fl[o + 3 * m + j] = ku[j], kr[j]
    o += 4 * m
    for k in range(nl):
        fl[o + 2 * k], fl[o + 2 * k + 1] = normal[k, 0], normal[k, 1]
        fl[o + 2 * nl + k] = distance[k]
        fl[o + 3 * nl + 2 * k], fl[o + 3 * nl + 2 * k + 1] = start[k, 0], start[k, 1]
        fl[o + 5 * nl + 2 * k], fl[o + 5 * nl + 2 * k + 1] = end[k, 0], end[k, 1]
        fl[o + 7 * nl + 2 * k] = 0.5 * (start[k, 0] + end[k, 0])
        fl[o + 7 * nl + 2 * k + 1] = 0.5 * (start[k, 1] + end[k, 1])
        fl[o + 9 * nl + k], fl[o + 10 * nl + k] = lt[k, 7], lt[k, 8]
        fl[o + 11 * nl + k] = f_line[k]
        fl[o + 12 * nl + k], fl[o + 13 * nl + k] = lt[k, 9], lt[k, 10]
        fl[o + 14 * nl + k] = math.hypot(end[k, 0] - start[k, 0], end[k, 1] - start[k, 1])
    o += 15 * nl
    for c in range(n_corners):
        fl[o + 2 * c], fl[o + 2 * c + 1] = corner_xy[c, 0], corner_xy[c, 1]
    o += 2 * n_corners
    for c in range(n_joined):
        fl[o + c] = corner_dv[c]
    return fl


#: :func:`scan_features`' sizes: the valid points, the kept points, the lines, the angular
#: points and the joined ones
ChainSizes = tuple[int, int, int, int, int]


#: a rule base's tables: its two inputs' grids, its table and its output's bounds
Tables = tuple[FloatArray, FloatArray, FloatArray, float, float]


@kernel
def settings_of(
    settings: FloatArray,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, float, Tables, Tables]:
    """The arrays of ``fuzzypos._kernels.packing.chain_settings`` (views of it): the
    no-return bands' lower and upper bounds, :func:`scan_front`'s params (:data:`PARAMS`),
    :func:`fit_lines`' params, the sine of the least angle lines are joined at and the point
    and line rule bases' tables."""
    s = settings
    n_bands = int(s[0])
    pg1, pg2, pr, pc = int(s[1]), int(s[2]), int(s[3]), int(s[4])
    lg1, lg2, lr, lc = int(s[5]), int(s[6]), int(s[7]), int(s[8])
    o = 14
    front_params, line_params = s[o : o + 12], s[o + 12 : o + 18]
    o += 18
    band_lo, band_hi = s[o : o + n_bands], s[o + n_bands : o + 2 * n_bands]
    o += 2 * n_bands
    point_tables = (
        s[o : o + pg1], s[o + pg1 : o + pg1 + pg2],
        s[o + pg1 + pg2 : o + pg1 + pg2 + pr * pc].reshape((pr, pc)), s[9], s[10],
    )  # fmt: skip
    o += pg1 + pg2 + pr * pc
    line_tables = (
        s[o : o + lg1], s[o + lg1 : o + lg1 + lg2],
        s[o + lg1 + lg2 : o + lg1 + lg2 + lr * lc].reshape((lr, lc)), s[11], s[12],
    )  # fmt: skip
    return band_lo, band_hi, front_params, line_params, s[13], point_tables, line_tables


@kernel
def scan_features(
    ranges: FloatArray,
    directions: FloatArray,
    valid: BoolArray,
    angle_increment: float,
    sensor_x: float,
    sensor_y: float,
    sensor_theta: float,
    closed: bool,
    settings: FloatArray,
) -> tuple[float, float, ChainSizes, FloatArray, IntArray, BoolArray]:
    """The whole compiled chain of ``fuzzypos.features.extract_features`` in one call (``settings``:
    the config's, ``fuzzypos._kernels.packing.chain_settings``, as :func:`settings_of` takes them
    apart; the sensor's pose on the robot as three numbers): :func:`usable_points` (``directions``:
    the beams' :func:`beam_directions`), :func:`scan_front`, the kept points, :func:`fit_lines` and
    the lines' arrays (``features._lines_of_table``), the lines on either side of each angular point
    and ``_kernels.segmentation.join_at_corners`` (§3.5 b)), with nothing but glue between them
    (what ``extract_features`` did in numpy between the four calls; a gapless 360° ring too, its
    seam at its sharpest corner). Returns the points' and the lines' distance scales, the
    :data:`ChainSizes` and the arrays packed end to end in three (few arrays to hand back to
    Python): the floats, the integers and the masks, in the order ``features._unpacked`` takes them
    apart (the front's arrays, as ``segmentation.ScanSegments`` without the raw segments; the kept
    points, uncertainty and ranges; the arrays of ``features.Lines``, joined at the corners; the
    corners' context, ``features._CornerContext``)."""
    config = settings_of(settings)
    band_lo, band_hi, front_params, line_params, min_sine, point_tables, line_tables = config
    beam_index, rng, p_sensor, points = usable_points(
        ranges, directions, valid, band_lo, band_hi, angle_increment, sensor_x, sensor_y,
        sensor_theta,
    )  # fmt: skip
    g1, g2, table, lo, hi = point_tables
    scale, beta, u, kept, kept_index, is_break, fov_edge, cluster, is_corner, raw, seg, _ = (
        scan_front(p_sensor, points, rng, angle_increment, closed, front_params, g1, g2, table,
                   lo, hi)
    )  # fmt: skip
    n, m = rng.shape[0], kept_index.shape[0]
    kp, ku = np.empty((m, 2)), np.empty(m)
    kr, kb = np.empty(m), np.empty(m)
    for j in range(m):
        i = kept_index[j]
        kp[j, 0], kp[j, 1] = points[i, 0], points[i, 1]
        ku[j], kr[j], kb[j] = u[i], rng[i], beta[i]
    line_scale, _lu, ids, lt, firsts, f_line = fit_lines(
        kp, kr, kb, ku, seg, scale, line_params, point_tables, line_tables
    )
    # the lines' arrays (``features._lines_of_table``)
    n_lines = ids.shape[0]
    normal, distance = np.empty((n_lines, 2)), np.empty(n_lines)
    start, end = np.empty((n_lines, 2)), np.empty((n_lines, 2))
    for k in range(n_lines):
        normal[k, 0], normal[k, 1], distance[k] = lt[k, 0], lt[k, 1], lt[k, 2]
        start[k, 0], start[k, 1], end[k, 0], end[k, 1] = lt[k, 3], lt[k, 4], lt[k, 5], lt[k, 6]
    corner_index, before, after, corner_xy, joined, corner_a, corner_b, corner_dv, start, end = (
        _corners(is_corner, raw, normal, distance, start, end, ids, min_sine)
    )
    nl, n_corners, n_joined = n_lines, corner_index.shape[0], corner_a.shape[0]
    fl = _floats(points, rng, beta, u, kp, ku, kr, normal, distance, start, end, lt, f_line,
                 corner_xy, corner_dv)  # fmt: skip
    # the integers: beam indices; kept indices, clusters and segment ids; the lines' point
    # counts, segment ids and clusters; the angular points' indices and the segments before
    # and after each; the joined ones' two lines
    it = np.empty(n + 3 * m + 3 * nl + 3 * n_corners + 2 * n_joined, dtype=np.int64)
    for i in range(n):
        it[i] = beam_index[i]
    o = n
    for j in range(m):
        it[o + j], it[o + m + j], it[o + 2 * m + j] = kept_index[j], cluster[j], seg[j]
    o += 3 * m
    for k in range(nl):
        it[o + k], it[o + nl + k] = int(lt[k, 11]), ids[k]
        it[o + 2 * nl + k] = cluster[firsts[k]]
    o += 3 * nl
    for c in range(n_corners):
        it[o + c], it[o + n_corners + c] = corner_index[c], before[c]
        it[o + 2 * n_corners + c] = after[c]
    o += 3 * n_corners
    for c in range(n_joined):
        it[o + c], it[o + n_joined + c] = corner_a[c], corner_b[c]
    # the masks: kept; break points, field-of-view edges, angular points and break point
    # features of the kept points; the joined angular points
    bl = np.empty(n + 4 * m + n_corners, dtype=np.bool_)
    for i in range(n):
        bl[i] = kept[i]
    o = n
    for j in range(m):
        bl[o + j], bl[o + m + j], bl[o + 2 * m + j] = is_break[j], fov_edge[j], is_corner[j]
        bl[o + 3 * m + j] = is_break[j] and not fov_edge[j] and cluster[j] >= 0
    o += 4 * m
    for c in range(n_corners):
        bl[o + c] = joined[c]
    return scale, line_scale, (n, m, nl, n_corners, n_joined), fl, it, bl
