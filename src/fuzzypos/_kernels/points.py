"""The point features of one scan (``fuzzypos.features.extract._point_features``) in one
compiled call (its numpy reference: ``point_features`` of ``tests/oracles/features.py``): the
line pairs that meet at a real angular point, the virtual angular points' candidates (§3.6,
eq. 10), one fuzzy grading of them and of the joined real corners (eq. 11–12: a three-input
product rule base, eq. 4's centre average), the angular points (refined to their lines'
intersection where configured, SPEC step 5), the break points and the merged points of
interest (§3.7), NaN's order and comparisons numpy's own. A rule base of another kind
(Mamdani's) grades :func:`grading_inputs`' inputs between two calls."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from ._jit import inlined, kernel

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]
Int8Array = NDArray[np.int8]

_LARGEST = float(np.finfo(np.float64).max)

#: ``flags`` of :func:`point_features`, in order
FLAGS = ("refine", "pair_unrefined", "use_break_points", "use_angular_points",
         "use_virtual_points")  # fmt: skip
#: ``params`` of :func:`point_features`, in order
PARAMS = ("min_sine", "max_distance", "line_distance_scale", "max_uncertainty",
          "angle_increment", "merge_distance")  # fmt: skip


@kernel
def _index(pos: IntArray, s: int) -> int:
    """``pos[s]`` as numpy indexes (a negative ``s`` from the end)."""
    return int(pos[s] if s >= 0 else pos[pos.shape[0] + s])


@kernel
def _membership(x: float, slopes: FloatArray, k: int) -> float:
    """``fuzzypos.fuzzy._memberships`` of ``x`` in set ``k`` (``slopes`` (6, sets): the
    effective left foot, 1/rise, right foot, 1/fall, the range's ends; no NaN)."""
    v = min(max(x, slopes[4, 0]), slopes[5, 0])
    rise = (v - slopes[0, k]) * slopes[1, k]
    fall = (slopes[2, k] - v) * slopes[3, k]
    mu: float = max(min(min(rise, fall), 1.0), 0.0)
    return mu


@kernel
def grade(
    x1: FloatArray,
    x2: FloatArray,
    x3: FloatArray,
    s1: FloatArray,
    s2: FloatArray,
    s3: FloatArray,
    centres: FloatArray,
    lo: float,
    hi: float,
) -> FloatArray:
    """A three-input product rule base (``RuleBase.__call__``, eq. 4): the firing strengths
    μ₁·μ₂·μ₃ of every rule (in the rule table's order), Σ w ȳ / Σ w (0 where no rule fires),
    clamped to the centres' range. ``s1``–``s3``: each input's slopes (:func:`_membership`);
    ``centres`` the rules' consequent centres, flattened. A NaN input grades NaN (numpy's
    memberships, sums and clamping all carry it through)."""
    n = x1.shape[0]
    k1, k2, k3 = s1.shape[1], s2.shape[1], s3.shape[1]
    mu2, mu3 = np.empty(k2), np.empty(k3)
    out = np.empty(n)
    for i in range(n):
        if math.isnan(x1[i]) or math.isnan(x2[i]) or math.isnan(x3[i]):
            out[i] = math.nan
            continue
        for b in range(k2):
            mu2[b] = _membership(x2[i], s2, b)
        for c in range(k3):
            mu3[c] = _membership(x3[i], s3, c)
        num = den = 0.0
        for a in range(k1):
            m1 = _membership(x1[i], s1, a)
            for b in range(k2):
                w12 = m1 * mu2[b]
                for c in range(k3):
                    w = w12 * mu3[c]
                    num += w * centres[(a * k2 + b) * k3 + c]
                    den += w
        value = num / den if den > 0.0 else 0.0
        out[i] = min(max(value, lo), hi)
    return out


@inlined
def _after(u: float, k: int, v: float, m: int) -> bool:
    """Whether the key (u, k) sorts after (v, m) in numpy's order (NaN after every number,
    NaNs equal to each other)."""
    if math.isnan(u) or math.isnan(v):
        if not math.isnan(v):
            return True
        if not math.isnan(u):
            return False
        return k > m
    return u > v or (u == v and k > m)


@kernel
def _merge(xy: FloatArray, u: FloatArray, kind: Int8Array, radius: float) -> IntArray:
    """The kept indices of the oracle's ``merge_duplicates``, in order: the points sorted by
    uncertainty, then kind (virtual first; ``np.lexsort``'s stable order, a NaN uncertainty
    after every number), each dropped that lies within ``radius`` of one before it in that
    order (a NaN coordinate is near nothing)."""
    n = xy.shape[0]
    keep = np.empty(n, dtype=np.int64)
    if n < 2 or not radius > 0.0:
        for i in range(n):
            keep[i] = i
        return keep
    order = np.empty(n, dtype=np.int64)
    for i in range(n):  # a stable insertion sort by (u, −kind)
        j = i
        while j > 0:
            p = order[j - 1]
            if _after(u[p], -kind[p], u[i], -kind[i]):
                order[j] = p
                j -= 1
            else:
                break
        order[j] = i
    r2 = radius * radius
    dropped = np.zeros(n, dtype=np.bool_)
    for jj in range(1, n):
        q = order[jj]
        for ii in range(jj):
            p = order[ii]
            dx, dy = xy[p, 0] - xy[q, 0], xy[p, 1] - xy[q, 1]
            if dx * dx + dy * dy < r2:
                dropped[jj] = True
                break
    m = 0
    for jj in range(n):
        if not dropped[jj]:
            keep[m] = order[jj]
            m += 1
    kept: IntArray = keep[:m].copy()
    kept.sort()
    return kept


@kernel
def _excluded_pairs(
    nl: int, segment: IntArray, seg_before: IntArray, seg_after: IntArray
) -> tuple[bool, BoolArray]:
    """Whether it is done (False: numpy would raise) and the (nl, nl) mask of the line pairs
    that meet at a real angular point (the oracle's ``_corner_line_pairs``: each corner's
    segments before and after it, by the lines' segment ids, numpy's negative indexing
    too)."""
    excluded = np.zeros((nl, nl), dtype=np.bool_)
    if nl < 2 or seg_before.shape[0] == 0:
        return True, excluded
    top = -1
    for k in range(nl):
        top = max(top, segment[k])
    for k in range(seg_before.shape[0]):
        top = max(top, seg_before[k], seg_after[k])
    if top < 0:
        return False, excluded  # (numpy's negative dimensions or IndexError)
    pos = np.full(top + 1, -1, dtype=np.int64)
    for k in range(nl):
        if segment[k] < -pos.shape[0]:
            return False, excluded  # (numpy's IndexError)
        pos[segment[k] if segment[k] >= 0 else pos.shape[0] + segment[k]] = k
    for k in range(seg_before.shape[0]):
        if min(seg_before[k], seg_after[k]) < -pos.shape[0]:
            return False, excluded  # (numpy's IndexError)
        a, b = _index(pos, seg_before[k]), _index(pos, seg_after[k])
        if a >= 0 and b >= 0:
            excluded[a, b] = excluded[b, a] = True
    return True, excluded


@kernel
def candidates(
    normal: FloatArray,
    distance: FloatArray,
    centre: FloatArray,
    excluded: BoolArray,
    min_sine: float,
    max_distance: float,
) -> tuple[FloatArray, IntArray, IntArray, FloatArray]:
    """The virtual angular points' candidates (``features.extract.virtual_candidates``, in
    ``np.nonzero``'s order): the intersection of every two lines i < j at least the minimum
    angle apart and not ``excluded`` (SPEC's normal form, eq. 15–16 fixed), kept where d_v
    (eq. 10) is at most ``max_distance``; their points, lines and d_v."""
    nl = normal.shape[0]
    xy = np.empty((nl * nl, 2))
    ci, cj, cdv = np.empty(nl * nl, np.int64), np.empty(nl * nl, np.int64), np.empty(nl * nl)
    nc = 0
    for i in range(nl):
        for j in range(i + 1, nl):
            det = normal[i, 0] * normal[j, 1] - normal[i, 1] * normal[j, 0]
            if not abs(det) >= min_sine or excluded[i, j]:
                continue
            safe = det if abs(det) > 1e-12 else 1.0
            x = (distance[i] * normal[j, 1] - distance[j] * normal[i, 1]) / safe
            y = (normal[i, 0] * distance[j] - normal[j, 0] * distance[i]) / safe
            dv = 0.5 * (
                math.hypot(x - centre[i, 0], y - centre[i, 1])
                + math.hypot(x - centre[j, 0], y - centre[j, 1])
            )
            if dv <= max_distance:  # (a NaN: not near)
                xy[nc, 0], xy[nc, 1], ci[nc], cj[nc], cdv[nc] = x, y, i, j, dv
                nc += 1
    return xy[:nc], ci[:nc], cj[:nc], cdv[:nc]


@inlined
def _finite(x: float) -> float:
    """``np.nan_to_num(x)``: 0 for NaN, the largest double of its sign for an infinity."""
    if math.isnan(x):
        return 0.0
    if math.isinf(x):
        return _LARGEST if x > 0.0 else -_LARGEST
    return x


@kernel
def _angular(
    corner_index: IntArray,
    corner_xy: FloatArray,
    joined: BoolArray,
    corner_grades: FloatArray,
    kept_points: FloatArray,
    kept_u: FloatArray,
    kept_ranges: FloatArray,
    angle_increment: float,
    refine: bool,
    pair_unrefined: bool,
) -> tuple[bool, FloatArray, FloatArray, BoolArray]:
    """Whether it is done (False: numpy would raise) and the angular points: sampled, or
    refined to their lines' intersection (graded
    ``corner_grades``, the joined ones in order) where that lies within three beam spacings
    and 5 cm of the sample (SPEC step 5); which of them are paired."""
    na = corner_index.shape[0]
    xy, u = np.empty((na, 2)), np.empty(na)
    pairable = np.ones(na, dtype=np.bool_)
    for k in range(na):
        c = corner_index[k]
        xy[k, 0], xy[k, 1], u[k] = kept_points[c, 0], kept_points[c, 1], kept_u[c]
    if not refine or na == 0:
        return True, xy, u, pairable
    if joined.shape[0] != na or corner_xy.shape[0] != na:
        return False, xy, u, pairable  # (numpy's broadcasting error)
    m = 0
    for k in range(na):
        near = False
        if joined[k]:  # (the others are not near whatever their gap)
            if m >= corner_grades.shape[0]:
                return False, xy, u, pairable  # (numpy's shape mismatch)
            spacing = abs(angle_increment) * kept_ranges[corner_index[k]]
            cx, cy = corner_xy[k, 0], corner_xy[k, 1]
            gx, gy = _finite(cx) - xy[k, 0], _finite(cy) - xy[k, 1]
            near = math.hypot(gx, gy) <= 3.0 * spacing + 0.05
            if near:
                xy[k, 0], xy[k, 1], u[k] = cx, cy, corner_grades[m]
            m += 1
        if not pair_unrefined:
            pairable[k] = near
    return m == corner_grades.shape[0], xy, u, pairable


@kernel
def _interest(
    ang_xy: FloatArray,
    ang_u: FloatArray,
    pairable: BoolArray,
    v_xy: FloatArray,
    v_u: FloatArray,
    b_xy: FloatArray,
    b_u: FloatArray,
    flags: BoolArray,
) -> tuple[FloatArray, FloatArray, Int8Array]:
    """The points of interest before the merge: the break points (``flags[2]``), the
    pairable angular points (``flags[3]``) and the virtual ones (``flags[4]``), in that order,
    with their kinds (BREAK_POINT 0, ANGULAR_POINT 1, VIRTUAL_ANGULAR_POINT 2)."""
    na, nv, nb = ang_xy.shape[0], v_xy.shape[0], b_xy.shape[0]
    n = (nb if flags[2] else 0) + (nv if flags[4] else 0)
    if flags[3]:
        for k in range(na):
            n += 1 if pairable[k] else 0
    xy, u, kind = np.empty((n, 2)), np.empty(n), np.empty(n, dtype=np.int8)
    p = 0
    for part, (pxy, pu) in enumerate(((b_xy, b_u), (ang_xy, ang_u), (v_xy, v_u))):
        if not flags[2 + part]:
            continue
        for k in range(pxy.shape[0]):
            if part == 1 and not pairable[k]:
                continue
            xy[p, 0], xy[p, 1], u[p], kind[p] = pxy[k, 0], pxy[k, 1], pu[k], part
            p += 1
    return xy, u, kind


@inlined
def grading_inputs(
    normal: FloatArray,
    distance: FloatArray,
    centre: FloatArray,
    line_u: FloatArray,
    segment: IntArray,
    seg_before: IntArray,
    seg_after: IntArray,
    corner_a: IntArray,
    corner_b: IntArray,
    corner_dv: FloatArray,
    params: FloatArray,
) -> tuple[bool, FloatArray, IntArray, IntArray, FloatArray, FloatArray, FloatArray, FloatArray]:
    """The virtual angular points' candidates (:func:`candidates`, without the line pairs
    that meet at a real angular point) and the three inputs of the one grading of the joined
    real corners and the candidates (eq. 11–12: the two lines' uncertainties and d_v over the
    lines' distance scale), the corners first. Returns whether it is done (False: numpy
    would raise), the candidates' points, lines and d_v, and the inputs."""
    g = np.zeros(0)
    ok, excluded = _excluded_pairs(normal.shape[0], segment, seg_before, seg_after)
    if not ok:
        return False, np.zeros((0, 2)), np.zeros(0, np.int64), np.zeros(0, np.int64), g, g, g, g
    c_xy, c_i, c_j, c_dv = candidates(normal, distance, centre, excluded, params[0], params[1])
    nj, nc = corner_a.shape[0], c_i.shape[0]
    line_scale = params[2]
    g1, g2, g3 = np.empty(nj + nc), np.empty(nj + nc), np.empty(nj + nc)
    for k in range(nj):
        g1[k], g2[k], g3[k] = line_u[corner_a[k]], line_u[corner_b[k]], corner_dv[k] / line_scale
    for k in range(nc):
        g1[nj + k], g2[nj + k], g3[nj + k] = line_u[c_i[k]], line_u[c_j[k]], c_dv[k] / line_scale
    return True, c_xy, c_i, c_j, c_dv, g1, g2, g3


@kernel
def point_features(
    normal: FloatArray,
    distance: FloatArray,
    centre: FloatArray,
    line_u: FloatArray,
    segment: IntArray,
    seg_before: IntArray,
    seg_after: IntArray,
    corner_index: IntArray,
    corner_xy: FloatArray,
    joined: BoolArray,
    corner_a: IntArray,
    corner_b: IntArray,
    corner_dv: FloatArray,
    kept_points: FloatArray,
    kept_u: FloatArray,
    kept_ranges: FloatArray,
    break_mask: BoolArray,
    s1: FloatArray,
    s2: FloatArray,
    s3: FloatArray,
    centres: FloatArray,
    centre_lo: float,
    centre_hi: float,
    grades: FloatArray,
    params: FloatArray,
    flags: BoolArray,
) -> tuple[bool, FloatArray, FloatArray, IntArray, Int8Array]:
    """``_point_features`` of one scan's corner context (``params`` as :data:`PARAMS`, the
    virtual points' ``max_distance`` already times the lines' distance scale; ``flags`` as
    :data:`FLAGS`; ``s1``–``centre_hi`` the virtual points' rule base, :func:`grade`, or, where
    ``s1`` is empty, ``grades`` its grades of :func:`grading_inputs`' inputs, a rule base of
    another kind evaluated by the caller). Returns whether it is done (False: what numpy would
    raise at, an inconsistent context) and, packed: ``xy`` (rows: the angular points, the
    virtual ones, the break points, the points of interest), their uncertainties in the same
    order, the integers (the counts of the four, then the virtual points' line pairs, row by
    row) and the points of interest's kinds."""
    fail = (False, np.zeros((0, 2)), np.zeros(0), np.zeros(0, np.int64), np.zeros(0, np.int8))
    ok, c_xy, c_i, c_j, _c_dv, g1, g2, g3 = grading_inputs(
        normal, distance, centre, line_u, segment, seg_before, seg_after, corner_a, corner_b,
        corner_dv, params,
    )  # fmt: skip
    if not ok:
        return fail
    # one grading of the joined real corners and the candidates (eq. 11–12)
    nj, nc = corner_a.shape[0], c_i.shape[0]
    if s1.shape[0] == 0:
        if grades.shape[0] != nj + nc:
            return fail
        graded = grades
    else:
        graded = grade(g1, g2, g3, s1, s2, s3, centres, centre_lo, centre_hi)
    certain = graded[nj:] <= params[3]
    v_xy, v_u = c_xy[certain], graded[nj:][certain]
    ok, ang_xy, ang_u, pairable = _angular(
        corner_index, corner_xy, joined, graded[:nj], kept_points, kept_u, kept_ranges,
        params[4], flags[0], flags[1],
    )  # fmt: skip
    if not ok:
        return fail
    b_xy, b_u = kept_points[break_mask], kept_u[break_mask]
    poi_xy, poi_u, poi_kind = _interest(ang_xy, ang_u, pairable, v_xy, v_u, b_xy, b_u, flags)
    keep = _merge(poi_xy, poi_u, poi_kind, params[5])
    na, nv, nb, nk = ang_xy.shape[0], v_xy.shape[0], b_xy.shape[0], keep.shape[0]
    xy, u = np.empty((na + nv + nb + nk, 2)), np.empty(na + nv + nb + nk)
    o = 0
    for pxy, pu in ((ang_xy, ang_u), (v_xy, v_u), (b_xy, b_u)):
        for k in range(pxy.shape[0]):
            xy[o + k, 0], xy[o + k, 1], u[o + k] = pxy[k, 0], pxy[k, 1], pu[k]
        o += pxy.shape[0]
    kinds = np.empty(nk, dtype=np.int8)
    for k in range(nk):
        q = keep[k]
        xy[o + k, 0], xy[o + k, 1], u[o + k], kinds[k] = (
            poi_xy[q, 0],
            poi_xy[q, 1],
            poi_u[q],
            poi_kind[q],
        )
    ints = np.empty(4 + 2 * nv, dtype=np.int64)
    ints[0], ints[1], ints[2], ints[3] = na, nv, nb, nk
    v = 0
    for k in range(nc):
        if certain[k]:
            ints[4 + 2 * v], ints[5 + 2 * v] = c_i[k], c_j[k]
            v += 1
    return True, xy, u, ints, kinds
