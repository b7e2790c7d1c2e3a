"""Feature extraction (§3.1–3.6): each stage a function over arrays, one call runs them all.

A scan's valid readings (but those in ``config.scanner``'s "no return" bands) become points
with a detection angle (eq. 3) and a fuzzy uncertainty (eq. 4); sharp-angle points are
filtered (§3.1); break points (eq. 13) split the rest into clusters (§3.3); angular points
(eq. 14) cut the clusters into segments; each segment of at least four points gets a
total-least-squares line in normal form ``n·p = d`` with a fuzzy uncertainty (eq. 5–9); pairs
of lines intersect into virtual angular points (eq. 10–12, §3.6).

Geometry that depends on the beam (ranges, detection angles) is computed in the sensor frame;
every point, line and feature is returned in the robot frame (SPEC: the scan's points are
moved into the robot frame by ``sensor_pose`` first). Every stage is a compiled kernel
(``fuzzypos._kernels``); their numpy references are the tests' oracles
(``tests/oracles/features.py``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from functools import cached_property, lru_cache
from typing import cast

import numpy as np
from numpy.typing import NDArray

from .._kernels import f64, packing
from .._kernels.packing import Unpacks
from ..config import Config, FuzzyConfig, same_as_last_call
from ..fuzzy import RuleBase, RuleBases
from ..geometry import stack_columns
from ..scan import LaserScan
from .chain import ChainOutputs, chain_inputs
from .chain import line_params as _line_params
from .segmentation import (
    angular_points,
    break_points,
    clusters,
    detection_angles,
    distance_scale,
    filter_points,
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
    Graded on the points' ``uncertainty`` as given (:func:`_graded_lines` takes the lines'
    own distance scale), in one compiled call (``_kernels.front.fit_lines``).
    """
    n = np.asarray(points).shape[0]
    return _lines_fitted(points, np.zeros(n), np.zeros(n), uncertainty, segment, cluster,
                         1.0, bases, cfg, structure=False)[0]  # fmt: skip


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
    """Step 6 on the kept points: the scale the lines are graded on (the scale of the lines'
    own surface, :func:`~fuzzypos.features.segmentation.line_distance_scale`, the points
    re-graded on it where it differs from the points' ``scale``) and the lines fitted on it."""
    return _lines_fitted(points, ranges, beta, u, segment, cluster, scale, bases, cfg, True)


def _lines_fitted(
    points: FloatArray,
    ranges: FloatArray,
    beta: FloatArray,
    u: FloatArray,
    segment: IntArray,
    cluster: IntArray,
    scale: float,
    bases: RuleBases,
    cfg: Config,
    structure: bool,
) -> tuple[Lines, float]:
    """:func:`_graded_lines` (``structure``: on the lines' own distance scale where the config
    says so) in one compiled call (``_kernels.front.fit_lines``). A rule base off the
    interpolation's path (Mamdani's, sets that are no partition of unity) grades itself
    around it: the points' rule base before it, on the lines' scale
    (``_kernels.front.line_distance_scale``), the lines' after it."""
    from .._kernels import front as kernel

    pb, lb = bases.points, bases.lines
    params = _line_params(cfg.lines, cfg.fuzzy)
    if not structure:
        params = _no_structure(params)
    p, r, b, lu = f64(points), f64(ranges), f64(beta), f64(u)
    seg = np.ascontiguousarray(segment, dtype=np.int64)
    if pb._grids is None:  # the lines' scale here, the points graded on it by the rule base
        line_scale = scale
        if params[3] != 0.0:
            line_scale = kernel.line_distance_scale(r[seg >= 0], scale, params[4], params[5])
        if line_scale != scale and r.shape[0]:
            lu = f64(point_uncertainty(r, b, bases, line_scale))
        params, scale = _no_structure(params), line_scale
    line_scale, _lu, ids, table, firsts, f_line = kernel.fit_lines(
        p, r, b, lu, seg, float(scale), params, _tables(pb), _tables(lb)
    )
    if ids.size == 0:
        return _empty_lines(), line_scale
    if lb._grids is None:
        f_line = lb(table[:, 8].copy(), table[:, 7].copy())  # eq. 9 / Table 2: (δ, σ)
    return _lines_of_table(table, ids, firsts, f_line, cluster), line_scale


_NO_GRID = np.zeros(0)


def _no_structure(params: FloatArray) -> FloatArray:
    """``_kernels.front.fit_lines``' params graded on the scale given (no structure scale)."""
    out: FloatArray = params.copy()
    out[3] = 0.0
    return out


def _tables(
    rule_base: RuleBase,
) -> tuple[FloatArray, FloatArray, FloatArray, float, float]:
    """A two-input rule base's interpolation (``_kernels.fuzzy.bilinear``'s grids, table and
    clamp), its grids empty where it is off that path (then it grades itself)."""
    g1, g2 = rule_base._grids if rule_base._grids is not None else (_NO_GRID, _NO_GRID)
    return g1, g2, rule_base._table, rule_base._centre_lo, rule_base._centre_hi


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
    excluded = np.zeros((nl, nl), dtype=np.bool_)
    if exclude_pairs is not None and exclude_pairs.size:
        excluded[exclude_pairs[:, 0], exclude_pairs[:, 1]] = True
        excluded[exclude_pairs[:, 1], exclude_pairs[:, 0]] = True
    from .._kernels.points import candidates

    pts, i, j, dv = candidates(
        f64(lines.normal), f64(lines.distance), f64(lines.centre), excluded,
        math.sin(cfg.virtual_points.min_intersection_angle),
        float(cfg.virtual_points.max_distance * scale),
    )  # fmt: skip
    return pts, i, j, dv


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
    """Run every stage of §3.1–3.6 on one scan and keep each intermediate result: in one
    compiled call, or, where a rule base is off the interpolation's path (Mamdani's, sets
    that are no partition of unity), the same compiled stages one by one with the rule
    bases' own grading between them."""
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
    """The :class:`Features` of ``scan`` from the compiled chain's values
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
    in four calls with the rule bases' grading between them); None for rule bases off the
    interpolation's path (then the staged chain runs)."""
    inputs = chain_inputs(scan, cfg, bases)
    if inputs is None:
        return None
    outputs = packing.front().scan_features(*inputs)
    return features_of_chain(scan, cfg, cast(ChainOutputs, tuple(outputs)))


def _point_features(c: _CornerContext) -> _PointFeatures:
    """Angular points, virtual angular points (with their line pairs), break points and the
    merged points of interest of one scan (§3.2, §3.4, §3.6): in one compiled call
    (:func:`.points.point_features`)."""
    from .points import point_features

    return point_features(c)
