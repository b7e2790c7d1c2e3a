"""Feature extraction (§3.1–3.6): each stage a function over arrays, one call runs them all.

A scan's valid readings (but those in ``config.scanner``'s "no return" bands) become points
with a detection angle (eq. 3) and a fuzzy uncertainty (eq. 4); sharp-angle points are
filtered (§3.1); break points (eq. 13) split the rest into clusters (§3.3); angular points
(eq. 14) cut the clusters into segments; each segment of at least four points gets a
total-least-squares line in normal form ``n·p = d`` with a fuzzy uncertainty (eq. 5–9); pairs
of lines intersect into virtual angular points (eq. 10–12, §3.6).

Geometry that depends on the beam (ranges, detection angles) is computed in the sensor frame;
every point, line and feature is returned in the robot frame (SPEC: the scan's points are
moved into the robot frame by ``sensor_pose`` first). No Python loop runs over beams or points:
per-cluster and per-segment statistics use ``np.bincount`` over labels.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from functools import cached_property, lru_cache
from typing import cast

import numpy as np
from numpy.typing import NDArray

from .._kernels import packing
from .._kernels.packing import Unpacks
from ..config import Config, FuzzyConfig, same_as_last_call
from ..fuzzy import RuleBases
from ..geometry import stack_columns
from ..scan import LaserScan
from .chain import MIN_LINE_NOISE as _MIN_LINE_NOISE
from .chain import ChainOutputs, chain_inputs
from .chain import line_params as _line_params
from .segmentation import (
    _strict_upper,
    angular_points,
    break_points,
    clusters,
    detection_angles,
    distance_scale,
    filter_points,
    line_distance_scale,
    point_uncertainty,
    segment_scan,
)
from .types import (
    ANGULAR_POINT,
    BREAK_POINT,
    KIND_NAMES,
    VIRTUAL_ANGULAR_POINT,
    FeaturePoints,
    Lines,
    _CornerContext,
    _PointFeatures,
)

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]

__all__ = [
    "BREAK_POINT",
    "ANGULAR_POINT",
    "VIRTUAL_ANGULAR_POINT",
    "KIND_NAMES",
    "FeaturePoints",
    "Lines",
    "Features",
    "rule_bases",
    "detection_angles",
    "point_uncertainty",
    "distance_scale",
    "filter_points",
    "break_points",
    "clusters",
    "angular_points",
    "fit_lines",
    "virtual_angular_points",
    "extract_features",
]


@same_as_last_call
@lru_cache(maxsize=16)
def rule_bases(cfg: FuzzyConfig) -> RuleBases:
    """The three fuzzy systems for a fuzzy config, built once and cached."""
    return RuleBases.from_config(cfg)


@dataclass(frozen=True, eq=False)
class Features(Unpacks):
    """Everything :func:`extract_features` found in one scan, every stage kept for plotting.

    Points are processed counter-clockwise (a scan with a negative increment is reversed) and
    a 360° scan starts after a gap, or at its sharpest corner when it has none.

    Per valid reading (arrays of length ``n_valid``): ``beam_index`` (into the scan),
    ``points`` (robot frame), ``ranges``, ``detection_angle`` (β, eq. 3), ``uncertainty``
    (eq. 4) and ``kept`` (survived filtering, §3.1). Per kept point (arrays of length
    ``n_kept``, ``kept_index`` into the valid arrays): ``is_break_point`` (eq. 13),
    ``cluster`` (−1 for dropped clusters), ``is_angular_point`` (eq. 14) and ``segment``
    (−1 where a point belongs to no line fit). Then ``lines``, the virtual angular points with
    the indices of their two lines (``virtual_lines``), and ``points_of_interest``: the
    feature points used for pairing. (Made by the one compiled call, the arrays the positioner
    does not read of every scan are taken out of the call's packed arrays on first use.)
    """

    stamp: float
    beam_index: IntArray
    points: FloatArray
    ranges: FloatArray
    detection_angle: FloatArray
    uncertainty: FloatArray
    kept: BoolArray
    kept_index: IntArray
    is_break_point: BoolArray
    is_field_of_view_edge: BoolArray
    cluster: IntArray
    is_angular_point: BoolArray
    segment: IntArray
    lines: Lines
    _corners: _CornerContext = field(repr=False)

    # The point features are computed on first use (a positioner that pairs lines needs them
    # only where the lines give no motion): angular and virtual angular points, their fuzzy
    # grades (eq. 10–12) and the merged points of interest.
    @cached_property
    def _point_features(
        self,
    ) -> tuple[FeaturePoints, FeaturePoints, IntArray, FeaturePoints, FeaturePoints]:
        return _point_features(self._corners)

    @property
    def angular_points(self) -> FeaturePoints:
        """Real angular points (§3.4), refined to their lines' intersection where configured."""
        return self._point_features[0]

    @property
    def virtual_points(self) -> FeaturePoints:
        """Virtual angular points (§3.6) that passed the uncertainty threshold."""
        return self._point_features[1]

    @property
    def virtual_lines(self) -> IntArray:
        """The indices (k, 2) into ``lines`` of each virtual angular point's two lines."""
        return self._point_features[2]

    @property
    def break_points(self) -> FeaturePoints:
        """Break points (eq. 13) of kept clusters, without the field-of-view edges."""
        return self._point_features[3]

    @property
    def points_of_interest(self) -> FeaturePoints:
        """The feature points used for pairing (§3.7), duplicates merged."""
        return self._point_features[4]

    @property
    def distance_scale(self) -> float:
        """The factor this scan's distance sets (ρ, d_v) and virtual-point distance limit were
        stretched by (``fuzzy.distance_scale``; 1 for an indoor scan)."""
        return self._corners.distance_scale

    @property
    def line_distance_scale(self) -> float:
        """The factor this scan's lines (δ), d_v and virtual-point distance limit were graded
        on (``fuzzy.line_distance_scale``; at least :attr:`distance_scale`)."""
        return self._corners.line_distance_scale

    @property
    def n_valid(self) -> int:
        return int(self.points.shape[0])

    @property
    def kept_points(self) -> FloatArray:
        return self.points.take(self.kept_index, axis=0)

    @property
    def n_clusters(self) -> int:
        c = self.cluster[self.cluster >= 0]
        return int(np.unique(c).size)


# ---------------------------------------------------------------------------------------------
# stages
# ---------------------------------------------------------------------------------------------
def fit_lines(
    points: FloatArray,
    uncertainty: FloatArray,
    segment: IntArray,
    cluster: IntArray,
    bases: RuleBases,
    cfg: Config,
) -> Lines:
    """§3.5, eq. 5–9: a total-least-squares line per segment of at least ``min_points`` points.

    The normal is the eigenvector of the scatter matrix's smallest eigenvalue (the orthogonal
    fit, valid for vertical and horizontal walls alike); endpoints are the projections of the
    segment's extreme points (joined at angular points later, see :func:`join_at_corners`).
    The sums and fits in one compiled loop (``_kernels.segmentation``).
    """
    from .._kernels.segmentation import finish_lines, segment_sums

    p = np.ascontiguousarray(points, dtype=np.float64)
    seg = np.ascontiguousarray(segment, dtype=np.int64)
    sums, first, last = segment_sums(p, np.ascontiguousarray(uncertainty, dtype=np.float64), seg)
    if sums.shape[0] == 0:
        return _empty_lines()
    # the principal direction φ of each scatter (numpy's trigonometry, as the reference's)
    phi = 0.5 * np.arctan2(2.0 * sums[:, 5], sums[:, 3] - sums[:, 4])
    normal = stack_columns(-np.sin(phi), np.cos(phi))
    ids, table, firsts = finish_lines(
        p, seg, sums, first, last, normal, int(cfg.lines.min_points),
        float(cfg.lines.min_length), _MIN_LINE_NOISE,
    )  # fmt: skip
    if ids.size == 0:
        return _empty_lines()
    f_line = bases.lines(table[:, 8].copy(), table[:, 7].copy())  # eq. 9 / Table 2: (δ, σ)
    return _lines_of_table(table, ids, firsts, f_line, cluster)


def _lines_of_table(
    table: FloatArray, ids: IntArray, firsts: IntArray, f_line: FloatArray, cluster: IntArray
) -> Lines:
    """The :class:`Lines` of ``_kernels.segmentation.finish_lines``' table (its kept segment
    ids and each one's first point) with their uncertainty ``f_line``."""
    start, end = table[:, 3:5].copy(), table[:, 5:7].copy()
    return Lines(
        normal=table[:, 0:2].copy(),
        distance=table[:, 2].copy(),
        start=start,
        end=end,
        centre=0.5 * (start + end),
        n_points=table[:, 11].astype(np.int64),
        sigma=table[:, 7].copy(),
        delta=table[:, 8].copy(),
        uncertainty=f_line,
        segment=ids,
        cluster=cluster[firsts],
        angle_variance=table[:, 9].copy(),
        distance_variance=table[:, 10].copy(),
    )


def _empty_lines() -> Lines:
    z2 = np.zeros((0, 2))
    z = np.zeros(0)
    zi = np.zeros(0, dtype=np.int64)
    return Lines(z2, z, z2, z2, z2, zi, z, z, z, zi, zi)


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


def join_at_corners(
    lines: Lines,
    corner_segment_before: IntArray,
    corner_segment_after: IntArray,
    cfg: Config,
) -> tuple[Lines, FloatArray, BoolArray, IntArray, IntArray, FloatArray]:
    """§3.5 b): where two lines meet at an angular point, their shared endpoint is their
    intersection. Returns the updated lines and, per angular point, the intersection and
    whether it exists; and for the joined ones the two line indices and d_v (eq. 10), from
    which the caller grades them as virtual angular points (eq. 11–12)."""
    m = corner_segment_before.shape[0]
    xy = np.full((m, 2), np.nan)
    ok = np.zeros(m, bool)
    none = np.zeros(0, dtype=np.int64)
    if m == 0 or len(lines) < 2:
        return lines, xy, ok, none, none, np.zeros(0)
    from .._kernels.segmentation import join_at_corners as kernel

    have_any, start, end, centre, xy, ok, ia, ib, dv = kernel(
        np.ascontiguousarray(lines.normal, dtype=np.float64),
        np.ascontiguousarray(lines.distance, dtype=np.float64),
        np.ascontiguousarray(lines.start, dtype=np.float64),
        np.ascontiguousarray(lines.end, dtype=np.float64),
        np.ascontiguousarray(lines.segment, dtype=np.int64),
        np.ascontiguousarray(corner_segment_before, dtype=np.int64),
        np.ascontiguousarray(corner_segment_after, dtype=np.int64),
        math.sin(cfg.virtual_points.min_intersection_angle),
    )
    if not have_any:
        return lines, xy, ok, none, none, np.zeros(0)
    return replace(lines, start=start, end=end, centre=centre), xy, ok, ia, ib, dv


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
    ok &= _strict_upper(nl)
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


def virtual_angular_points(
    lines: Lines,
    bases: RuleBases,
    cfg: Config,
    exclude_pairs: IntArray | None = None,
    scale: float = 1.0,
) -> tuple[FeaturePoints, IntArray, FloatArray]:
    """§3.6, eq. 10–12: intersections of every two lines at least the minimum angle apart.

    Each gets the uncertainty of Table 3 from its lines' uncertainties and d_v (eq. 10), and
    points above the threshold are removed. ``exclude_pairs`` (k, 2) are line pairs that meet
    at a real angular point: that intersection is the angular point, not a second feature.
    ``scale`` (:func:`~fuzzypos.features.segmentation.distance_scale`) stretches d_v's sets and the
    distance limit. Returns the points, their line index pairs and their d_v.
    """
    pts, i, j, dv = virtual_candidates(lines, cfg, exclude_pairs, scale)
    if i.size == 0:
        return FeaturePoints.empty(), np.zeros((0, 2), dtype=np.int64), np.zeros(0)
    # eq. 11–12, on d_v's sets stretched by the scale
    f = bases.virtual_points(lines.uncertainty[i], lines.uncertainty[j], dv / scale)
    return _keep_certain(pts, i, j, dv, f, cfg)


# ---------------------------------------------------------------------------------------------
# the whole chain
# ---------------------------------------------------------------------------------------------
def extract_features(scan: LaserScan, config: Config | None = None) -> Features:
    """Run every stage of §3.1–3.6 on one scan and keep each intermediate result."""
    cfg = config if config is not None else Config()
    bases = rule_bases(cfg.fuzzy)
    fused = _extract_compiled(scan, bases, cfg)
    if fused is not None:
        return fused
    inc = scan.angle_increment
    front = segment_scan(scan, bases, cfg)
    (beam_index, ranges, points, scale, beta, u, kept, kept_index, is_break, fov_edge,
     cluster, is_corner, raw_seg, segment, _ring_corner) = front  # fmt: skip
    kp = points.take(kept_index, axis=0)
    ku = u.take(kept_index)
    kr = ranges.take(kept_index)

    # 6. lines (§3.5, eq. 5–9)
    lines, line_scale = _graded_lines(
        kp, kr, beta.take(kept_index), ku, segment, cluster, scale, bases, cfg
    )
    corner_idx = is_corner.nonzero()[0]
    n_kept = kp.shape[0]
    # the lines on either side of each angular point (circularly, for the ring's seam)
    seg_before = raw_seg[(corner_idx - 1) % max(n_kept, 1)]
    seg_after = raw_seg[(corner_idx + 1) % max(n_kept, 1)]
    lines, corner_xy, joined, corner_a, corner_b, corner_dv = join_at_corners(
        lines, seg_before, seg_after, cfg
    )
    context = _CornerContext(
        cfg=cfg,
        bases=bases,
        lines=lines,
        kept_points=kp,
        kept_uncertainty=ku,
        kept_ranges=kr,
        angle_increment=inc,
        corner_index=corner_idx,
        corner_xy=corner_xy,
        joined=joined,
        corner_a=corner_a,
        corner_b=corner_b,
        corner_dv=corner_dv,
        distance_scale=scale,
        line_distance_scale=line_scale,
        seg_before=seg_before,
        seg_after=seg_after,
        break_mask=is_break & ~fov_edge & (cluster >= 0),
    )
    return Features(
        stamp=scan.stamp,
        beam_index=beam_index,
        points=points,
        ranges=ranges,
        detection_angle=beta,
        uncertainty=u,
        kept=kept,
        kept_index=kept_index,
        is_break_point=is_break,
        is_field_of_view_edge=fov_edge,
        cluster=cluster,
        is_angular_point=is_corner,
        segment=segment,
        lines=lines,
        _corners=context,
    )


def features_of_chain(scan: LaserScan, config: Config, outputs: ChainOutputs) -> Features:
    """The :class:`Features` of ``scan`` from the compiled chain's values where it is done
    (:func:`extract_features`' to the bit)."""
    scale, line_scale, sizes, fl, it, bl = outputs
    context = {
        "cfg": config,
        "bases": rule_bases(config.fuzzy),
        "angle_increment": scan.angle_increment,
    }
    unpacked = packing.unpacked(
        (Features, Lines, _CornerContext), _empty_lines, scan.stamp, context, scale, line_scale,
        sizes, fl, it, bl,
    )  # fmt: skip
    return cast(Features, unpacked)


def _extract_compiled(scan: LaserScan, bases: RuleBases, cfg: Config) -> Features | None:
    """:func:`extract_features` in one compiled call (``_kernels.front.scan_features``: the
    front, the lines and their joins at the angular points, which the staged chain computes
    in four calls with numpy between them); None for a gapless 360° ring or rule bases off
    the interpolation's path (then the staged chain runs)."""
    inputs = chain_inputs(scan, cfg, bases)
    if inputs is None:
        return None
    done, *outputs = packing.front().scan_features(*inputs)
    if not done:
        return None
    return features_of_chain(scan, cfg, cast(ChainOutputs, tuple(outputs)))


def _graded_lines(
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
    """Step 6 on the kept points: the scale the lines are graded on and the lines fitted on
    it, in one compiled call (:func:`_lines_compiled`), or where that declines (a rule base off
    the interpolation's path) by :func:`_graded_for_lines` and :func:`fit_lines`."""
    fitted = _lines_compiled(points, ranges, beta, u, segment, cluster, scale, bases, cfg)
    if fitted is not None:
        return fitted
    lu, line_scale = _graded_for_lines(ranges, beta, u, segment, scale, bases, cfg)
    return fit_lines(points, lu, segment, cluster, bases, cfg), line_scale


def _lines_compiled(
    points: FloatArray,
    ranges: FloatArray,
    beta: FloatArray,
    u: FloatArray,
    segment: IntArray,
    cluster: IntArray,
    scale: float,
    bases: RuleBases,
    cfg: Config,
) -> tuple[Lines, float] | None:
    """:func:`_graded_for_lines` and :func:`fit_lines` in one compiled call
    (``_kernels.front.fit_lines``): the lines and the scale they are graded on; None where a
    rule base is off the interpolation's path (then the staged functions run)."""
    from .._kernels.front import fit_lines as kernel

    pb, lb = bases.points, bases.lines
    if pb._grids is None or lb._grids is None:
        return None
    line_scale, _lu, ids, table, firsts, f_line = kernel(
        np.ascontiguousarray(points), ranges, beta, u, segment, float(scale),
        _line_params(cfg.lines, cfg.fuzzy),
        (*pb._grids, pb._table, pb._centre_lo, pb._centre_hi),
        (*lb._grids, lb._table, lb._centre_lo, lb._centre_hi),
    )  # fmt: skip
    if ids.size == 0:
        return _empty_lines(), line_scale
    return _lines_of_table(table, ids, firsts, f_line, cluster), line_scale


def _graded_for_lines(
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
    return point_uncertainty(ranges, beta, bases, line_scale), line_scale


def _point_features(c: _CornerContext) -> _PointFeatures:
    """Angular points, virtual angular points (with their line pairs), break points and the
    merged points of interest of one scan (§3.2, §3.4, §3.6): in one compiled call
    (:func:`.points.point_features_compiled`), or where that declines in numpy
    (:func:`_point_features_numpy`, its reference and fallback)."""
    from .points import point_features_compiled

    done = point_features_compiled(c)
    if done is not None:
        return done
    return _point_features_numpy(c)


def _point_features_numpy(c: _CornerContext) -> _PointFeatures:
    """:func:`_point_features` in numpy (the compiled kernel's reference)."""
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
