"""The numpy references of ``fuzzypos.matching``'s kernels (``_kernels.search``,
``_kernels.lines``, ``_kernels.refine``, ``_kernels.surface``): the code each replaced, the
tests' oracles."""

from __future__ import annotations

import math
import weakref

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from fuzzypos.config import RefinementConfig, SearchConfig
from fuzzypos.features import Lines
from fuzzypos.geometry import stack_columns
from fuzzypos.matching import lines, search, surface
from fuzzypos.matching._robust import (
    MAD_TO_SIGMA,
    OUTLIER_SIGMAS,
    BoolArray,
    FloatArray,
    IntArray,
    index_pairs,
    median,
    outlier_cut,
)
from fuzzypos.matching.lines import _HALF_PI, LinePairs
from fuzzypos.matching.search import SearchHit, _candidates
from fuzzypos.matching.surface import Refinement, SurfacePoints, _prior_terms

_TREES: weakref.WeakKeyDictionary[SurfacePoints, cKDTree] = weakref.WeakKeyDictionary()


def kd_tree(surface: SurfacePoints) -> cKDTree:
    """A KD-tree over a surface's points (the numpy references' index; the kernels use its
    ``grid``), built once a surface."""
    tree = _TREES.get(surface)
    if tree is None:
        tree = _TREES[surface] = cKDTree(surface.xy)
    return tree


def search_start(
    reference: SurfacePoints,
    points: FloatArray,
    start: FloatArray,
    settings: SearchConfig,
    *,
    half_width: float,
    translation_half_width: float,
) -> SearchHit:
    """:func:`fuzzypos.matching.search.search_start` by KD-tree queries over all candidates,
    a chunk of rotations at a time (at most ``batch_size`` transformed points a query)."""
    start = np.asarray(start, dtype=float)
    if len(reference) == 0 or points.shape[0] == 0:
        return SearchHit(start, 0.0)
    pts, thetas, tx, ty, penalty = _candidates(
        points, start, settings, half_width, translation_half_width
    )
    return _search_numpy(reference, pts, start, thetas, tx, ty, penalty, settings)


