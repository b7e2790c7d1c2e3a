"""The numpy references of ``fuzzypos.features``' kernels (``_kernels.segmentation``,
``_kernels.front``): the code each replaced, the tests' oracles."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from fuzzypos.config import Config, FuzzyConfig
from fuzzypos.features import chain, extract, segmentation
from fuzzypos.features.chain import MIN_LINE_NOISE as _MIN_LINE_NOISE
from fuzzypos.features.extract import _empty_lines
from fuzzypos.features.segmentation import ScanSegments
from fuzzypos.features.types import (
    ANGULAR_POINT,
    BREAK_POINT,
    VIRTUAL_ANGULAR_POINT,
    FeaturePoints,
    Lines,
    _CornerContext,
    _PointFeatures,
)
from fuzzypos.fuzzy import RuleBases
from fuzzypos.geometry import stack_columns, transform_points
from fuzzypos.scan import LaserScan, usable
from oracles import _declines

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]


def steps(points: FloatArray, closed: bool) -> FloatArray:
    """:func:`_steps` in numpy (the compiled kernel's reference)."""
    n = points.shape[0]
    d = np.empty(n)
    if n == 0:
        return d
    diff = points[1:] - points[:-1]
    d[:-1] = np.sqrt(diff[:, 0] ** 2 + diff[:, 1] ** 2)
    d[-1] = np.hypot(*(points[0] - points[-1])) if closed else np.inf
    return d


def _shift_prev(a: NDArray, closed: bool, fill: object) -> NDArray:
    """``a[i-1]`` at i (wrapping when ``closed``, else ``fill`` at 0)."""
    out = np.empty_like(a)
    out[1:] = a[:-1]
    out[0] = a[-1] if closed else fill
    return out


def _shift_next(a: NDArray, closed: bool, fill: object) -> NDArray:
    """``a[i+1]`` at i (wrapping when ``closed``, else ``fill`` at the end)."""
    out = np.empty_like(a)
    out[:-1] = a[1:]
    out[-1] = a[0] if closed else fill
    return out


def break_points(
    points: FloatArray, thresholds: FloatArray, gap_difference: float, closed: bool = False
) -> tuple[BoolArray, BoolArray]:
    """:func:`break_points` in numpy (the compiled kernel's reference)."""
    n = points.shape[0]
    if n == 0:
        return np.zeros(0, bool), np.zeros(0, bool)
    # step j joins points j and j+1; it is a gap when longer than T2 and longer (by T1) than a
    # neighbouring step, so a uniformly sparse surface has no gaps (eq. 13)
    step = steps(points, closed)
    inner = step if closed else np.where(np.isfinite(step), step, np.nan)  # no step past the end
    before = _shift_prev(inner, closed, np.nan)
    after = _shift_next(inner, closed, np.nan)
    # (nan marks a missing neighbour; inf − nan is nan and compares False, without a warning)
    differ = (step - before > gap_difference) | (step - after > gap_difference)
    split = (step > thresholds) & differ & np.isfinite(step)
    if not closed:
        split[-1] = True  # the end of the field of view
    is_break = split | _shift_prev(split, closed, True)  # both points that border a gap
    return is_break, split


def detection_angles(
    points_sensor: FloatArray, gap_after: BoolArray, closed: bool = False
) -> FloatArray:
    """:func:`detection_angles` in numpy (the compiled kernel's reference)."""
    n = points_sensor.shape[0]
    if n == 0:
        return np.zeros(0)
    nxt = _shift_next(points_sensor, closed, np.nan)
    prv = _shift_prev(points_sensor, closed, np.nan)
    gap_before = _shift_prev(gap_after, closed, True)
    use_next = ~gap_after
    if not closed:
        use_next[-1] = False  # the last point of an open scan has no i+1
    step = np.where(use_next[:, None], nxt - points_sensor, points_sensor - prv)
    beam = points_sensor
    cross = np.abs(beam[:, 0] * step[:, 1] - beam[:, 1] * step[:, 0])
    dot = np.abs(beam[:, 0] * step[:, 0] + beam[:, 1] * step[:, 1])
    beta = np.arctan2(cross, dot)  # folded: both |·| put it in [0, π/2]
    isolated = gap_after & gap_before
    return np.where(isolated, 0.0, beta)


def clusters(split: BoolArray, min_points: int) -> IntArray:
    """:func:`clusters` in numpy (the compiled kernel's reference)."""
    n = split.shape[0]
    if n == 0:
        return np.zeros(0, dtype=np.int64)
    starts = np.empty(n, bool)
    starts[0] = True
    starts[1:] = split[:-1]
    label = _running_count(starts) - 1
    size = np.bincount(label)
    ok = size >= min_points
    new_id = _running_count(ok) - 1
    return np.where(ok[label], new_id[label], -1).astype(np.int64)


def angular_points(
    points: FloatArray, cluster: IntArray, step_spacing: FloatArray, cfg: Config
) -> tuple[BoolArray, FloatArray]:
    """:func:`angular_points` in numpy (the compiled kernel's reference)."""
    n = points.shape[0]
    if n == 0:
        return np.zeros(0, bool), np.zeros(0)
    ap = cfg.angular_points
    wanted = np.ceil(ap.neighbour_distance / np.maximum(step_spacing, 1e-9))
    k = np.minimum(np.maximum(wanted, ap.neighbour_step), 4 * ap.neighbour_step).astype(np.int64)
    idx = np.arange(n)
    # the k-step neighbours, but never past the cluster's ends: a corner one or two points
    # before a cluster end is still a corner (else its line swallows the stray point)
    new_cluster = np.ones(n, bool)
    new_cluster[1:] = cluster[1:] != cluster[:-1]
    start = np.maximum.accumulate(np.where(new_cluster, idx, 0))
    last = np.empty(n, bool)
    last[:-1] = new_cluster[1:]
    last[-1] = True
    end = np.minimum.accumulate(np.where(last, idx, n - 1)[::-1])[::-1]
    lo = np.maximum(idx - k, start)
    hi = np.minimum(idx + k, end)
    a = points.take(lo, axis=0) - points
    b = points.take(hi, axis=0) - points
    min_arm = 0.5 * ap.neighbour_distance
    inside = (
        (cluster >= 0)
        & (lo < idx)
        & (hi > idx)
        & (a[:, 0] ** 2 + a[:, 1] ** 2 >= min_arm * min_arm)
        & (b[:, 0] ** 2 + b[:, 1] ** 2 >= min_arm * min_arm)
    )
    cross = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    dot = a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1]
    angle = np.where(inside, np.abs(np.arctan2(cross, dot)), np.pi)
    cand = angle <= ap.interior_angle_threshold
    if not cand.any():
        return cand, angle
    # runs of consecutive candidates within a cluster: keep the sharpest of each run
    prev_cand = np.concatenate([[False], cand[:-1]])
    same_cluster_prev = np.concatenate([[False], cluster[1:] == cluster[:-1]])
    run_start = cand & ~(prev_cand & same_cluster_prev)
    run_id = _running_count(run_start) - 1
    ci = cand.nonzero()[0]
    runs = run_id[ci]
    a = angle[ci]
    starts = run_start[ci].nonzero()[0]
    sharpest = np.minimum.reduceat(a, starts)[runs]
    # the first point of each run that reaches the run's sharpest angle
    hit = a == sharpest
    before = _running_count(hit) - hit
    first_hit = hit & (before == before[starts][runs])
    is_corner = np.zeros(n, bool)
    is_corner[ci[first_hit]] = True
    return is_corner, angle


