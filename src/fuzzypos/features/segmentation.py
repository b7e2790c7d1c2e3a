"""Segmentation of a scan (§3.1–3.4): detection angles (eq. 3), point uncertainty (eq. 4),
filtering (§3.1), break points (eq. 13) and clusters (§3.3), angular points (eq. 14) and the
segments lines are fitted to; each a function over arrays (:func:`fuzzypos.features.
extract_features` runs them in turn)."""

from __future__ import annotations

import math
from functools import lru_cache
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from .._kernels import compiled, f64
from ..config import (
    AngularPointConfig,
    Config,
    FilterConfig,
    FuzzyConfig,
    LineConfig,
    ScannerConfig,
    SegmentationConfig,
    same_as_last_call,
)
from ..fuzzy import RuleBases
from ..geometry import stack_columns, transform_points
from ..scan import LaserScan, _band_bounds_cached, usable

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]

__all__ = [
    "gap_thresholds",
    "break_points",
    "detection_angles",
    "distance_scale",
    "line_distance_scale",
    "point_uncertainty",
    "filter_points",
    "clusters",
    "angular_points",
    "segments",
    "raw_segment_ids",
    "segment_ids",
    "segment_scan",
    "ScanSegments",
]


def _running_count(mask: BoolArray) -> IntArray:
    """``np.cumsum`` of a boolean mask as int64 (the ufunc on an int array is several times
    faster than np.cumsum on booleans)."""
    return np.add.accumulate(mask.astype(np.int64))


@lru_cache(maxsize=128)
def _strict_upper(n: int) -> BoolArray:
    """The (n, n) mask of i < j (cached)."""
    m = np.triu(np.ones((n, n), dtype=bool), 1)
    m.flags.writeable = False
    return m


def _steps(points: FloatArray, closed: bool) -> FloatArray:
    """Distance from each point to the next one (the last: to the first if ``closed``, else inf)."""
    if compiled():
        from .._kernels import segmentation as kernel

        return kernel.steps(f64(points), bool(closed))
    return _steps_numpy(points, closed)


def _steps_numpy(points: FloatArray, closed: bool) -> FloatArray:
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


def gap_thresholds(ranges: FloatArray, angle_increment: float, cfg: Config) -> FloatArray:
    """T2 per point: the fixed gap distance, or a few beam spacings at the point's range."""
    seg = cfg.segmentation
    return np.maximum(seg.gap_distance, seg.gap_distance_per_metre * abs(angle_increment) * ranges)


def break_points(
    points: FloatArray, thresholds: FloatArray, gap_difference: float, closed: bool = False
) -> tuple[BoolArray, BoolArray]:
    """Eq. 13 over an ordered point sequence.

    A point is a break point when the step to a neighbour exceeds T2 (``thresholds``) and
    differs by more than T1 (``gap_difference``) from the step beside it: both points that
    border a gap qualify, a uniformly sparse surface does not. Returns ``(is_break_point, split)``
    where ``split[j]`` says the sequence is cut between points j and j+1. The two ends of an
    open sequence are break points too (field-of-view edges, eq. 13's ``i = 1, 180``).
    """
    if compiled():
        from .._kernels import segmentation as kernel

        return kernel.break_points(
            f64(points), f64(thresholds), float(gap_difference), bool(closed)
        )
    return _break_points_numpy(points, thresholds, gap_difference, closed)


def _break_points_numpy(
    points: FloatArray, thresholds: FloatArray, gap_difference: float, closed: bool = False
) -> tuple[BoolArray, BoolArray]:
    """:func:`break_points` in numpy (the compiled kernel's reference)."""
    n = points.shape[0]
    if n == 0:
        return np.zeros(0, bool), np.zeros(0, bool)
    # step j joins points j and j+1; it is a gap when longer than T2 and longer (by T1) than a
    # neighbouring step, so a uniformly sparse surface has no gaps (eq. 13)
    step = _steps_numpy(points, closed)
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
    """β (eq. 3, SPEC step 1): angle between the beam and the surface, folded into [0, π/2].

    The surface through point i runs to its neighbour i+1, or to i−1 where i+1 lies across a
    gap (``gap_after[i]``) or does not exist. π/2 = square-on, 0 = grazing. A point with no
    neighbour on its surface (gaps on both sides) gets β = 0, so filtering removes it.
    """
    if compiled():
        from .._kernels.segmentation import detection_terms

        cross, dot, isolated = detection_terms(
            f64(points_sensor), np.ascontiguousarray(gap_after, dtype=np.bool_), bool(closed)
        )
        beta: FloatArray = np.arctan2(cross, dot)  # numpy's, as the reference's
        beta[isolated] = 0.0
        return beta
    return _detection_angles_numpy(points_sensor, gap_after, closed)


