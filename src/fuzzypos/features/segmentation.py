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

from .._kernels import f64
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
    "segment_ids",
    "segment_scan",
    "ScanSegments",
]


def _steps(points: FloatArray, closed: bool) -> FloatArray:
    """Distance from each point to the next one (the last: to the first if ``closed``, else inf)."""
    from .._kernels import segmentation as kernel

    return kernel.steps(f64(points), bool(closed))


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
    from .._kernels import segmentation as kernel

    return kernel.break_points(f64(points), f64(thresholds), float(gap_difference), bool(closed))


def detection_angles(
    points_sensor: FloatArray, gap_after: BoolArray, closed: bool = False
) -> FloatArray:
    """β (eq. 3, SPEC step 1): angle between the beam and the surface, folded into [0, π/2].

    The surface through point i runs to its neighbour i+1, or to i−1 where i+1 lies across a
    gap (``gap_after[i]``) or does not exist. π/2 = square-on, 0 = grazing. A point with no
    neighbour on its surface (gaps on both sides) gets β = 0, so filtering removes it.
    """
    from .._kernels.segmentation import detection_terms

    cross, dot, isolated = detection_terms(
        f64(points_sensor), np.ascontiguousarray(gap_after, dtype=np.bool_), bool(closed)
    )
    beta: FloatArray = np.arctan2(cross, dot)  # numpy's, as the reference's
    beta[isolated] = 0.0
    return beta


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
    from .._kernels import segmentation as kernel

    return kernel.clusters(np.ascontiguousarray(split, dtype=np.bool_), int(min_points))


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


def segment_ids(
    cluster: IntArray, is_corner: BoolArray, corner_exclusion: int, ring: bool = False
) -> tuple[IntArray, IntArray]:
    """Cut clusters at angular points into segments (§3.5): the raw id of every point (a new
    segment at each cluster start and after each angular point, which belongs to the segment
    before it; global and consecutive) and the id its line is fitted with (−1: none, for the
    points within ``corner_exclusion`` of an angular point, circularly on a ``ring``, the
    angular point itself and the points of dropped clusters)."""
    from .._kernels import segmentation as kernel

    return kernel.segments(
        np.ascontiguousarray(cluster, dtype=np.int64),
        np.ascontiguousarray(is_corner, dtype=np.bool_),
        int(corner_exclusion),
        bool(ring),
    )


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


# ---------------------------------------------------------------------------------------------
# the front of feature extraction: §3.1–3.4 and the segments of §3.5 on one scan
# ---------------------------------------------------------------------------------------------
def segment_scan(scan: LaserScan, bases: RuleBases, cfg: Config) -> ScanSegments:
    """Steps 1–5 of :func:`fuzzypos.features.extract_features` and the segments lines are
    fitted to (:class:`ScanSegments`). Compiled in two calls (a
    gapless 360° ring takes the staged chain)."""
    closed = bool(scan.is_full_circle)
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