def segment_ids(
    cluster: IntArray, is_corner: BoolArray, corner_exclusion: int, ring: bool = False
) -> tuple[IntArray, IntArray]:
    """:func:`segment_ids` in numpy (the compiled kernel's reference)."""
    if cluster.shape[0] == 0:
        empty = np.zeros(0, dtype=np.int64)
        return empty, empty.copy()
    raw = raw_segment_ids(cluster, is_corner)
    return raw, segments(cluster, is_corner, corner_exclusion, ring=ring, raw=raw)


def fit_lines(
    points: FloatArray,
    uncertainty: FloatArray,
    segment: IntArray,
    cluster: IntArray,
    bases: RuleBases,
    cfg: Config,
) -> Lines:
    """:func:`fit_lines` in numpy, per-segment sums by ``np.bincount`` (the compiled kernel's
    reference)."""
    used = segment >= 0
    if not used.any():
        return _empty_lines()
    seg = segment[used]  # non-decreasing: segments are runs of the sequence
    p = points.compress(used, axis=0)
    px, py = p[:, 0], p[:, 1]
    nseg = int(seg[-1]) + 1
    count = np.bincount(seg, minlength=nseg).astype(float)
    safe = np.maximum(count, 1.0)
    mx = np.bincount(seg, px, nseg) / safe
    my = np.bincount(seg, py, nseg) / safe
    dx = px - mx[seg]
    dy = py - my[seg]
    sxx = np.bincount(seg, dx * dx, nseg)
    syy = np.bincount(seg, dy * dy, nseg)
    sxy = np.bincount(seg, dx * dy, nseg)
    # principal direction φ of the scatter; the normal is perpendicular to it, pointing away
    # from the robot (d ≥ 0)
    phi = 0.5 * np.arctan2(2.0 * sxy, sxx - syy)
    normal = stack_columns(-np.sin(phi), np.cos(phi))
    dist = normal[:, 0] * mx + normal[:, 1] * my
    flip = np.where(dist < 0, -1.0, 1.0)
    normal *= flip[:, None]
    dist *= flip
    # extreme points of each segment (first and last in sequence order), projected on its line
    ids_all = np.arange(nseg)
    first = np.minimum(np.searchsorted(seg, ids_all, "left"), seg.shape[0] - 1)
    last = np.maximum(np.searchsorted(seg, ids_all, "right") - 1, 0)
    p0, p1 = p.take(first, axis=0), p.take(last, axis=0)
    start = p0 - ((p0 * normal).sum(axis=1) - dist)[:, None] * normal
    end = p1 - ((p1 * normal).sum(axis=1) - dist)[:, None] * normal
    span = end - start
    keep = (count >= cfg.lines.min_points) & ((span * span).sum(axis=1) >= cfg.lines.min_length**2)
    ids = keep.nonzero()[0]
    if ids.size == 0:
        return _empty_lines()
    # eq. 7–8 (SPEC fix: x·a + y·b + c) with a unit normal: d_i = |n·p_i − d|
    nseg_pt = normal.take(seg, axis=0)
    resid = np.abs(nseg_pt[:, 0] * px + nseg_pt[:, 1] * py - dist[seg])
    sigma = (np.bincount(seg, resid, nseg) / safe)[ids]
    delta = (np.bincount(seg, uncertainty[used], nseg) / safe)[ids]  # eq. 6
    f_line = bases.lines(delta, sigma)  # eq. 9 / Table 2
    # least-squares variances: residual variance s² = Σr²/(N−2) (at least 1 mm²), the
    # normal's angle var s²/Σt² (t along the line; Σt² is the scatter's trace less Σr²) and
    # the distance var s²/N + var_φ·(c·dir)² (c the centroid)
    n_ids = count[ids]
    r2 = np.bincount(seg, resid * resid, nseg)[ids]
    s2 = np.maximum(r2 / np.maximum(n_ids - 2.0, 1.0), _MIN_LINE_NOISE**2)
    var_phi = s2 / np.maximum(sxx[ids] + syy[ids] - r2, 1e-12)
    normal = normal.take(ids, axis=0)
    along = mx[ids] * normal[:, 1] - my[ids] * normal[:, 0]
    start, end = start.take(ids, axis=0), end.take(ids, axis=0)
    return Lines(
        normal=normal,
        distance=dist[ids],
        start=start,
        end=end,
        centre=0.5 * (start + end),
        n_points=n_ids.astype(np.int64),
        sigma=sigma,
        delta=delta,
        uncertainty=f_line,
        segment=ids,
        cluster=cluster[used][first[ids]],
        angle_variance=var_phi,
        distance_variance=s2 / n_ids + var_phi * along * along,
    )