def _detection_angles_numpy(
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


def distance_scale(ranges: FloatArray, cfg: FuzzyConfig) -> float:
    """The factor the distance sets (ρ, d_v) and the virtual points' distance limit are
    stretched by for a scan with these valid ranges: 1 with ``distance_scale = "fixed"``, else
    max(1, the ``distance_scale_quantile`` of the ranges / ``distance_scale_reference``).
    A scan with structure near the robot (a room, a corridor) keeps a scale of 1."""
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
    """The scale the lines, d_v and the virtual points' distance limit are graded on, from the
    ranges of the points that belong to line fits: with ``line_distance_scale = "structure"``
    (and ``distance_scale = "scan"``), max(``point_scale``, the ``distance_scale_quantile`` of
    those ranges weighted by range / ``distance_scale_reference``); else ``point_scale``.

    Weighted by range, each beam counts as the length of surface it samples (ρ·Δφ up to its
    incidence), so the quantile is of the lines' length by distance: short clutter near the
    robot takes many beams but little of that length."""
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


def point_uncertainty(
    ranges: FloatArray, beta: FloatArray, bases: RuleBases, scale: float = 1.0
) -> FloatArray:
    """Eq. 4 / Table 1: the fuzzy uncertainty of each point from ρ and β.

    With a distance ``scale`` (:func:`distance_scale`) the sets are stretched by it, computed
    as ρ / scale on the unstretched sets: for triangles, μ_{sA}(ρ) = μ_A(ρ / s) exactly (the
    stretch is about 0, feet, peaks and the clamping range alike), and the cached rule base
    stays one per config.
    """
    if ranges.shape[0] == 0:
        return np.zeros(0)
    return bases.points(ranges if scale == 1.0 else ranges / scale, beta)


def filter_points(beta: FloatArray, threshold: float) -> BoolArray:
    """§3.1: keep points whose detection angle exceeds ξ_TH."""
    return beta > threshold


def clusters(split: BoolArray, min_points: int) -> IntArray:
    """§3.3: cluster labels 0, 1, … from cuts (``split[j]``: cut after point j); −1 = too small."""
    if compiled():
        from .._kernels import segmentation as kernel

        return kernel.clusters(np.ascontiguousarray(split, dtype=np.bool_), int(min_points))
    return _clusters_numpy(split, min_points)


def _clusters_numpy(split: BoolArray, min_points: int) -> IntArray:
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
    points: FloatArray,
    cluster: IntArray,
    step_spacing: FloatArray,
    cfg: Config,
) -> tuple[BoolArray, FloatArray]:
    """Eq. 14 (SPEC step 5): corners inside clusters, and the interior angle at every point.

    The interior angle at P_i is between P_i→P_{i−k} and P_i→P_{i+k}, with k the configured
    step, widened so the neighbours are at least ``neighbour_distance`` away (``step_spacing``
    is each point's distance to the next), and shortened at a cluster's ends so long as each
    arm stays at least half that distance long. Points whose angle is at most θ_TH are candidates;
    of a run of consecutive candidates the sharpest wins.
    """
    if compiled():
        from .._kernels.segmentation import corner_arms, sharpest_of_runs

        ap = cfg.angular_points
        labels = np.ascontiguousarray(cluster, dtype=np.int64)
        cross, dot, inside = corner_arms(
            f64(points), labels, f64(step_spacing), float(ap.neighbour_distance),
            int(ap.neighbour_step),
        )  # fmt: skip
        angle: FloatArray = np.abs(np.arctan2(cross, dot))  # numpy's, as the reference's
        angle[~inside] = np.pi
        return sharpest_of_runs(angle, labels, float(ap.interior_angle_threshold)), angle
    return _angular_points_numpy(points, cluster, step_spacing, cfg)


