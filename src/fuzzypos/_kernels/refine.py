"""The point-to-line refinement as one compiled loop: pairing every point with the nearest
surface point (through the surface's grid, built once per local map; a point that stays
nearer to its last nearest than the bound its last search left on every other point, less
how far it moved, keeps its nearest without a search) and each pair's robust weight and
terms of the normal equations in the same pass, the corridor's hold and the prior, the 3×3
solve, per Gauss-Newton iteration. The reference is ``refine`` of
``tests/oracles/matching.py``, the same steps in numpy with a KD-tree query per iteration. Also the
inputs it is given: the scan points' weights (``Refiner.points``) and a keyframe's surface
normals (``surface_points``)."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from ._jit import inlined, kernel
from ._select import kth_smallest_in, median
from .grid import frame_of, nearest_in

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

#: ``params`` of :func:`refine`, in order
PARAMS = (
    "residual_scale",
    "point_sigma",
    "degenerate_ratio",
    "hold_tolerance",
    "trim_floor",
    "converged_translation",
    "converged_rotation",
    "trim_sigmas",
    "pairing_spacing",
    "min_distance",
)
#: the status :func:`refine` returns
OK, TOO_FEW_PAIRS, SINGULAR = 0, 1, 2
#: a point's movement bound is widened by this (m), past the rounding of its position
_SLACK = 1e-9


@inlined
def _pair(
    points: FloatArray,
    radius: FloatArray,
    weights: FloatArray,
    pose: FloatArray,
    moved: FloatArray,
    gate: float,
    reach: FloatArray,
    surface: tuple[FloatArray, IntArray, IntArray, FloatArray],
    scale: float,
    sigma2: float,
    trimming: bool,
    out: tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray],
    state: tuple[IntArray, FloatArray, FloatArray],
) -> tuple[int, float, float, float]:
    """The points moved by ``pose``, each paired with the nearest reference point within
    ``gate`` (or its own ``reach``, where larger; ``reach`` empty: the gate alone), and each
    pair weighed. ``out`` = (rows, w, absr, H, g): rows of ``rows`` for the paired points, in
    order, the Jacobian (n_x, n_y, dr/dθ) of the residual r = n·(T·p − q) and r; ``w`` the
    pair's weight (both points' certainty times Huber's at ``scale``, over σ² = ``sigma2``),
    ``absr`` |r|; unless ``trimming`` (whose cut needs every weight first) ``H`` = Σ w J Jᵀ
    and ``g`` = Σ w J r, in the same pass (the sums in the pairs' order, as pass by pass).
    Returns how many paired and the translation block ``(a, b, c)`` of Σ w J Jᵀ.

    ``surface``: the grid's geometry, shape and cells, and ``table``, the reference points
    in the grid's order (x, y, n_x, n_y, weight). ``state`` = (near, far, seen), what the
    last search left spares the next iterations' searches: ``near[i]``, the two
    grid entries nearest to point i then (−1: none), ``far[i]`` how far every other entry lay
    at least (:func:`fuzzypos._kernels.grid.nearest_in`), less how far the point moved
    since (``moved``: the pose's |Δx| + |Δy| and |Δθ| since the last iteration, with
    ``radius`` the points' distances from the origin, bounds that); while one of the two is
    nearer than that, the nearer of them is the point's nearest. Where that bound fails,
    ``seen[i]`` (where the point was at its last search, and its bound then) gives the exact
    way it moved since, before a search."""
    geometry, shape, cells, table = surface
    frame = frame_of(geometry, shape)
    rows, w, absr, H, g = out
    near, far, seen = state
    c, s = math.cos(pose[2]), math.sin(pose[2])
    a = b = cc = 0.0
    h02 = h10 = h12 = h20 = h21 = h22 = 0.0
    g0 = g1 = g2 = 0.0
    spread = reach.shape[0] > 0
    m = 0
    for i in range(points.shape[0]):
        rx = c * points[i, 0] - s * points[i, 1]
        ry = s * points[i, 0] + c * points[i, 1]
        qx, qy = rx + pose[0], ry + pose[1]
        bound = reach[i] if spread and reach[i] > gate else gate
        lower = far[i] - (moved[0] + moved[1] * radius[i] + _SLACK)
        k, other = near[i, 0], near[i, 1]
        d2 = math.inf
        if k >= 0:
            dx, dy = table[k, 0] - qx, table[k, 1] - qy
            d2 = dx * dx + dy * dy
            if other >= 0:
                dx, dy = table[other, 0] - qx, table[other, 1] - qy
                e2 = dx * dx + dy * dy
                if e2 < d2 or (e2 == d2 and other < k):  # (the first of equal ones)
                    k, other, d2 = other, k, e2
                    near[i, 0], near[i, 1] = k, other
        hit = lower > 0.0 and d2 < lower * lower
        if not (hit or lower >= bound):  # the bound less the way since the search, exactly
            dx, dy = qx - seen[i, 0], qy - seen[i, 1]
            lower = seen[i, 2] - (math.sqrt(dx * dx + dy * dy) + _SLACK)
            hit = lower > 0.0 and d2 < lower * lower
        if hit:  # the nearer of the two is the nearest
            far[i] = lower
        elif lower >= bound:  # the two and every other point lie beyond the bound
            far[i] = lower
            continue
        else:
            k, d2, other, far[i] = nearest_in(qx, qy, bound, math.sqrt(d2), frame, cells, table)
            near[i, 0], near[i, 1] = k, other
            seen[i, 0], seen[i, 1], seen[i, 2] = qx, qy, far[i]
        if not d2 < bound * bound:
            continue
        nx, ny = table[k, 2], table[k, 3]
        j0, j1, j2 = nx, ny, nx * (-ry) + ny * rx  # d r / d θ
        res = nx * (qx - table[k, 0]) + ny * (qy - table[k, 1])
        rows[m, 0], rows[m, 1], rows[m, 2], rows[m, 3] = j0, j1, j2, res
        r = abs(res)
        absr[m] = r
        huber = 1.0 if r <= scale else scale / max(r, 1e-12)
        wk = weights[i] * table[k, 4] * huber / sigma2
        w[m] = wk
        m += 1
        ja = wk * j0
        a, b, cc = a + ja * j0, b + ja * j1, cc + wk * j1 * j1
        if not trimming:  # (a, b and c are H's first two entries of its first two rows)
            g0, h02 = g0 + ja * res, h02 + ja * j2
            ja = wk * j1
            g1, h10, h12 = g1 + ja * res, h10 + ja * j0, h12 + ja * j2
            ja = wk * j2
            g2, h20, h21, h22 = g2 + ja * res, h20 + ja * j0, h21 + ja * j1, h22 + ja * j2
    if not trimming:
        _store(H, g, a, b, h02, h10, cc, h12, h20, h21, h22, g0, g1, g2)
    return m, a, b, cc


@inlined
def _store(
    H: FloatArray,
    g: FloatArray,
    h00: float,
    h01: float,
    h02: float,
    h10: float,
    h11: float,
    h12: float,
    h20: float,
    h21: float,
    h22: float,
    g0: float,
    g1: float,
    g2: float,
) -> None:
    """``H`` the 3×3 of those entries, ``g`` = (g0, g1, g2). (Σ (w a) b and Σ (w b) a may
    differ in their last bit: both triangles are summed.)"""
    H[0, 0], H[0, 1], H[0, 2] = h00, h01, h02
    H[1, 0], H[1, 1], H[1, 2] = h10, h11, h12
    H[2, 0], H[2, 1], H[2, 2] = h20, h21, h22
    g[0], g[1], g[2] = g0, g1, g2


@inlined
def _normal_equations(
    rows: FloatArray, w: FloatArray, m: int, H: FloatArray, g: FloatArray, square: bool
) -> None:
    """``H = Σ w J Jᵀ`` and ``g = Σ w J r`` over the first ``m`` rows (``square``: w² in ``H``)."""
    h00 = h01 = h02 = h10 = h11 = h12 = h20 = h21 = h22 = 0.0
    g0 = g1 = g2 = 0.0
    for k in range(m):
        wk = w[k] * w[k] if square else w[k]
        j0, j1, j2, r = rows[k, 0], rows[k, 1], rows[k, 2], rows[k, 3]
        ja = wk * j0
        g0 += ja * r
        h00 += ja * j0
        h01 += ja * j1
        h02 += ja * j2
        ja = wk * j1
        g1 += ja * r
        h10 += ja * j0
        h11 += ja * j1
        h12 += ja * j2
        ja = wk * j2
        g2 += ja * r
        h20 += ja * j0
        h21 += ja * j1
        h22 += ja * j2
    _store(H, g, h00, h01, h02, h10, h11, h12, h20, h21, h22, g0, g1, g2)


@inlined
def _trim(
    w: FloatArray, absr: FloatArray, m: int, sigmas: float, floor: float, scratch: FloatArray
) -> None:
    """Weight 0 for residuals beyond ``sigmas`` × the upper median of |r| (at least ``floor``;
    ``scratch``, at least ``m`` long, for the selection's copy)."""
    med = kth_smallest_in(absr[:m], m // 2, scratch)
    cut = max(sigmas * med, floor)
    for k in range(m):
        if absr[k] > cut:
            w[k] = 0.0


@inlined
def _hold(
    a: float,
    b: float,
    c: float,
    H: FloatArray,
    g: FloatArray,
    pose: FloatArray,
    start_xy: FloatArray,
    hold_xy: FloatArray,
    ratio: float,
    tolerance: float,
    term: FloatArray,
) -> bool:
    """The corridor's hold (``_hold_degenerate`` of the reference): where the translation block
    ``(a, b, c)`` fixes one direction less than ``ratio`` times the other, a term along it on
    ``H`` and ``g`` toward the start's value (within ``tolerance`` of the hold's) or the hold's.
    ``term`` gets the term added to ``H``; returns whether it holds the start's value."""
    for i in range(3):
        for j in range(3):
            term[i, j] = 0.0
    half = math.hypot(0.5 * (a - c), b)
    lo, hi = 0.5 * (a + c) - half, 0.5 * (a + c) + half
    if not lo < ratio * hi:
        return False
    if abs(b) > 1e-12 * hi:
        vx, vy = b, lo - a
    elif a <= c:
        vx, vy = 1.0, 0.0
    else:
        vx, vy = 0.0, 1.0
    norm = math.hypot(vx, vy)
    vx, vy = vx / norm, vy / norm
    along_start = vx * (start_xy[0] - hold_xy[0]) + vy * (start_xy[1] - hold_xy[1])
    on_start = bool(abs(along_start) <= tolerance)
    tx, ty = (start_xy[0], start_xy[1]) if on_start else (hold_xy[0], hold_xy[1])
    term[0, 0], term[0, 1] = hi * vx * vx, hi * vx * vy
    term[1, 0], term[1, 1] = hi * vy * vx, hi * vy * vy
    for i in range(2):
        for j in range(2):
            H[i, j] += term[i, j]
    along = vx * (pose[0] - tx) + vy * (pose[1] - ty)
    g[0] += hi * vx * along
    g[1] += hi * vy * along
    return on_start


@inlined
def _solve_in_place(M: FloatArray, v: FloatArray, x: FloatArray) -> bool:
    """``x = M⁻¹ v`` for a 3×3 ``M`` by Gaussian elimination with partial pivoting (as
    LAPACK's dgesv), on ``M`` and ``v`` themselves (left eliminated: no copies); False where
    a pivot is exactly zero (numpy's LinAlgError)."""
    for col in range(3):
        p = col
        for r in range(col + 1, 3):
            if abs(M[r, col]) > abs(M[p, col]):
                p = r
        if M[p, col] == 0.0:
            return False
        if p != col:
            for k in range(3):
                M[col, k], M[p, k] = M[p, k], M[col, k]
            v[col], v[p] = v[p], v[col]
        for r in range(col + 1, 3):
            f = M[r, col] / M[col, col]
            for k in range(col, 3):
                M[r, k] -= f * M[col, k]
            v[r] -= f * v[col]
    for r in range(2, -1, -1):
        acc = v[r]
        for k in range(r + 1, 3):
            acc -= M[r, k] * x[k]
        x[r] = acc / M[r, r]
    return True


@inlined
def _wrap(a: float) -> float:
    """An angle wrapped into [−π, π) (Python's floored modulo, as the reference)."""
    return (a + math.pi) % (2 * math.pi) - math.pi


@inlined
def _add_prior(
    H: FloatArray,
    g: FloatArray,
    pose: FloatArray,
    prior: FloatArray,
    prior_diag: FloatArray,
    prior_info: FloatArray,
    full_prior: bool,
) -> None:
    """The prior as one more measurement: its diagonal information, or the full 3×3."""
    d0, d1 = pose[0] - prior[0], pose[1] - prior[1]
    d2 = _wrap(pose[2] - prior[2])
    for i in range(3):
        if full_prior:
            H[i, 0] += prior_info[i, 0]
            g[i] += prior_info[i, 0] * d0
            H[i, 1] += prior_info[i, 1]
            g[i] += prior_info[i, 1] * d1
            H[i, 2] += prior_info[i, 2]
            g[i] += prior_info[i, 2] * d2
        else:
            H[i, i] += prior_diag[i]
            g[i] += prior_diag[i] * (d0 if i == 0 else (d1 if i == 1 else d2))


@inlined
def _reach(spacing: FloatArray, pairing_spacing: float, min_distance: float) -> FloatArray:
    """How far each point may pair by its own beam ``spacing`` (``pairing_spacing`` of them);
    empty where none reaches beyond ``min_distance`` (the fixed distances decide) or no
    spacing is given."""
    n = spacing.shape[0]
    reach = np.empty(n)
    beyond = False
    if pairing_spacing > 0.0:
        for i in range(n):
            reach[i] = pairing_spacing * spacing[i]
            beyond = beyond or reach[i] > min_distance
    return reach if beyond else reach[:0]


@kernel
def refine(
    geometry: FloatArray,
    shape: IntArray,
    cells: IntArray,
    table: FloatArray,
    points: FloatArray,
    weights: FloatArray,
    start: FloatArray,
    prior: FloatArray,
    hold_xy: FloatArray,
    gates: FloatArray,
    spacing: FloatArray,
    params: FloatArray,
    iterations: int,
    prior_diag: FloatArray,
    prior_info: FloatArray,
    full_prior: bool,
) -> tuple[int, int, int, bool, FloatArray]:
    """The whole refinement (``refine_point_to_line``): status (OK, TOO_FEW_PAIRS, SINGULAR),
    how many paired at the last iteration, how many of those within half the Huber scale,
    whether the hold holds the start, and one (4, 3, 3) array (one to return, not four): the
    pose (its first row), the points' information, the hold's term and the gradient's
    covariance σ_r² Σ w² J Jᵀ (σ_r² the residuals' variance). The reference: its
    grid's ``geometry``, ``shape`` and ``cells`` (``start``) and ``table``, its points in the
    grid's order (x, y, the normal's x and y, the weight). ``params`` as :data:`PARAMS`;
    ``spacing``, each point's beam spacing at its range (empty: none)."""
    scale, sigma, ratio, tolerance = params[0], params[1], params[2], params[3]
    trim_floor, conv_t, conv_r, trim_sigmas = params[4], params[5], params[6], params[7]
    reach = _reach(spacing, params[8], params[9])
    sigma2 = sigma**2
    n = points.shape[0]
    rows = np.empty((n, 4))
    w, absr, scratch = np.empty(n), np.empty(n), np.empty(n)
    H, g = np.empty((3, 3)), np.empty(3)
    result, delta, last = np.zeros((4, 3, 3)), np.empty(3), np.zeros(3)
    pose, info, term, gradient = result[0, 0], result[1], result[2], result[3]
    near = np.full((n, 2), -1, dtype=np.int64)  # each point's two nearest at its last search
    far, radius, moved = np.zeros(n), np.empty(n), np.zeros(2)
    seen = np.zeros((n, 3))  # where each point was at its last search, and its bound then
    for i in range(n):  # (its rounding far below _SLACK: cheaper than math.hypot)
        radius[i] = math.sqrt(points[i, 0] * points[i, 0] + points[i, 1] * points[i, 1])
    surface, out, state = (geometry, shape, cells, table), (rows, w, absr, H, g), (near, far, seen)
    pose[0], pose[1], pose[2] = start[0], start[1], start[2]
    start_xy = start[:2].copy()
    trimming, on_start, m = False, False, 0
    for it in range(iterations):
        gate = gates[min(it, gates.shape[0] - 1)]
        m, a, b, c = _pair(
            points, radius, weights, pose, moved, gate, reach, surface, scale, sigma2,
            trimming, out, state,
        )  # fmt: skip
        if m < 3:
            return TOO_FEW_PAIRS, m, 0, False, result
        if trimming:
            _trim(w, absr, m, trim_sigmas, trim_floor, scratch)
            _normal_equations(rows, w, m, H, g, False)
        for i in range(3):
            for j in range(3):
                info[i, j] = H[i, j]
        on_start = _hold(a, b, c, H, g, pose, start_xy, hold_xy, ratio, tolerance, term)
        _add_prior(H, g, pose, prior, prior_diag, prior_info, full_prior)
        if not _solve_in_place(H, g, delta):
            return SINGULAR, m, 0, False, result
        for i in range(3):
            pose[i] -= delta[i]
        moved[0], moved[1] = abs(delta[0]) + abs(delta[1]), abs(delta[2])
        if it >= gates.shape[0] - 1 and (
            (moved[0] < conv_t and moved[1] < conv_r)
            or (  # a two-cycle: back where it stood two steps before (_converged of the reference)
                it >= gates.shape[0]
                and abs(delta[0] + last[0]) + abs(delta[1] + last[1]) < conv_t
                and abs(delta[2] + last[2]) < conv_r
            )
        ):
            if trimming:
                break
            trimming = True  # converged: trim the false pairs and converge again
        last[0], last[1], last[2] = delta[0], delta[1], delta[2]
    pose[2] = _wrap(pose[2])
    close = 0
    used, clipped = 0, 0.0
    for k in range(m):
        if absr[k] < 0.5 * scale:
            close += 1
        if w[k] > 0.0:
            used += 1
            r = min(absr[k], scale)
            clipped += r * r
    variance = scale * scale if used <= 3 else clipped / (used - 3)
    _normal_equations(rows, w, m, gradient, g, True)
    for i in range(3):
        for j in range(3):
            gradient[i, j] = variance * gradient[i, j]
    return OK, m, close, on_start, result


#: ``checks`` of :func:`refine_both`, in order
CHECKS = (
    "also_from_odometry",
    "both_distance",
    "both_angle",
    "both_min_gain",
    "min_points",
    "min_inlier_fraction",
    "max_correction",
)
#: which fit :func:`refine_both` returns
NEITHER, FROM_START, FROM_HOLD = 0, 1, 2


@inlined
def _trusted(
    status: int, paired: int, n: int, result: FloatArray, start: FloatArray, checks: FloatArray
) -> bool:
    """Whether a fit counts (``Refiner.fit``): it converged, at least ``min_points`` and the
    ``min_inlier_fraction`` of the scan's points paired, and it moved at most
    ``max_correction`` from its ``start``."""
    if status != OK or paired < checks[4] or paired / n < checks[5]:
        return False
    return not math.hypot(result[0, 0, 0] - start[0], result[0, 0, 1] - start[1]) > checks[6]


@kernel
def refine_both(
    geometry: FloatArray,
    shape: IntArray,
    cells: IntArray,
    table: FloatArray,
    points: FloatArray,
    weights: FloatArray,
    start: FloatArray,
    prior: FloatArray,
    hold: FloatArray,
    gates: FloatArray,
    spacing: FloatArray,
    params: FloatArray,
    iterations: int,
    prior_diag: FloatArray,
    start_info: FloatArray,
    full_start: bool,
    hold_info: FloatArray,
    full_hold: bool,
    checks: FloatArray,
) -> tuple[int, int, int, bool, FloatArray]:
    """``Refiner.refine`` off a search in one call: the fit from ``start`` held to ``prior``
    (its information ``start_info``, the full 3×3 where ``full_start``, else the diagonal
    ``prior_diag``) and, where the start and the odometry's ``hold`` differ by more than
    ``both_distance`` or ``both_angle`` (``checks`` as :data:`CHECKS`), the fit from ``hold``
    held to it (``hold_info``, ``full_hold``); each counts as ``Refiner.fit`` says
    (:func:`_trusted`), and the one from the hold is kept where it puts ``both_min_gain`` more
    of the scan close to its surfaces. Returns which (:data:`NEITHER`, :data:`FROM_START`,
    :data:`FROM_HOLD`) and that fit's :func:`refine` values."""
    n = points.shape[0]
    status, paired, close, on_start, result = refine(
        geometry, shape, cells, table, points, weights, start, prior, hold, gates, spacing,
        params, iterations, prior_diag, start_info, full_start,
    )  # fmt: skip
    which = FROM_START if _trusted(status, paired, n, result, start, checks) else NEITHER
    differ = (
        math.hypot(start[0] - hold[0], start[1] - hold[1]) > checks[1]
        or abs(start[2] - hold[2]) > checks[2]
    )
    if checks[0] != 0.0 and differ:
        status2, paired2, close2, on_start2, result2 = refine(
            geometry, shape, cells, table, points, weights, hold, hold, hold, gates, spacing,
            params, iterations, prior_diag, hold_info, full_hold,
        )  # fmt: skip
        if _trusted(status2, paired2, n, result2, hold, checks) and (
            which == NEITHER or close2 / n > close / n + checks[3]
        ):
            return FROM_HOLD, paired2, close2, on_start2, result2
    return which, paired, close, on_start, result


#: ``weighing`` of :func:`weigh_and_refine_both`, in order (``scan_weights``' settings)
WEIGHING = ("angle_increment", "weight_floor", "length_weight_max", "length_cap")


@kernel
def weigh_and_refine_both(
    geometry: FloatArray,
    shape: IntArray,
    cells: IntArray,
    table: FloatArray,
    points: FloatArray,
    ranges: FloatArray,
    uncertainty: FloatArray,
    weighing: FloatArray,
    start: FloatArray,
    prior: FloatArray,
    hold: FloatArray,
    gates: FloatArray,
    params: FloatArray,
    iterations: int,
    prior_diag: FloatArray,
    start_info: FloatArray,
    full_start: bool,
    hold_info: FloatArray,
    full_hold: bool,
    checks: FloatArray,
) -> tuple[int, int, int, bool, FloatArray]:
    """:func:`refine_both` of the points weighed and spaced as :func:`scan_weights` weighs them
    from their ``ranges`` and ``uncertainty`` (``weighing`` as :data:`WEIGHING`), in the same
    call: two arrays fewer to hand to Python and back."""
    w, spacing = _weighed(
        points, ranges, uncertainty, weighing[0], weighing[1], weighing[2], weighing[3]
    )
    return refine_both(
        geometry, shape, cells, table, points, w, start, prior, hold, gates, spacing, params,
        iterations, prior_diag, start_info, full_start, hold_info, full_hold, checks,
    )  # fmt: skip


@kernel
def surface_table(
    xy: FloatArray, normal: FloatArray, weight: FloatArray, order: IntArray
) -> FloatArray:
    """:func:`refine`'s ``table``: the surface's points in the grid's ``order`` (``xy``
    already in it), a row each: x, y, the normal's x and y, the weight."""
    n = order.shape[0]
    table = np.empty((n, 5))
    for k in range(n):
        j = order[k]
        table[k, 0], table[k, 1] = xy[k, 0], xy[k, 1]
        table[k, 2], table[k, 3] = normal[j, 0], normal[j, 1]
        table[k, 4] = weight[j]
    return table


@kernel
def scan_weights(
    points: FloatArray,
    ranges: FloatArray,
    uncertainty: FloatArray,
    angle_increment: float,
    weight_floor: float,
    length_weight_max: float,
    length_cap: float,
) -> tuple[FloatArray, FloatArray]:
    """Each scan point's weight in the refinement (``fuzzypos.pipeline.refine.Refiner.points``):
    its certainty 1 − u (at least ``weight_floor``) times the stretch of surface it stands for
    over the scan's median (within [1/max, max]; ``length_weight_max`` 1: not at all); and
    the beam spacing at each point's range (``ranges · |angle_increment|``)."""
    return _weighed(
        points, ranges, uncertainty, angle_increment, weight_floor, length_weight_max, length_cap
    )


@inlined
def _weighed(
    points: FloatArray,
    ranges: FloatArray,
    uncertainty: FloatArray,
    angle_increment: float,
    weight_floor: float,
    length_weight_max: float,
    length_cap: float,
) -> tuple[FloatArray, FloatArray]:
    """:func:`scan_weights`' weights and beam spacings."""
    n = points.shape[0]
    w = np.empty(n)
    spacing = abs(angle_increment)
    at_range = np.empty(n)
    for i in range(n):
        w[i] = min(max(1.0 - uncertainty[i], weight_floor), 1.0)
        at_range[i] = ranges[i] * spacing
    if not length_weight_max > 1.0:
        return w, at_range
    length = np.empty(n)
    if n < 2:
        for i in range(n):
            length[i] = at_range[i]
    else:
        d_prev = 0.0
        for i in range(n):  # the distance to the nearer neighbour along the scan, capped
            d_next = 0.0
            if i < n - 1:
                d_next = math.hypot(
                    points[i + 1, 0] - points[i, 0], points[i + 1, 1] - points[i, 1]
                )
            if i == 0:
                near = d_next
            elif i == n - 1:
                near = d_prev
            else:
                near = min(d_prev, d_next)
            length[i] = min(near, length_cap * at_range[i])
            d_prev = d_next
    mid = median(length)
    if mid > 0.0:
        lo = 1.0 / length_weight_max
        for i in range(n):
            w[i] = w[i] * min(max(length[i] / mid, lo), length_weight_max)
    return w, at_range


@kernel
def _agree(ax: float, ay: float, bx: float, by: float, tan_bend: float) -> bool:
    """Two chords agree in direction within the bend whose tangent is ``tan_bend``."""
    cross = ax * by - ay * bx
    dot = ax * bx + ay * by
    return dot > 0 and abs(cross) <= tan_bend * dot


@kernel
def surface_normals(
    xy: FloatArray,
    ranges: FloatArray,
    uncertainty: FloatArray,
    params: FloatArray,
    step: int,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """``fuzzypos.matching.surface.surface_points``: the points on a straight stretch of
    their run (consecutive points within ``neighbour_distance`` or ``neighbour_ratio`` × their
    range), their normals from the chord between their ``step``-th neighbours (next to a
    corner the side that runs straight on) and their weights; ``params`` = (neighbour
    distance, neighbour ratio, tan of the bend, weight floor)."""
    n = xy.shape[0]
    distance, ratio, tan_bend, floor = params[0], params[1], params[2], params[3]
    first, last = np.empty(n, dtype=np.int64), np.empty(n, dtype=np.int64)
    start = 0
    for i in range(n):  # the runs of linked points
        if i > 0:
            gap = math.hypot(xy[i, 0] - xy[i - 1, 0], xy[i, 1] - xy[i - 1, 1])
            if not gap <= max(distance, ratio * min(ranges[i], ranges[i - 1])):
                start = i
        first[i] = start
    end = n - 1
    for i in range(n - 1, -1, -1):
        if i < n - 1 and first[i + 1] == i + 1:
            end = i
        last[i] = end
    out_xy, out_n, out_w = np.empty((n, 2)), np.empty((n, 2)), np.empty(n)
    m = 0
    for i in range(n):
        p, q = max(i - step, first[i]), min(i + step, last[i])
        if not (q > i and p < i):
            continue
        p2, q2 = max(p - step, first[i]), min(q + step, last[i])
        lx, ly = xy[i, 0] - xy[p, 0], xy[i, 1] - xy[p, 1]
        rx, ry = xy[q, 0] - xy[i, 0], xy[q, 1] - xy[i, 1]
        if _agree(lx, ly, rx, ry, tan_bend):  # straight: the chord across the point
            cx, cy = xy[q, 0] - xy[p, 0], xy[q, 1] - xy[p, 1]
        elif p2 < p and _agree(xy[p, 0] - xy[p2, 0], xy[p, 1] - xy[p2, 1], lx, ly, tan_bend):
            cx, cy = lx, ly
        elif q2 > q and _agree(rx, ry, xy[q2, 0] - xy[q, 0], xy[q2, 1] - xy[q, 1], tan_bend):
            cx, cy = rx, ry
        else:
            continue
        length = math.hypot(cx, cy)
        if not length > 1e-9:
            continue
        out_xy[m, 0], out_xy[m, 1] = xy[i, 0], xy[i, 1]
        out_n[m, 0], out_n[m, 1] = -cy / length, cx / length
        out_w[m] = min(max(1.0 - uncertainty[i], floor), 1.0)
        m += 1
    return out_xy[:m].copy(), out_n[:m].copy(), out_w[:m].copy()