def join_at_corners(
    lines: Lines,
    corner_segment_before: IntArray,
    corner_segment_after: IntArray,
    cfg: Config,
) -> tuple[Lines, FloatArray, BoolArray, IntArray, IntArray, FloatArray]:
    """:func:`fuzzypos.features.extract.join_at_corners` in numpy (the kernel's reference)."""
    m = corner_segment_before.shape[0]
    xy = np.full((m, 2), np.nan)
    ok = np.zeros(m, bool)
    none = np.zeros(0, dtype=np.int64)
    if m == 0 or len(lines) < 2:
        return lines, xy, ok, none, none, np.zeros(0)
    a, b = _lines_around_corners(lines, corner_segment_before, corner_segment_after)
    have = (a >= 0) & (b >= 0)
    if not have.any():
        return lines, xy, ok, none, none, np.zeros(0)
    ia, ib = a[have], b[have]
    pts, sin_ang = intersect_lines(
        lines.normal[ia], lines.distance[ia], lines.normal[ib], lines.distance[ib]
    )
    good = sin_ang >= math.sin(cfg.virtual_points.min_intersection_angle)
    hv = have.nonzero()[0][good]
    ia, ib, pts = ia[good], ib[good], pts[good]
    start = lines.start.copy()
    end = lines.end.copy()
    end[ia] = pts
    start[ib] = pts
    centre = 0.5 * (start + end)
    dv = _mean_distance_to_centres(pts, centre[ia], centre[ib])
    xy[hv] = pts
    ok[hv] = True
    return replace(lines, start=start, end=end, centre=centre), xy, ok, ia, ib, dv


