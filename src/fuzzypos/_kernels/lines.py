"""Line-to-line matching as compiled loops: the pairing of two scans' lines and the increment
from the pairs (the references: ``pair_lines`` and ``increment_from_lines`` of
``tests/oracles/matching.py``)."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from ._jit import inlined, kernel
from ._select import median

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]

_HALF_PI = 0.5 * math.pi

#: where :func:`match_lines` reads a scan's ``nl`` lines in one flat array of floats: from its
#: element ``first``, each array's first element at ``first + k · nl`` for these ``k`` (the
#: compiled feature chain's packed floats, ``fuzzypos._kernels.packing.LAYOUT``'s ``Lines``
#: less the points' ``5n + 4m`` before them; the lengths after its 14 · nl floats), 15 · nl
#: floats in all
LINE_NORMAL, LINE_DISTANCE, LINE_CENTRE = 0, 2, 7
LINE_ANGLE_VARIANCE, LINE_DISTANCE_VARIANCE, LINE_LENGTH = 12, 13, 14
LINE_FLOATS = 15


@kernel
def pair_lines(
    prev_angle: FloatArray,
    prev_distance: FloatArray,
    prev_normal: FloatArray,
    prev_centre: FloatArray,
    prev_length: FloatArray,
    curr_angle: FloatArray,
    curr_distance: FloatArray,
    curr_centre: FloatArray,
    curr_length: FloatArray,
    pose: FloatArray,
    gates: FloatArray,
) -> tuple[IntArray, IntArray]:
    """The mutual best pairs of previous and current lines (the current moved by ``pose``):
    ``gates`` = (angle gate, distance gate, overlap margin). Indices (previous, current)."""
    n_prev, n_curr = prev_angle.shape[0], curr_angle.shape[0]
    angle_gate, distance_gate, margin = gates[0], gates[1], gates[2]
    inv_a, inv_d = 1.0 / angle_gate, 1.0 / distance_gate
    c, s = math.cos(pose[2]), math.sin(pose[2])
    cost = np.empty((n_prev, n_curr))
    for q in range(n_curr):
        ac = curr_angle[q] + pose[2]  # the current normal's angle in frame k
        d = curr_distance[q] + math.cos(ac) * pose[0] + math.sin(ac) * pose[1]
        cx = pose[0] + c * curr_centre[q, 0] - s * curr_centre[q, 1]
        cy = pose[1] + s * curr_centre[q, 0] + c * curr_centre[q, 1]
        for p in range(n_prev):
            raw = prev_angle[p] - ac
            ang = abs((raw + _HALF_PI) % math.pi - _HALF_PI)  # normals may point either way
            dd = abs(prev_distance[p] - math.copysign(1.0, math.cos(raw)) * d)
            along = prev_normal[p, 1] * (cx - prev_centre[p, 0]) - prev_normal[p, 0] * (
                cy - prev_centre[p, 1]
            )
            reach = 0.5 * (prev_length[p] + curr_length[q]) + margin
            if ang >= angle_gate or dd >= distance_gate or abs(along) > reach:
                cost[p, q] = np.inf
            else:
                cost[p, q] = ang * inv_a + dd * inv_d
    best_prev = np.zeros(n_curr, dtype=np.int64)  # the first of the least cost, per column
    for q in range(n_curr):
        for p in range(1, n_prev):
            if cost[p, q] < cost[best_prev[q], q]:
                best_prev[q] = p
    pairs = np.empty((2, n_prev), dtype=np.int64)  # rows and columns, one allocation
    rows, cols = pairs[0], pairs[1]
    m = 0
    for p in range(n_prev):
        j = 0
        for q in range(1, n_curr):
            if cost[p, q] < cost[p, j]:
                j = q
        if cost[p, j] < np.inf and best_prev[j] == p:
            rows[m], cols[m] = p, j
            m += 1
    return rows[:m], cols[:m]


@kernel
def robust_keep(values: FloatArray, floor: float, sigmas: float) -> BoolArray:
    """Values within ``sigmas`` × their median absolute deviation (at least ``floor``) of
    their median (the numpy reference: ``tests/oracles/matching.py``'s ``robust_keep``)."""
    center = median(values)
    dev = np.empty(values.shape[0])
    for i in range(values.shape[0]):
        dev[i] = abs(values[i] - center)
    cut = max(sigmas * median(dev), floor)
    keep = np.empty(values.shape[0], dtype=np.bool_)
    for i in range(values.shape[0]):
        keep[i] = dev[i] <= cut
    return keep


@kernel
def translation_consensus(
    nx: FloatArray, ny: FloatArray, rhs: FloatArray, candidates: BoolArray, tau: float, sine: float
) -> BoolArray:
    """The candidate pairs within ``tau`` of the translation two non-parallel ones (sine of
    their angle above ``sine``) fix with the least truncated squared residual (MSAC);
    every candidate where no two are so."""
    idx = np.nonzero(candidates)[0]
    k = idx.shape[0]
    if k < 3:
        return candidates
    best_score, best_tx, best_ty = np.inf, 0.0, 0.0
    found = False
    tau2 = tau * tau
    for a in range(k):
        i = idx[a]
        for b in range(a + 1, k):
            j = idx[b]
            det = nx[i] * ny[j] - ny[i] * nx[j]
            if not abs(det) > sine:
                continue
            tx = (rhs[i] * ny[j] - ny[i] * rhs[j]) / det
            ty = (nx[i] * rhs[j] - rhs[i] * nx[j]) / det
            score = 0.0
            for e in range(k):
                r = abs(tx * nx[idx[e]] + ty * ny[idx[e]] - rhs[idx[e]])
                score += min(r * r, tau2)
            if not found or score < best_score:
                best_score, best_tx, best_ty, found = score, tx, ty, True
    if not found:
        return candidates
    out = np.zeros_like(candidates)
    for e in range(k):
        i = idx[e]
        out[i] = abs(best_tx * nx[i] + best_ty * ny[i] - rhs[i]) < tau
    return out


@kernel
def increment_from_lines(
    prev_angle: FloatArray,
    prev_distance: FloatArray,
    curr_angle: FloatArray,
    curr_distance: FloatArray,
    angle_variance: FloatArray,
    distance_variance: FloatArray,
    start: FloatArray,
    prior: FloatArray,
    params: FloatArray,
) -> FloatArray:
    """The increment from paired lines (``prev_*[i]`` ↔ ``curr_*[i]``; the pairs' summed
    angle and distance variances): ``params`` = (prior sigma, trim floor angle, inlier
    distance, sine of the consensus angle, the outlier rule's sigmas)."""
    prior_sigma, trim_floor, tau, sine, sigmas = (
        params[0],
        params[1],
        params[2],
        params[3],
        params[4],
    )
    n = prev_angle.shape[0]
    work = np.empty((5, n))  # the per-pair arrays, one allocation
    raw, delta, nx, ny, rhs = work[0], work[1], work[2], work[3], work[4]
    for k in range(n):
        raw[k] = prev_angle[k] - curr_angle[k] - start[2]
        delta[k] = (raw[k] + _HALF_PI) % math.pi - _HALF_PI  # rotation left after ``start``
    keep = robust_keep(delta, trim_floor, sigmas)
    num, den = 0.0, 0.0
    for k in range(n):
        if keep[k]:
            w_a = 1.0 / angle_variance[k]
            num += w_a * delta[k]
            den += w_a
    theta = start[2] + num / den
    for k in range(n):
        # n: the mean of the previous normal and the current one rotated by θ
        turn = raw[k] - delta[k]
        half = 0.5 * (prev_angle[k] + curr_angle[k] + theta + turn)
        nx[k], ny[k] = math.cos(half), math.sin(half)
        rhs[k] = prev_distance[k] - math.copysign(1.0, math.cos(turn)) * curr_distance[k]
    consensus = translation_consensus(nx, ny, rhs, keep, tau, sine)
    lam = 1.0 / (prior_sigma * prior_sigma)
    a11, a12, a22, b1, b2 = lam, 0.0, lam, lam * prior[0], lam * prior[1]
    for k in range(n):
        if keep[k] and consensus[k]:
            w = 1.0 / distance_variance[k]
            a11 += w * nx[k] * nx[k]
            a12 += w * nx[k] * ny[k]
            a22 += w * ny[k] * ny[k]
            b1 += w * nx[k] * rhs[k]
            b2 += w * ny[k] * rhs[k]
    det = a11 * a22 - a12 * a12
    out = np.empty(3)
    out[0] = (a22 * b1 - a12 * b2) / det
    out[1] = (a11 * b2 - a12 * b1) / det
    out[2] = math.atan2(math.sin(theta), math.cos(theta))
    return out


@inlined
def _line_views(
    flat: FloatArray, first: int, nl: int
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
    """A scan's lines in ``flat`` (:data:`LINE_FLOATS`): their normals' angles (libm's atan2:
    ``Lines.normal_angle``'s within a last bit, numpy's own where it has a SIMD one),
    distances, normals, centres, lengths, angle and distance variances; views of ``flat`` but
    the angles."""
    normal = flat[first + LINE_NORMAL * nl : first + (LINE_NORMAL + 2) * nl].reshape((nl, 2))
    distance = flat[first + LINE_DISTANCE * nl : first + (LINE_DISTANCE + 1) * nl]
    centre = flat[first + LINE_CENTRE * nl : first + (LINE_CENTRE + 2) * nl].reshape((nl, 2))
    angle_variance = flat[first + LINE_ANGLE_VARIANCE * nl : first + (LINE_ANGLE_VARIANCE + 1) * nl]
    distance_variance = flat[
        first + LINE_DISTANCE_VARIANCE * nl : first + (LINE_DISTANCE_VARIANCE + 1) * nl
    ]
    length = flat[first + LINE_LENGTH * nl : first + (LINE_LENGTH + 1) * nl]
    angle = np.empty(nl)
    for k in range(nl):
        angle[k] = math.atan2(normal[k, 1], normal[k, 0])
    return angle, distance, normal, centre, length, angle_variance, distance_variance


@kernel
def line_views(
    flat: FloatArray, first: int, nl: int
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
    """:func:`match_lines`' reading of a scan's lines (for the tests)."""
    return _line_views(flat, first, nl)


@kernel
def match_lines(
    prev: FloatArray,
    prev_first: int,
    prev_n: int,
    curr: FloatArray,
    curr_first: int,
    curr_n: int,
    start: FloatArray,
    prior: FloatArray,
    gates: FloatArray,
    params: FloatArray,
    passes: int,
    min_pairs: int,
) -> tuple[bool, FloatArray, int]:
    """``fuzzypos.pipeline.feature_match.FeatureMatcher.match_lines`` in one loop: pair the
    lines from ``start``, the increment from the pairs, and again from it while it moves
    enough to change the pairs. ``prev`` and ``curr``: each scan's ``*_n`` lines from element
    ``*_first`` of one flat array (:data:`LINE_FLOATS`; the compiled feature chain's packed
    floats themselves: one array to hand over, not seven); ``gates`` = (the first pass's
    angle and distance gates, the later passes', the overlap margin, the repair fraction);
    ``params`` as :func:`increment_from_lines`. Returns whether the lines gave an increment,
    the increment and how many pairs it rests on."""
    pa, pd, pn, pc, pl, pav, pdv = _line_views(prev, prev_first, prev_n)
    ca, cd, _cn, cc, cl, cav, cdv = _line_views(curr, curr_first, curr_n)
    pose = start.copy()
    pair_gates = np.empty(3)
    pair_gates[0], pair_gates[1], pair_gates[2] = gates[0], gates[1], gates[4]
    found, n_pairs = False, 0
    for _ in range(passes):
        rows, cols = pair_lines(pa, pd, pn, pc, pl, ca, cd, cc, cl, pose, pair_gates)
        m = rows.shape[0]
        if m < min_pairs or m < 2:
            break
        paired = np.empty((6, m))  # the pairs' arrays, one allocation
        for k in range(m):
            i, j = rows[k], cols[k]
            paired[0, k], paired[1, k], paired[2, k], paired[3, k] = pa[i], pd[i], ca[j], cd[j]
            paired[4, k] = pav[i] + cav[j]
            paired[5, k] = pdv[i] + cdv[j]
        new = increment_from_lines(
            paired[0], paired[1], paired[2], paired[3], paired[4], paired[5], pose, prior, params
        )
        moved_t = abs(new[0] - pose[0]) + abs(new[1] - pose[1])
        moved_r = abs(new[2] - pose[2])
        pose = new
        found, n_pairs = True, m
        # pair again with the refined motion, unless it moved too little to change pairs
        if moved_t < gates[5] * gates[3] and moved_r < gates[5] * gates[2]:
            break
        pair_gates[0], pair_gates[1] = gates[2], gates[3]
    return found, pose, n_pairs