def _angular_points_numpy(
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


def segment_ids(
    cluster: IntArray, is_corner: BoolArray, corner_exclusion: int, ring: bool = False
) -> tuple[IntArray, IntArray]:
    """:func:`raw_segment_ids` and :func:`segments` in one: the raw id of every point and the
    id its line is fitted with (−1: none)."""
    if compiled():
        from .._kernels import segmentation as kernel

        return kernel.segments(
            np.ascontiguousarray(cluster, dtype=np.int64),
            np.ascontiguousarray(is_corner, dtype=np.bool_),
            int(corner_exclusion),
            bool(ring),
        )
    return _segment_ids_numpy(cluster, is_corner, corner_exclusion, ring)


def _segment_ids_numpy(
    cluster: IntArray, is_corner: BoolArray, corner_exclusion: int, ring: bool = False
) -> tuple[IntArray, IntArray]:
    """:func:`segment_ids` in numpy (the compiled kernel's reference)."""
    if cluster.shape[0] == 0:
        empty = np.zeros(0, dtype=np.int64)
        return empty, empty.copy()
    raw = raw_segment_ids(cluster, is_corner)
    return raw, segments(cluster, is_corner, corner_exclusion, ring=ring, raw=raw)


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


def raw_segment_ids(cluster: IntArray, is_corner: BoolArray) -> IntArray:
    """Segment id of every point, counting a new segment at each cluster start and after each
    angular point; the angular point itself belongs to the segment before it."""
    n = cluster.shape[0]
    new_cluster = np.ones(n, bool)
    new_cluster[1:] = cluster[1:] != cluster[:-1]
    after_corner = np.zeros(n, bool)
    after_corner[1:] = is_corner[:-1] & ~new_cluster[1:]
    return _running_count(new_cluster | after_corner) - 1


# ---------------------------------------------------------------------------------------------
# the front of feature extraction: §3.1–3.4 and the segments of §3.5 on one scan
# ---------------------------------------------------------------------------------------------
def segment_scan(scan: LaserScan, bases: RuleBases, cfg: Config) -> ScanSegments:
    """Steps 1–5 of :func:`fuzzypos.features.extract_features` and the segments lines are
    fitted to (:class:`ScanSegments`). Compiled in two calls where the kernels are on (a
    gapless 360° ring takes the staged chain)."""
    closed = bool(scan.is_full_circle)
    if compiled():
        front = segment_scan_compiled(scan, closed, bases, cfg)
        if front is not None:
            return front
    return segment_scan_staged(scan, closed, bases, cfg)


class ScanSegments(NamedTuple):
    """What the front of the chain (steps 1–5 and the segment ids, :func:`segment_scan`)
    gives the rest: per usable reading ``beam_index``, ``ranges``, ``points`` (robot frame),
    ``detection_angle`` (β) and ``uncertainty``, with the ``distance_scale``; which were
    ``kept`` and ``kept_index`` (in the sequence's order); per kept point ``is_break_point``,
    ``is_field_of_view_edge``, ``cluster``, ``is_angular_point``, ``raw_segment`` and
    ``segment`` (the line fits'; −1 none); ``ring_corner``: a gapless ring's seam sits on its
    sharpest corner."""

    beam_index: IntArray
    ranges: FloatArray
    points: FloatArray
    distance_scale: float
    detection_angle: FloatArray
    uncertainty: FloatArray
    kept: BoolArray
    kept_index: IntArray
    is_break_point: BoolArray
    is_field_of_view_edge: BoolArray
    cluster: IntArray
    is_angular_point: BoolArray
    raw_segment: IntArray
    segment: IntArray
    ring_corner: bool


def segment_scan_staged(
    scan: LaserScan, closed: bool, bases: RuleBases, cfg: Config
) -> ScanSegments:
    """Steps 1–5 of :func:`extract_features` and the segments of step 6, stage by stage:
    the usable points, their β, uncertainty, filtering, break points, clusters, angular
    points, segment ids (the reference of :func:`segment_scan_compiled`)."""
    beam_index, ranges, p_sensor, points = _valid_points(scan, cfg.scanner.no_return_bands)
    inc = scan.angle_increment
    t2_valid = gap_thresholds(ranges, inc, cfg)

    # 1. gaps among the valid points, then β (eq. 3), then 2. uncertainty (eq. 4)
    _, gap_after = break_points(p_sensor, t2_valid, cfg.segmentation.gap_difference, closed)
    beta = detection_angles(p_sensor, gap_after, closed)
    u, scale = _graded_points(ranges, beta, bases, cfg)

    # 3. filtering (§3.1)
    kept = filter_points(beta, cfg.filtering.detection_angle_threshold)
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
    steps = _steps(kp, False)
    is_corner, _interior = angular_points(kp, cluster, steps, cfg)
    if ring_corner and cluster.size and cluster[0] >= 0:
        is_corner[0] = True  # the seam of a gapless ring sits on its sharpest corner

    raw_seg, segment = segment_ids(cluster, is_corner, cfg.lines.corner_exclusion, ring_corner)
    return ScanSegments(
        beam_index, ranges, points, scale, beta, u, kept, kept_index, is_break, fov_edge,
        cluster, is_corner, raw_seg, segment, ring_corner,
    )  # fmt: skip


def segment_scan_compiled(
    scan: LaserScan, closed: bool, bases: RuleBases, cfg: Config
) -> ScanSegments | None:
    """:func:`segment_scan_staged` in two compiled calls (``_kernels.front``); None for a gapless
    360° ring (its seam is the staged chain's) or rule bases off the interpolation's path."""
    from .._kernels import front as kernel

    base = bases.points
    if base._grids is None:
        return None
    lo, hi = _band_bounds_of(cfg.scanner)
    sp = scan.sensor_pose
    beam_index, ranges, _p_sensor, points = kernel.valid_points(
        np.asarray(scan.ranges), scan.angles, scan.valid, lo, hi, float(scan.angle_increment),
        np.array([sp.x, sp.y, sp.theta]),
    )  # fmt: skip
    done, scale, beta, u, kept, kept_index, is_break, fov_edge, cluster, is_corner, raw, seg = (
        kernel.scan_front(
            _p_sensor, points, ranges, float(scan.angle_increment), closed,
            _front_params(cfg.segmentation, cfg.angular_points, cfg.fuzzy, cfg.filtering,
                          cfg.lines), base._grids[0], base._grids[1], base._table,
            base._centre_lo, base._centre_hi,
        )
    )  # fmt: skip
    if not done:
        return None
    return ScanSegments(
        beam_index, ranges, points, scale, beta, u, kept, kept_index, is_break, fov_edge,
        cluster, is_corner, raw, seg, False,
    )  # fmt: skip


@same_as_last_call
def _band_bounds_of(scanner: ScannerConfig) -> tuple[FloatArray, FloatArray]:
    """The bounds of the scanner section's "no return" bands (read-only)."""
    return _band_bounds_cached(tuple(tuple(band) for band in scanner.no_return_bands))


@same_as_last_call
@lru_cache(maxsize=16)
def _front_params(
    seg: SegmentationConfig,
    ap: AngularPointConfig,
    fz: FuzzyConfig,
    filtering: FilterConfig,
    lines: LineConfig,
) -> FloatArray:
    """``_kernels.front.PARAMS`` of a config's sections (cached; not to be written to)."""
    from .._kernels.front import PARAMS

    values = {
        "gap_distance": seg.gap_distance,
        "gap_distance_per_metre": seg.gap_distance_per_metre,
        "gap_difference": seg.gap_difference,
        "detection_angle_threshold": filtering.detection_angle_threshold,
        "min_cluster_points": seg.min_cluster_points,
        "neighbour_distance": ap.neighbour_distance,
        "neighbour_step": ap.neighbour_step,
        "interior_angle_threshold": ap.interior_angle_threshold,
        "corner_exclusion": lines.corner_exclusion,
        "distance_scale_reference": fz.distance_scale_reference,
        "distance_scale_quantile": fz.distance_scale_quantile,
        "scan_scale": 0.0 if fz.distance_scale == "fixed" else 1.0,
    }
    return np.array([float(values[name]) for name in PARAMS])


def _graded_points(
    ranges: FloatArray, beta: FloatArray, bases: RuleBases, cfg: Config
) -> tuple[FloatArray, float]:
    """Eq. 4 for every valid point, on distance sets stretched to the scan's own distances
    (:func:`distance_scale`); returns the uncertainties and the scale."""
    scale = distance_scale(ranges, cfg.fuzzy)
    return point_uncertainty(ranges, beta, bases, scale), scale


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