def _running_count(mask: BoolArray) -> IntArray:
    """``np.cumsum`` of a boolean mask as int64 (the ufunc on an int array is several times
    faster than np.cumsum on booleans)."""
    return np.add.accumulate(mask.astype(np.int64))


def segments(
    cluster: IntArray,
    is_corner: BoolArray,
    corner_exclusion: int,
    ring: bool = False,
    raw: IntArray | None = None,
) -> IntArray:
    """Cut clusters at angular points into segments (§3.5). Returns a segment id per point.

    Ids are global and consecutive (see :func:`raw_segment_ids`, whose result may be passed as
    ``raw``). Points within ``corner_exclusion`` of an angular point (circularly when the
    points form a ``ring``), the angular point itself, and points of dropped clusters get −1
    (no line).
    """
    if cluster.shape[0] == 0:
        return np.zeros(0, dtype=np.int64)
    seg = raw_segment_ids(cluster, is_corner) if raw is None else raw
    excluded = is_corner.copy()
    for s in range(1, corner_exclusion + 1):
        if ring:
            excluded |= np.roll(is_corner, s) | np.roll(is_corner, -s)
        else:
            excluded[s:] |= is_corner[:-s]
            excluded[:-s] |= is_corner[s:]
    excluded |= cluster < 0
    return np.where(excluded, -1, seg)


def raw_segment_ids(cluster: IntArray, is_corner: BoolArray) -> IntArray:
    """Segment id of every point, counting a new segment at each cluster start and after each
    angular point; the angular point itself belongs to the segment before it."""
    n = cluster.shape[0]
    new_cluster = np.ones(n, bool)
    new_cluster[1:] = cluster[1:] != cluster[:-1]
    after_corner = np.zeros(n, bool)
    after_corner[1:] = is_corner[:-1] & ~new_cluster[1:]
    return _running_count(new_cluster | after_corner) - 1


