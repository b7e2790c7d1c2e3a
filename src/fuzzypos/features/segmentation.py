"""Segmentation of a scan (§3.1–3.4): detection angles (eq. 3), point uncertainty (eq. 4),
filtering (§3.1), break points (eq. 13) and clusters (§3.3), angular points (eq. 14) and the
segments lines are fitted to; each a function over arrays (:func:`fuzzypos.features.
extract_features` runs them in turn)."""

from __future__ import annotations

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
from ..scan import LaserScan, _band_bounds_cached

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
    A scan with structure near the robot (a room, a corridor) keeps a scale of 1. Compiled
    (``_kernels.front.distance_scale``)."""
    if cfg.distance_scale == "fixed":
        return 1.0
    from .._kernels import front as kernel

    reference, quantile = cfg.distance_scale_reference, cfg.distance_scale_quantile
    return float(kernel.distance_scale(f64(ranges), reference, quantile))


def line_distance_scale(line_ranges: FloatArray, point_scale: float, cfg: FuzzyConfig) -> float:
    """The scale the lines, d_v and the virtual points' distance limit are graded on, from the
    ranges of the points that belong to line fits: with ``line_distance_scale = "structure"``
    (and ``distance_scale = "scan"``), max(``point_scale``, the ``distance_scale_quantile`` of
    those ranges weighted by range / ``distance_scale_reference``); else ``point_scale``.

    Weighted by range, each beam counts as the length of surface it samples (ρ·Δφ up to its
    incidence), so the quantile is of the lines' length by distance: short clutter near the
    robot takes many beams but little of that length. Compiled
    (``_kernels.front.line_distance_scale``)."""
    if cfg.distance_scale == "fixed" or cfg.line_distance_scale == "points":
        return point_scale
    from .._kernels import front as kernel

    r, reference, quantile = (
        f64(line_ranges),
        cfg.distance_scale_reference,
        cfg.distance_scale_quantile,
    )
    return float(kernel.line_distance_scale(r, float(point_scale), reference, quantile))


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


# ---------------------------------------------------------------------------------------------
# the front of feature extraction: §3.1–3.4 and the segments of §3.5 on one scan
# ---------------------------------------------------------------------------------------------
def segment_scan(scan: LaserScan, bases: RuleBases, cfg: Config) -> ScanSegments:
    """Steps 1–5 of :func:`fuzzypos.features.extract_features` and the segments lines are
    fitted to (:class:`ScanSegments`), in two compiled calls (``_kernels.front``: the usable
    points, then the rest; a gapless 360° ring's seam on its sharpest corner). A point rule
    base off the interpolation's path (Mamdani's, sets that are no partition of unity)
    grades the points itself after them (:func:`point_uncertainty`)."""
    from .._kernels import front as kernel

    base = bases.points
    lo, hi = _band_bounds_of(cfg.scanner)
    sp = scan.sensor_pose
    beam_index, ranges, p_sensor, points = kernel.valid_points(
        np.asarray(scan.ranges), scan.angles, scan.valid, lo, hi, float(scan.angle_increment),
        np.array([sp.x, sp.y, sp.theta]),
    )  # fmt: skip
    g1, g2 = base._grids if base._grids is not None else (_NO_GRID, _NO_GRID)
    scale, beta, u, kept, kept_index, is_break, fov_edge, cluster, is_corner, raw, seg, ring = (
        kernel.scan_front(
            p_sensor, points, ranges, float(scan.angle_increment), bool(scan.is_full_circle),
            _front_params(cfg.segmentation, cfg.angular_points, cfg.fuzzy, cfg.filtering,
                          cfg.lines), g1, g2, base._table, base._centre_lo, base._centre_hi,
        )
    )  # fmt: skip
    if base._grids is None:
        u = point_uncertainty(ranges, beta, bases, scale)
    return ScanSegments(
        beam_index, ranges, points, scale, beta, u, kept, kept_index, is_break, fov_edge,
        cluster, is_corner, raw, seg, ring,
    )  # fmt: skip


_NO_GRID = np.zeros(0)


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