def _search_numpy(
    reference: SurfacePoints,
    pts: FloatArray,
    start: FloatArray,
    thetas: FloatArray,
    tx: FloatArray,
    ty: FloatArray,
    penalty: FloatArray,
    settings: SearchConfig,
) -> SearchHit:
    """The candidates scored by KD-tree queries, a chunk of rotations at a time (the compiled
    kernel's reference): the best start and its fraction."""
    gate = settings.gate
    best_score, best_fraction, best = -np.inf, 0.0, start
    chunk = max(1, settings.batch_size // (tx.size * pts.shape[0]))
    for c0 in range(0, thetas.size, chunk):  # bounded memory: a chunk of rotations at a time
        th = thetas[c0 : c0 + chunk]
        c, s = np.cos(th)[:, None], np.sin(th)[:, None]
        rx = c * pts[None, :, 0] - s * pts[None, :, 1]  # (rotations, points)
        ry = s * pts[None, :, 0] + c * pts[None, :, 1]
        qx = rx[:, None, :] + tx[None, :, None]  # (rotations, translations, points)
        qy = ry[:, None, :] + ty[None, :, None]
        dist, _ = kd_tree(reference).query(
            np.stack((qx.ravel(), qy.ravel()), axis=1), distance_upper_bound=gate
        )
        fraction = np.isfinite(dist).reshape(th.size, tx.size, -1).mean(axis=2)
        score = fraction - penalty[None, :]
        i = int(np.argmax(score))
        if score.flat[i] > best_score:
            r, t = divmod(i, tx.size)
            best_score, best_fraction = float(score.flat[i]), float(fraction.flat[i])
            best = np.array([tx[t], ty[t], th[r]])
    return SearchHit(best, best_fraction)


def increment_from_lines(
    prev: Lines,
    curr: Lines,
    pairs: LinePairs,
    start: FloatArray,
    prior: FloatArray,
    prior_sigma: float,
    trim_floor_angle: float,
    inlier_distance: float,
    consensus_angle: float,
) -> FloatArray | None:
    """:func:`fuzzypos.matching.lines.increment_from_lines` in numpy (the kernel's reference)."""
    if len(pairs) < 2:
        return None
    pa, ca, pd, cd = (
        prev.angle_variance,
        curr.angle_variance,
        prev.distance_variance,
        curr.distance_variance,
    )
    assert pa is not None and ca is not None and pd is not None and cd is not None
    P = pairs.prev_index
    C = pairs.curr_index
    raw = prev.normal_angle[P] - curr.normal_angle[C] - start[2]
    delta = (raw + _HALF_PI) % math.pi - _HALF_PI  # rotation left after ``start``
    sign = np.copysign(1.0, np.cos(raw - delta))  # opposite normals: flip d′
    w_a = 1.0 / (pa[P] + ca[C])
    keep = robust_keep(delta, trim_floor_angle)
    theta = float(start[2] + np.dot(w_a[keep], delta[keep]) / w_a[keep].sum())
    # n: the mean of the previous normal and the current one rotated by θ (both lines agree)
    half = 0.5 * (prev.normal_angle[P] + curr.normal_angle[C] + theta + (raw - delta))
    nx = np.cos(half)
    ny = np.sin(half)
    rhs = prev.distance[P] - sign * curr.distance[C]
    used = keep & _translation_consensus(
        nx, ny, rhs, keep, inlier_distance, math.sin(consensus_angle)
    )
    w = np.where(used, 1.0 / (pd[P] + cd[C]), 0.0)
    lam = 1.0 / (prior_sigma * prior_sigma)
    wx, wy = w * nx, w * ny
    a11 = float(np.dot(wx, nx)) + lam
    a12 = float(np.dot(wx, ny))
    a22 = float(np.dot(wy, ny)) + lam
    b1 = float(np.dot(wx, rhs)) + lam * float(prior[0])
    b2 = float(np.dot(wy, rhs)) + lam * float(prior[1])
    det = a11 * a22 - a12 * a12
    tx = (a22 * b1 - a12 * b2) / det
    ty = (a11 * b2 - a12 * b1) / det
    return np.array([tx, ty, math.atan2(math.sin(theta), math.cos(theta))])


def pair_lines(
    prev: Lines,
    curr: Lines,
    pose: FloatArray,
    angle_gate: float,
    distance_gate: float,
    overlap_margin: float,
) -> LinePairs:
    """:func:`pair_lines` in numpy (the compiled kernel's reference)."""
    ang, dd, along, reach = _line_geometry(prev, curr, pose, overlap_margin)
    cost = ang * (1.0 / angle_gate) + dd * (1.0 / distance_gate)
    cost[(ang >= angle_gate) | (dd >= distance_gate) | (np.abs(along) > reach)] = np.inf
    j = cost.argmin(axis=1)
    i = cost.argmin(axis=0)
    rows = np.arange(len(prev))
    good = (cost.min(axis=1) < np.inf) & (i[j] == rows)
    return LinePairs(rows[good], j[good])


def _line_geometry(
    prev: Lines, curr: Lines, pose: FloatArray, overlap_margin: float
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Every previous line (rows) against every current one moved by ``pose`` (columns): the
    angle between their normals (either way), between their distances, the offset of the
    current centre along the previous line, and how far it may be for their segments to
    overlap."""
    ac = curr.normal_angle + pose[2]  # the current normals' angles in frame k
    raw = prev.normal_angle[:, None] - ac  # (P, C)
    ang = np.abs((raw + _HALF_PI) % math.pi - _HALF_PI)  # normals may point either way
    sign = np.copysign(1.0, np.cos(raw))
    d = curr.distance + np.cos(ac) * pose[0] + np.sin(ac) * pose[1]
    dd = np.abs(prev.distance[:, None] - sign * d)
    # centre of each current segment in frame k, and its offset along each previous line
    c, s = math.cos(pose[2]), math.sin(pose[2])
    cx = pose[0] + c * curr.centre[:, 0] - s * curr.centre[:, 1]
    cy = pose[1] + s * curr.centre[:, 0] + c * curr.centre[:, 1]
    pn = prev.normal
    along = pn[:, 1:2] * (cx - prev.centre[:, 0:1]) - pn[:, 0:1] * (cy - prev.centre[:, 1:2])
    reach = 0.5 * (prev.length[:, None] + curr.length) + overlap_margin
    return ang, dd, along, reach


def _translation_consensus(
    nx: FloatArray,
    ny: FloatArray,
    rhs: FloatArray,
    candidates: NDArray[np.bool_],
    tau: float,
    min_sine: float,
) -> NDArray[np.bool_]:
    """Line pairs consistent with the best translation that two non-parallel pairs fix.

    Every two candidate pairs whose normals' angle has a sine above ``min_sine`` give ``t``
    exactly (``n·t = rhs`` twice);
    the one with the smallest truncated squared residual over all pairs (MSAC, τ) wins and its
    pairs within τ are the inliers. With no such two (parallel walls) every candidate is kept.
    """
    idx = candidates.nonzero()[0]
    if idx.size < 3:
        return candidates
    a, b = index_pairs(idx.size)
    i, j = idx[a], idx[b]
    det = nx[i] * ny[j] - ny[i] * nx[j]
    ok = np.abs(det) > min_sine
    if not ok.any():
        return candidates
    i, j, det = i[ok], j[ok], det[ok]
    tx = (rhs[i] * ny[j] - ny[i] * rhs[j]) / det
    ty = (nx[i] * rhs[j] - rhs[i] * nx[j]) / det
    r = np.abs(tx[:, None] * nx[idx] + ty[:, None] * ny[idx] - rhs[idx])
    best = int(np.minimum(r * r, tau * tau).sum(axis=1).argmin())
    out = np.zeros_like(candidates)
    out[idx] = r[best] < tau
    return out


def robust_keep(values: FloatArray, floor: float, center: float | None = None) -> BoolArray:
    """Values within 3 robust sigmas (1.4826 × MAD, at least ``floor``) of their median (or
    of ``center``)."""
    if center is None:
        center = median(values)
    dev = np.abs(values - center)
    return dev <= outlier_cut(dev, floor)


def refine(
    reference: SurfacePoints,
    points: FloatArray,
    weights: FloatArray,
    start: FloatArray,
    prior: FloatArray,
    hold: FloatArray,
    cfg: RefinementConfig,
    max_distance: float,
    prior_scale: float,
    prior_information: FloatArray | None,
    spacing: FloatArray | None,
) -> Refinement | None:
    """:func:`refine_point_to_line` in numpy, a KD-tree query per iteration (the compiled
    kernel's reference)."""
    min_distance, iterations, residual_scale = cfg.min_distance, cfg.iterations, cfg.residual_scale
    point_sigma, degenerate_ratio = cfg.point_sigma, cfg.degenerate_ratio
    hold_tolerance = cfg.hold_tolerance
    pose = np.asarray(start, dtype=float).copy()
    start_xy = pose[:2].copy()
    hold_xy = np.asarray(hold, dtype=float)[:2]
    prior = np.asarray(prior, dtype=float)
    info_prior, prior_info = _prior_terms(cfg, prior_scale, prior_information)
    gates = np.geomspace(max_distance, min_distance, cfg.gate_steps)
    reach = _reach(cfg, spacing)
    paired = 0
    trimming = False
    last = np.zeros(3)
    for it in range(iterations):
        gate = gates[min(it, gates.size - 1)]
        lin = _linearise(reference, points, pose, gate, reach)
        if lin is None:
            return None
        ok, j, J, r = lin
        paired = int(ok.sum())
        absr = np.abs(r)
        huber = np.where(absr <= residual_scale, 1.0, residual_scale / np.maximum(absr, 1e-12))
        w = weights[ok] * reference.weight[j] * huber / point_sigma**2
        # degeneracy (a corridor): where the points fix the translation in one direction only,
        # the other direction, which only the noise of the normals speaks for, stays at start
        a, b, c = (J[0] * w) @ J[0], (J[0] * w) @ J[1], (J[1] * w) @ J[1]
        if trimming:
            w = _trimmed(w, absr, cfg.trim_floor)
        H = (J * w) @ J.T
        g = (J * w) @ r
        info_points = H.copy()
        jw = J * w
        hold_info, on_start = _hold_degenerate(
            H, g, (a, b, c), pose, start_xy, hold_xy, degenerate_ratio, hold_tolerance
        )
        dp = pose - prior
        dp[2] = (dp[2] + math.pi) % (2 * math.pi) - math.pi
        if prior_information is None:
            H[np.diag_indices(3)] += info_prior
            g += info_prior * dp
        else:
            H += prior_info
            g += prior_info @ dp
        try:
            delta = -np.linalg.solve(H, g)
        except np.linalg.LinAlgError:
            return None
        pose += delta
        if it >= gates.size - 1 and _converged(delta, last if it >= gates.size else None, cfg):
            if trimming:
                break
            trimming = True  # converged: trim the false pairs and converge again
        last = delta
    pose[2] = (pose[2] + math.pi) % (2 * math.pi) - math.pi
    close = int(np.count_nonzero(absr < 0.5 * residual_scale))
    return Refinement(
        pose,
        paired,
        paired / points.shape[0],
        close / points.shape[0],
        information=info_points,
        prior_information=prior_info,
        hold_information=hold_info,
        hold_on_start=on_start,
        start=np.asarray(start, dtype=float).copy(),
        prior=prior.copy(),
        gradient_covariance=_residual_variance(w, r, residual_scale) * (jw @ jw.T),
    )


def _converged(delta: FloatArray, last: FloatArray | None, cfg: RefinementConfig) -> bool:
    """Whether Gauss-Newton has converged with the step ``delta``: the step is below
    ``converged_translation`` (|dx| + |dy|) and ``converged_rotation``, or, given the step
    before (``last``, both at the final gate), the two steps cancel to within those (a
    two-cycle: a point at the gate's edge paired and unpaired by turns puts the pose back
    where it stood two steps before, and the steps would repeat to the last iteration)."""
    conv_t, conv_r = cfg.converged_translation, cfg.converged_rotation
    if abs(delta[0]) + abs(delta[1]) < conv_t and abs(delta[2]) < conv_r:
        return True
    if last is None:
        return False
    back = delta + last
    return bool(abs(back[0]) + abs(back[1]) < conv_t and abs(back[2]) < conv_r)


def _linearise(
    reference: SurfacePoints,
    points: FloatArray,
    pose: FloatArray,
    gate: float,
    reach: FloatArray | None,
) -> tuple[NDArray[np.bool_], IntArray, FloatArray, FloatArray] | None:
    """The points moved by ``pose``, paired with the reference: which paired, their reference
    points, the Jacobian (3, m) of the point-to-line residuals n·(T·p − q) and the residuals;
    None with fewer than 3 pairs."""
    c, s = math.cos(pose[2]), math.sin(pose[2])
    rx = c * points[:, 0] - s * points[:, 1]
    ry = s * points[:, 0] + c * points[:, 1]
    qx, qy = rx + pose[0], ry + pose[1]
    ok, j = _pair(reference, qx, qy, gate, reach)
    if int(ok.sum()) < 3:
        return None
    j = j[ok]
    nx, ny = reference.normal[j, 0], reference.normal[j, 1]
    r = nx * (qx[ok] - reference.xy[j, 0]) + ny * (qy[ok] - reference.xy[j, 1])
    jt = nx * (-ry[ok]) + ny * rx[ok]  # d r / d θ
    return ok, j, np.stack((nx, ny, jt)), r


def _reach(cfg: RefinementConfig, spacing: FloatArray | None) -> FloatArray | None:
    """How far each point may pair by its own beam spacing (None where no point is so sparse
    that it reaches beyond the smallest pairing distance: the fixed distances decide)."""
    if spacing is None or cfg.pairing_spacing <= 0.0:
        return None
    reach = cfg.pairing_spacing * np.asarray(spacing, dtype=float)
    return reach if np.any(reach > cfg.min_distance) else None


def _pair(
    reference: SurfacePoints, qx: FloatArray, qy: FloatArray, gate: float, reach: FloatArray | None
) -> tuple[NDArray[np.bool_], IntArray]:
    """Each point's nearest reference point within ``gate`` (or its own ``reach``, where
    larger): whether it paired, and the reference index."""
    if reach is None:
        dist, j = kd_tree(reference).query(stack_columns(qx, qy), distance_upper_bound=gate)
        return np.isfinite(dist), j
    # sparse far points reach further: their own beam spacing times the factor
    bound = np.maximum(reach, gate)
    dist, j = kd_tree(reference).query(
        stack_columns(qx, qy), distance_upper_bound=float(bound.max())
    )
    return dist <= bound, j


def _trimmed(w: FloatArray, absr: FloatArray, trim_floor: float) -> FloatArray:
    """Once converged: pairs far beyond the residuals' robust spread are false (a far wall's
    point next to a nearer object) and get no weight (never a tighter cut than
    ``trim_floor``)."""
    m = absr.size // 2
    cut = max(OUTLIER_SIGMAS * MAD_TO_SIGMA * float(np.partition(absr, m)[m]), trim_floor)
    out: FloatArray = np.where(absr > cut, 0.0, w)
    return out


def _residual_variance(weights: FloatArray, residuals: FloatArray, scale: float) -> float:
    """The points' noise variance (m²) from the residuals of the points that had weight
    (clipped at the Huber scale, as the fit sees them), with the fit's 3 degrees of freedom
    taken off their count."""
    used = weights > 0.0
    n = int(np.count_nonzero(used))
    if n <= 3:
        return scale * scale
    clipped = np.minimum(np.abs(residuals[used]), scale)
    return float(clipped @ clipped) / (n - 3)


def _hold_degenerate(
    H: FloatArray,
    g: FloatArray,
    block: tuple[float, float, float],
    pose: FloatArray,
    start_xy: FloatArray,
    hold_xy: FloatArray,
    degenerate_ratio: float,
    hold_tolerance: float,
) -> tuple[FloatArray, bool]:
    """Where the points fix the translation in one direction less than ``degenerate_ratio``
    times the other (``block``: the translation block ``(a, b, c)`` of their information), a
    strong term (in place, on ``H`` and ``g``) keeps the translation along it at ``start_xy``'s
    where that lies within ``hold_tolerance`` of ``hold_xy``'s (the odometry), else at
    ``hold_xy``'s. Returns the term added to ``H`` (zero where none) and whether it holds the
    start's value."""
    a, b, c = block
    half = math.hypot(0.5 * (a - c), b)
    lo, hi = 0.5 * (a + c) - half, 0.5 * (a + c) + half  # eigenvalues of the 2×2 block
    term = np.zeros((3, 3))
    if not lo < degenerate_ratio * hi:
        return term, False
    # its eigenvector for ``lo``: the direction the points hardly fix
    v = (
        np.array([b, lo - a])
        if abs(b) > 1e-12 * hi
        else (np.array([1.0, 0.0]) if a <= c else np.array([0.0, 1.0]))
    )
    v /= math.hypot(v[0], v[1])
    # keep the start's value along v where it agrees with ``hold`` (the odometry)
    # within ``hold_tolerance``, else the odometry's
    on_start = abs(float(v @ (start_xy - hold_xy))) <= hold_tolerance
    target = start_xy if on_start else hold_xy
    term[:2, :2] = hi * np.outer(v, v)
    H[:2, :2] += term[:2, :2]
    g[:2] += hi * v * float(v @ (pose[:2] - target))
    return term, on_start


def surface_points(
    points: FloatArray,
    ranges: FloatArray,
    uncertainty: FloatArray,
    settings: RefinementConfig,
) -> SurfacePoints:
    """:func:`fuzzypos.matching.surface.surface_points` in numpy, no Python loop over points
    (the kernel's reference)."""
    neighbour_distance, neighbour_step = settings.neighbour_distance, settings.neighbour_step
    neighbour_ratio, max_bend = settings.neighbour_ratio, settings.max_bend_angle
    xy = np.asarray(points, dtype=float).reshape(-1, 2)
    n = xy.shape[0]
    if n < 3:
        empty = np.zeros((0, 2))
        return SurfacePoints(empty, empty, np.zeros(0))
    step = np.diff(xy, axis=0)
    step_len = np.hypot(step[:, 0], step[:, 1])
    rng = np.asarray(ranges, dtype=float)
    limit = np.maximum(neighbour_distance, neighbour_ratio * np.minimum(rng[1:], rng[:-1]))
    link = step_len <= limit
    run = np.concatenate(([0], np.cumsum(~link)))
    first = np.searchsorted(run, run, side="left")
    last = np.searchsorted(run, run, side="right") - 1
    idx = np.arange(n)
    prev_i = np.maximum(idx - neighbour_step, first)
    next_i = np.minimum(idx + neighbour_step, last)
    # a point on a straight stretch: the chords to either side agree in direction within
    # ``max_bend``, and its normal is that of the chord across it. Where they do not (next to
    # a corner), the side whose chord agrees with the chord beyond it gives the normal; a
    # point straight on neither side (a corner, a round pillar) and a run's ends give none
    prev2 = np.maximum(prev_i - neighbour_step, first)
    next2 = np.minimum(next_i + neighbour_step, last)
    left, right = xy - xy[prev_i], xy[next_i] - xy
    far_left, far_right = xy[prev_i] - xy[prev2], xy[next2] - xy[next_i]
    tan_bend = math.tan(max_bend) if max_bend < math.pi / 2 else math.inf

    def agree(a: FloatArray, b: FloatArray) -> NDArray[np.bool_]:
        cross = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
        dot = a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1]
        return (dot > 0) & (np.abs(cross) <= tan_bend * dot)

    inner = (next_i > idx) & (prev_i < idx)
    straight = inner & agree(left, right)
    left_ok = ~straight & inner & (prev2 < prev_i) & agree(far_left, left)
    right_ok = ~straight & inner & ~left_ok & (next2 > next_i) & agree(right, far_right)
    chord = np.where(
        straight[:, None], xy[next_i] - xy[prev_i], np.where(left_ok[:, None], left, right)
    )
    length = np.hypot(chord[:, 0], chord[:, 1])
    ok = (straight | left_ok | right_ok) & (length > 1e-9)
    normal = stack_columns(-chord[ok, 1], chord[ok, 0]) / length[ok, None]
    w = np.clip(1.0 - np.asarray(uncertainty, dtype=float)[ok], settings.weight_floor, 1.0)
    xy_ok = xy[ok]
    return SurfacePoints(xy_ok, normal, w)


def refine_point_to_line(
    reference: SurfacePoints,
    points: FloatArray,
    weights: FloatArray,
    start: FloatArray,
    prior: FloatArray,
    hold: FloatArray,
    settings: RefinementConfig,
    *,
    max_distance: float,
    prior_scale: float,
    prior_information: FloatArray | None = None,
    spacing: FloatArray | None = None,
) -> Refinement | None:
    """:func:`fuzzypos.matching.surface.refine_point_to_line` in numpy (:func:`refine`)."""
    if len(reference) < 3 or points.shape[0] == 0:
        return None
    return refine(
        reference, points, weights, start, prior, hold, settings, max_distance, prior_scale,
        prior_information, spacing,
    )  # fmt: skip


#: (module, attribute, its reference) for :func:`oracles.references`
STAND_INS = [
    (search.__name__, "search_start", search_start),
    (lines.__name__, "pair_lines", pair_lines),
    (lines.__name__, "increment_from_lines", increment_from_lines),
    (surface.__name__, "surface_points", surface_points),
    (surface.__name__, "refine_point_to_line", refine_point_to_line),
]