def intersect_lines(
    n1: FloatArray, d1: FloatArray, n2: FloatArray, d2: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Intersections of lines ``n·p = d`` (SPEC's fix of eq. 15–16: normal form, homogeneous
    cross product, so vertical lines work). Returns ``(points, |sin angle|)``."""
    det = n1[:, 0] * n2[:, 1] - n1[:, 1] * n2[:, 0]
    safe = np.where(np.abs(det) > 1e-12, det, 1.0)
    x = (d1 * n2[:, 1] - d2 * n1[:, 1]) / safe
    y = (n1[:, 0] * d2 - n2[:, 0] * d1) / safe
    return stack_columns(x, y), np.abs(det)


def _mean_distance_to_centres(pts: FloatArray, c1: FloatArray, c2: FloatArray) -> FloatArray:
    """Eq. 10: d_v, the mean distance from each point to the centres of its two lines."""
    return 0.5 * (
        np.hypot(pts[:, 0] - c1[:, 0], pts[:, 1] - c1[:, 1])
        + np.hypot(pts[:, 0] - c2[:, 0], pts[:, 1] - c2[:, 1])
    )


def virtual_candidates(
    lines: Lines, cfg: Config, exclude_pairs: IntArray | None = None, scale: float = 1.0
) -> tuple[FloatArray, IntArray, IntArray, FloatArray]:
    """§3.6: the intersections of every two lines at least the minimum angle apart, not farther
    than the maximum distance (times the scan's distance ``scale``) from their lines (d_v,
    eq. 10), without the pairs in ``exclude_pairs`` (lines that meet at a real angular point:
    that intersection is the angular point). Returns ``(points, line i, line j, d_v)``."""
    nl = len(lines)
    none = np.zeros(0, dtype=np.int64)
    if nl < 2:
        return np.zeros((0, 2)), none, none, np.zeros(0)
    n = lines.normal
    # |sin| of the angle between every two lines = |n_i × n_j|; keep i < j far enough apart
    sin_ang = np.abs(n[:, 0:1] * n[:, 1] - n[:, 1:2] * n[:, 0])
    ok = sin_ang >= math.sin(cfg.virtual_points.min_intersection_angle)
    ok &= np.triu(np.ones((nl, nl), dtype=bool), 1)
    if exclude_pairs is not None and exclude_pairs.size:
        ok[exclude_pairs[:, 0], exclude_pairs[:, 1]] = False
        ok[exclude_pairs[:, 1], exclude_pairs[:, 0]] = False
    i, j = np.nonzero(ok)
    if i.size == 0:
        return np.zeros((0, 2)), none, none, np.zeros(0)
    pts, _ = intersect_lines(n[i], lines.distance[i], n[j], lines.distance[j])
    dv = _mean_distance_to_centres(pts, lines.centre[i], lines.centre[j])
    near = dv <= cfg.virtual_points.max_distance * scale
    return pts[near], i[near], j[near], dv[near]


def _keep_certain(
    pts: FloatArray, i: IntArray, j: IntArray, dv: FloatArray, f: FloatArray, cfg: Config
) -> tuple[FeaturePoints, IntArray, FloatArray]:
    """§3.6: virtual angular points more uncertain than the threshold are removed."""
    ok = f <= cfg.virtual_points.max_uncertainty
    fp = FeaturePoints(pts[ok], f[ok], np.full(int(ok.sum()), VIRTUAL_ANGULAR_POINT, dtype=np.int8))
    return fp, stack_columns(i[ok], j[ok]).astype(np.int64), dv[ok]


def point_features(c: _CornerContext) -> _PointFeatures:
    """:func:`fuzzypos.features.extract._point_features` in numpy (the compiled kernel's
    reference)."""
    cfg, lines = c.cfg, c.lines
    # 7. virtual angular points (§3.6), without the ones that are real angular points; one
    # fuzzy evaluation (eq. 10–12) grades them and the joined real corners together
    exclude = _corner_line_pairs(lines, c.seg_before, c.seg_after)
    v_pts, v_i, v_j, v_dv = virtual_candidates(lines, cfg, exclude, c.line_distance_scale)
    n_corners = c.corner_a.shape[0]
    graded = c.bases.virtual_points(
        lines.uncertainty[np.concatenate([c.corner_a, v_i])],
        lines.uncertainty[np.concatenate([c.corner_b, v_j])],
        np.concatenate([c.corner_dv, v_dv]) / c.line_distance_scale,  # d_v's sets stretched
    )
    virtual, virtual_lines, _dv = _keep_certain(v_pts, v_i, v_j, v_dv, graded[n_corners:], cfg)

    # angular points: sampled (the paper) or refined to their lines' intersection (SPEC step 5)
    idx = c.corner_index
    ang_xy = c.kept_points.take(idx, axis=0)
    ang_u = c.kept_uncertainty[idx]
    pairable = np.ones(idx.size, bool)
    if cfg.angular_points.refine and idx.size:
        corner_unc = np.full(c.joined.shape[0], np.nan)
        corner_unc[c.joined] = graded[:n_corners]
        spacing = abs(c.angle_increment) * c.kept_ranges[idx]
        gap = np.nan_to_num(c.corner_xy) - ang_xy
        near = c.joined & (np.hypot(gap[:, 0], gap[:, 1]) <= 3.0 * spacing + 0.05)
        ang_xy = np.where(near[:, None], c.corner_xy, ang_xy)
        ang_u = np.where(near, corner_unc, ang_u)
        if not cfg.angular_points.pair_unrefined:
            pairable = near
    angular = FeaturePoints(ang_xy, ang_u, np.full(idx.size, ANGULAR_POINT, dtype=np.int8))

    # break points as features: not at field-of-view edges, only in kept clusters
    bp = c.break_mask
    breaks = FeaturePoints(
        c.kept_points.compress(bp, axis=0),
        c.kept_uncertainty[bp],
        np.full(int(bp.sum()), BREAK_POINT, dtype=np.int8),
    )
    m = cfg.matching
    parts = []
    if m.use_break_points:
        parts.append(breaks)
    if m.use_angular_points:
        parts.append(angular.select(pairable))
    if m.use_virtual_points:
        parts.append(virtual)
    poi = merge_duplicates(
        FeaturePoints(
            np.concatenate([p.xy for p in parts]) if parts else np.zeros((0, 2)),
            np.concatenate([p.uncertainty for p in parts]) if parts else np.zeros(0),
            np.concatenate([p.kind for p in parts]) if parts else np.zeros(0, dtype=np.int8),
        ),
        cfg.virtual_points.merge_distance,
    )
    return angular, virtual, virtual_lines, breaks, poi


def merge_duplicates(points: FeaturePoints, radius: float) -> FeaturePoints:
    """Keep one feature of each group closer than ``radius``: the least uncertain.

    One wall seen as two lines (split by an occlusion) gives the same corner twice; the
    pairing rule "exactly one candidate within T" (§3.7) would then reject the true pair.
    """
    n = len(points)
    if n < 2 or radius <= 0:
        return points
    order = np.lexsort(
        (-points.kind, points.uncertainty)
    )  # most certain first; ties: virtual, angular, break
    xy = points.xy[order]
    d2 = np.sum((xy[:, None, :] - xy[None, :, :]) ** 2, axis=2)
    close = np.triu(d2 < radius * radius, 1)
    # a point is dropped when a more certain point it is close to is kept; one sweep over the
    # (small) upper triangle in order approximates this by dropping anything close to an
    # earlier point, which is exact when duplicates form tight groups
    dropped = close.any(axis=0)
    keep = np.sort(order[~dropped])
    return FeaturePoints(points.xy[keep], points.uncertainty[keep], points.kind[keep])


def _lines_around_corners(
    lines: Lines, seg_before: IntArray, seg_after: IntArray
) -> tuple[IntArray, IntArray]:
    """For each angular point, the index of the line before and after it (−1: no line)."""
    pos = np.full(int(max(lines.segment.max(), seg_before.max(), seg_after.max()) + 1), -1)
    pos[lines.segment] = np.arange(len(lines))
    return pos[seg_before], pos[seg_after]


def _corner_line_pairs(lines: Lines, seg_before: IntArray, seg_after: IntArray) -> IntArray:
    """Line index pairs (k, 2) of lines that meet at a real angular point."""
    if len(lines) < 2 or seg_before.size == 0:
        return np.zeros((0, 2), dtype=np.int64)
    a, b = _lines_around_corners(lines, seg_before, seg_after)
    ok = (a >= 0) & (b >= 0)
    return stack_columns(a[ok], b[ok]).astype(np.int64)


def segment_scan(scan: LaserScan, bases: RuleBases, cfg: Config) -> ScanSegments:
    """:func:`fuzzypos.features.segmentation.segment_scan` stage by stage in numpy: the
    usable points, their β, uncertainty, filtering, break points, clusters, angular points,
    segment ids (the reference of the compiled front, ``_kernels.front.scan_front``)."""
    closed = bool(scan.is_full_circle)
    beam_index, ranges, p_sensor, points = _valid_points(scan, cfg.scanner.no_return_bands)
    inc = scan.angle_increment
    t2_valid = segmentation.gap_thresholds(ranges, inc, cfg)

    # 1. gaps among the valid points, then β (eq. 3), then 2. uncertainty (eq. 4)
    _, gap_after = break_points(p_sensor, t2_valid, cfg.segmentation.gap_difference, closed)
    beta = detection_angles(p_sensor, gap_after, closed)
    u, scale = _graded_points(ranges, beta, bases, cfg)

    # 3. filtering (§3.1)
    kept = segmentation.filter_points(beta, cfg.filtering.detection_angle_threshold)
    kept_index = kept.nonzero()[0]
    kp = points.take(kept_index, axis=0)

    # 4. break points (eq. 13) and clusters (§3.3) on the filtered points
    t2 = t2_valid[kept_index]
    is_break, split = break_points(kp, t2, cfg.segmentation.gap_difference, closed)
    ring_corner = False
    if closed and kept_index.size:
        # a 360° scan wraps around (the paper's "indices additive modulo m"): start the
        # sequence after a gap, or, with no gap at all, at the sharpest corner of the ring
        if split.any():
            first = int(split.nonzero()[0][0]) + 1
        else:
            first, ring_corner = _sharpest_ring_corner(kp, cfg)
        order = np.roll(np.arange(kept_index.size), -first)
        kept_index, kp = kept_index[order], kp[order]
        is_break, split = is_break[order], split[order].copy()
        split[-1] = True
    fov_edge = np.zeros(kept_index.shape[0], bool)
    if kept_index.size and not closed:
        fov_edge[0] = True
        fov_edge[-1] = True
    cluster = clusters(split, cfg.segmentation.min_cluster_points)

    # 5. angular points (eq. 14)
    spacing = steps(kp, False)
    is_corner, _interior = angular_points(kp, cluster, spacing, cfg)
    if ring_corner and cluster.size and cluster[0] >= 0:
        is_corner[0] = True  # the seam of a gapless ring sits on its sharpest corner

    raw_seg, segment = segment_ids(cluster, is_corner, cfg.lines.corner_exclusion, ring_corner)
    return ScanSegments(
        beam_index, ranges, points, scale, beta, u, kept, kept_index, is_break, fov_edge,
        cluster, is_corner, raw_seg, segment, ring_corner,
    )  # fmt: skip


def _sharpest_ring_corner(points: FloatArray, cfg: Config) -> tuple[int, bool]:
    """For a gapless 360° ring of points: the index of its sharpest angular point (eq. 14 with
    neighbours k steps away, modulo the ring) and whether it is sharp enough to be one."""
    n = points.shape[0]
    k = cfg.angular_points.neighbour_step
    if n < 2 * k + 1:
        return 0, False
    idx = np.arange(n)
    a = points[(idx - k) % n] - points
    b = points[(idx + k) % n] - points
    angle = np.abs(np.arctan2(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0], np.sum(a * b, axis=1)))
    best = int(np.argmin(angle))
    return best, bool(angle[best] <= cfg.angular_points.interior_angle_threshold)


def _graded_points(
    ranges: FloatArray, beta: FloatArray, bases: RuleBases, cfg: Config
) -> tuple[FloatArray, float]:
    """Eq. 4 for every valid point, on distance sets stretched to the scan's own distances
    (:func:`distance_scale`); returns the uncertainties and the scale."""
    scale = distance_scale(ranges, cfg.fuzzy)
    return segmentation.point_uncertainty(ranges, beta, bases, scale), scale


def _valid_points(
    scan: LaserScan, no_return_bands: tuple[tuple[float, float], ...] = ()
) -> tuple[IntArray, FloatArray, FloatArray, FloatArray]:
    """The scan's valid readings outside ``no_return_bands`` (:func:`~fuzzypos.scan.usable`)
    counter-clockwise: their beam indices, ranges, points in the sensor and robot frames."""
    beam_index = usable(scan, no_return_bands).nonzero()[0]
    if scan.angle_increment < 0:
        # process counter-clockwise, so eq. 3's i+1 is the same neighbour
        beam_index = beam_index[::-1]
    ranges = np.asarray(scan.ranges)[beam_index]
    angles = scan.angles[beam_index]
    p_sensor = stack_columns(ranges * np.cos(angles), ranges * np.sin(angles))
    sp = scan.sensor_pose
    if sp.x == 0.0 and sp.y == 0.0 and sp.theta == 0.0:
        points = p_sensor
    else:
        points = transform_points(sp.as_array(), p_sensor)
    return beam_index, ranges, p_sensor, points


def graded_for_lines(
    ranges: FloatArray,
    beta: FloatArray,
    u: FloatArray,
    segment: IntArray,
    scale: float,
    bases: RuleBases,
    cfg: Config,
) -> tuple[FloatArray, float]:
    """The kept points' uncertainties the lines' δ (eq. 6) is taken from, and the scale the
    lines, d_v and the virtual points' distance limit are graded on: the scale of the lines'
    own surface (:func:`~fuzzypos.features.segmentation.line_distance_scale`), the points
    re-graded on it where it differs from the points' ``scale`` (else ``u`` itself)."""
    line_scale = line_distance_scale(ranges[segment >= 0], scale, cfg.fuzzy)
    if line_scale == scale:
        return u, scale
    return segmentation.point_uncertainty(ranges, beta, bases, line_scale), line_scale


def graded_lines(
    points: FloatArray,
    ranges: FloatArray,
    beta: FloatArray,
    u: FloatArray,
    segment: IntArray,
    cluster: IntArray,
    scale: float,
    bases: RuleBases,
    cfg: Config,
) -> tuple[Lines, float]:
    """``fuzzypos.features.extract._graded_lines`` in numpy: :func:`graded_for_lines`, then
    :func:`fit_lines` (the compiled ``_kernels.front.fit_lines``' reference)."""
    lu, line_scale = graded_for_lines(ranges, beta, u, segment, scale, bases, cfg)
    return fit_lines(points, lu, segment, cluster, bases, cfg), line_scale


def distance_scale(ranges: FloatArray, cfg: FuzzyConfig) -> float:
    """``fuzzypos.features.segmentation.distance_scale`` in numpy (the kernel's reference)."""
    n = ranges.shape[0]
    if cfg.distance_scale == "fixed" or n == 0:
        return 1.0
    reference, quantile = cfg.distance_scale_reference, cfg.distance_scale_quantile
    # the quantile interpolates between two order statistics, at most the one past
    # ⌈q·(n − 1)⌉ (a safe bound on numpy's index): where that one is within the reference, so
    # is the quantile and the scale is 1 (one comparison instead of np.quantile's sort)
    k = min(math.ceil(quantile * (n - 1)) + 1, n - 1)
    if np.count_nonzero(ranges <= reference) >= k + 1:
        return 1.0
    q = float(np.quantile(ranges, quantile))
    return max(1.0, q / reference)


def line_distance_scale(line_ranges: FloatArray, point_scale: float, cfg: FuzzyConfig) -> float:
    """``fuzzypos.features.segmentation.line_distance_scale`` in numpy (the kernel's reference)."""
    if (
        cfg.distance_scale == "fixed"
        or cfg.line_distance_scale == "points"
        or line_ranges.shape[0] == 0
    ):
        return point_scale
    reference = cfg.distance_scale_reference
    r = np.sort(line_ranges)
    if r[-1] <= reference * point_scale:
        return point_scale
    # the weighted quantile: the range where the cumulative weight (midpoint rule) reaches q
    w = np.cumsum(r) - 0.5 * r
    q = float(np.interp(cfg.distance_scale_quantile * float(r.sum()), w, r))
    return max(point_scale, q / reference)


#: (module, attribute, its reference) for :func:`oracles.references`; a fused call's
#: reference declines (``_declines``), so the staged chain runs
STAND_INS = [
    (segmentation.__name__, "_steps", steps),
    (segmentation.__name__, "break_points", break_points),
    (segmentation.__name__, "detection_angles", detection_angles),
    (segmentation.__name__, "clusters", clusters),
    (segmentation.__name__, "angular_points", angular_points),
    (segmentation.__name__, "segment_ids", segment_ids),
    (segmentation.__name__, "segment_scan", segment_scan),
    (extract.__name__, "fit_lines", fit_lines),
    (extract.__name__, "join_at_corners", join_at_corners),
    (extract.__name__, "_extract_compiled", _declines),
    (extract.__name__, "_graded_lines", graded_lines),
    (extract.__name__, "_point_features", point_features),
    (extract.__name__, "virtual_candidates", virtual_candidates),
    (chain.__name__, "chain_inputs", _declines),
]
