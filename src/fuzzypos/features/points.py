"""The point features of one scan in one compiled call (``fuzzypos._kernels.points``):
what ``fuzzypos.features.extract._point_features`` runs (its numpy reference is
``point_features`` of ``tests/oracles/features.py``). A virtual points' rule base the kernel
does not grade (Mamdani's) is evaluated by :class:`~fuzzypos.fuzzy.RuleBase` itself between
two calls."""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from .._kernels import f64
from ..fuzzy import RuleBase
from .types import (
    ANGULAR_POINT,
    BREAK_POINT,
    VIRTUAL_ANGULAR_POINT,
    FeatureError,
    FeaturePoints,
    _CornerContext,
    _PointFeatures,
)

_INCONSISTENT = (
    "the point features' corner context is inconsistent: its lines, segments and corners "
    "disagree in size or index"
)

__all__ = ["grading_tables", "point_features"]

_NO_TABLE = np.zeros((0, 0))
_NO_GRADES = np.zeros(0)

FloatArray = NDArray[np.float64]


@lru_cache(maxsize=8)
def grading_tables(
    rule_base: RuleBase,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray] | None:
    """A three-input product rule base's inputs' slopes (each (6, sets)) and its consequent
    centres, as ``_kernels.points.grade`` takes them (None: another kind of rule base)."""
    slopes = rule_base._slopes
    if rule_base.mode != "product" or len(slopes) != 3:
        return None
    s1, s2, s3 = (np.ascontiguousarray(np.stack(s), dtype=np.float64) for s in slopes)
    return s1, s2, s3, np.ascontiguousarray(rule_base._centres, dtype=np.float64)


def point_features(c: _CornerContext) -> _PointFeatures:
    """``features._point_features`` in one compiled call (``_kernels.points``; two, with the
    rule base's own grading between them, for a rule base :func:`grading_tables` has no
    tables of). Raises :class:`~fuzzypos.features.types.FeatureError` where the context's
    arrays disagree (sizes, indices)."""
    cfg, lines, rule_base = c.cfg, c.lines, c.bases.virtual_points
    tables = grading_tables(rule_base)
    vp, ap, m = cfg.virtual_points, cfg.angular_points, cfg.matching
    params = np.array([
        math.sin(vp.min_intersection_angle), vp.max_distance * c.line_distance_scale,
        c.line_distance_scale, vp.max_uncertainty, c.angle_increment, vp.merge_distance,
    ])  # fmt: skip
    flags = np.array(
        [ap.refine, ap.pair_unrefined, m.use_break_points, m.use_angular_points,
         m.use_virtual_points], dtype=np.bool_,
    )  # fmt: skip
    from .._kernels import points as kernel

    i64 = np.int64
    line_args = (
        f64(lines.normal), f64(lines.distance), f64(lines.centre), f64(lines.uncertainty),
        np.ascontiguousarray(lines.segment, dtype=i64),
        np.ascontiguousarray(c.seg_before, dtype=i64),
        np.ascontiguousarray(c.seg_after, dtype=i64),
    )  # fmt: skip
    corners = (
        np.ascontiguousarray(c.corner_a, dtype=i64), np.ascontiguousarray(c.corner_b, dtype=i64),
        f64(c.corner_dv),
    )  # fmt: skip
    grades = _NO_GRADES
    if tables is None:  # the rule base grades the kernel's inputs
        ok, *_candidates, g1, g2, g3 = kernel.grading_inputs(*line_args, *corners, params)
        if not ok:
            raise FeatureError(_INCONSISTENT)
        grades = f64(rule_base(g1, g2, g3))
        tables = (_NO_TABLE, _NO_TABLE, _NO_TABLE, _NO_GRADES)
    done, xy, u, ints, kinds = kernel.point_features(
        *line_args, np.ascontiguousarray(c.corner_index, dtype=i64), f64(c.corner_xy),
        np.ascontiguousarray(c.joined, dtype=np.bool_), *corners, f64(c.kept_points),
        f64(c.kept_uncertainty), f64(c.kept_ranges),
        np.ascontiguousarray(c.break_mask, dtype=np.bool_), *tables,
        float(rule_base._centre_lo), float(rule_base._centre_hi), grades, params, flags,
    )  # fmt: skip
    if not done:
        raise FeatureError(_INCONSISTENT)
    na, nv, nb, nk = (int(v) for v in ints[:4])
    o = (0, na, na + nv, na + nv + nb, na + nv + nb + nk)

    def part(k: int, kind: int | NDArray[np.int8]) -> FeaturePoints:
        """Rows ``o[k]:o[k + 1]`` of the packed points, all of ``kind`` or of those kinds."""
        n = o[k + 1] - o[k]
        of_kind = np.full(n, kind, dtype=np.int8) if isinstance(kind, int) else kind
        return FeaturePoints(xy[o[k] : o[k + 1]], u[o[k] : o[k + 1]], of_kind)

    virtual_lines = ints[4:].reshape(nv, 2)
    return (
        part(0, ANGULAR_POINT), part(1, VIRTUAL_ANGULAR_POINT), virtual_lines,
        part(2, BREAK_POINT), part(3, kinds),
    )  # fmt: skip
