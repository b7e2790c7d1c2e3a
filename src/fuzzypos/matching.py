"""Pairing features between scans (§3.7), the pose from two pairs (§4), fusion (eq. 23–24).

Frames (SPEC step 9): unprimed points are scan k's (frame k), primed points scan k+1's, and the
transform sought, ``T`` with ``p = T · p′`` (eq. 20), is the increment ``u_k``: the pose of
scan k+1 in the frame of scan k. Pairing maps scan k's points into frame k+1 with the prior
increment, ``⊖u_k · p`` (eq. 17 with SPEC's fix).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from .config import FusionConfig
from .features import FeaturePoints, Lines
from .geometry import circular_mean, inverse, stack_columns, transform_points

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

__all__ = [
    "Pairs",
    "pair_features",
    "poses_from_two_pairs",
    "TwoPairSolutions",
    "two_pair_solutions",
    "fuse_weighted_mean",
    "fuse_least_squares",
    "consensus_inliers",
    "estimate_increment",
    "LinePairs",
    "pair_lines",
    "increment_from_lines",
    "SurfacePoints",
    "surface_points",
    "Refinement",
    "refine_point_to_line",
    "search_start",
    "surface_lengths",
]


_HALF_PI = 0.5 * math.pi


@lru_cache(maxsize=256)
def _index_pairs(m: int) -> tuple[IntArray, IntArray]:
    """All ``(i, j)`` with ``i < j < m`` (np.triu_indices, cached: it is slow to build)."""
    i, j = np.triu_indices(m, 1)
    i.flags.writeable = False
    j.flags.writeable = False
    return i, j


@dataclass(frozen=True, eq=False)
class Pairs:
    """Paired feature points: ``prev[i]`` (frame k) ↔ ``curr[i]`` (frame k+1)."""

    prev_index: IntArray
    curr_index: IntArray
    prev: FloatArray
    curr: FloatArray
    uncertainty: FloatArray  # (m, 2): the two points' fuzzy uncertainties

    def __len__(self) -> int:
        return int(self.prev_index.shape[0])

    def select(self, mask: NDArray[np.bool_]) -> "Pairs":
        return Pairs(
            self.prev_index[mask], self.curr_index[mask], self.prev[mask], self.curr[mask],
            self.uncertainty[mask],
        )


def pair_features(
    prev: FeaturePoints,
    curr: FeaturePoints,
    increment: FloatArray,
    max_distance: float,
    same_kind_only: bool = False,
    mutual: bool = False,
) -> Pairs:
    """§3.7, eq. 17–18: map scan k's points into frame k+1 with the prior ``increment`` and pair
    each with the point of scan k+1 within ``max_distance`` (T) of it, where there is exactly
    one. ``same_kind_only`` pairs only points of the same kind; ``mutual`` also requires the
    scan-k+1 point to have exactly one candidate in scan k."""
    n1, n2 = len(prev), len(curr)
    if n1 == 0 or n2 == 0:
        z = np.zeros(0, dtype=np.int64)
        return Pairs(z, z, np.zeros((0, 2)), np.zeros((0, 2)), np.zeros((0, 2)))
    mapped = transform_points(inverse(np.asarray(increment, dtype=float)), prev.xy)  # eq. 17
    diff = mapped[:, None, :] - curr.xy[None, :, :]
    d2 = diff[..., 0] ** 2 + diff[..., 1] ** 2  # eq. 18, squared
    within = d2 < max_distance * max_distance
    if same_kind_only:
        within &= prev.kind[:, None] == curr.kind[None, :]
    row_count = within.sum(axis=1)
    ok = row_count == 1
    j = within.argmax(axis=1)
    if mutual:
        col_count = within.sum(axis=0)
        ok &= col_count[j] == 1
    i = ok.nonzero()[0]
    j = j[ok]
    return Pairs(
        prev_index=i.astype(np.int64),
        curr_index=j.astype(np.int64),
        prev=prev.xy[i],
        curr=curr.xy[j],
        uncertainty=stack_columns(prev.uncertainty[i], curr.uncertainty[j]),
    )


def poses_from_two_pairs(
    p1: FloatArray, p2: FloatArray, q1: FloatArray, q2: FloatArray, min_separation: float = 0.0
) -> tuple[FloatArray, NDArray[np.bool_]]:
    """Eq. 19–22 for many two-pair sets at once: ``p = T · q`` for (p1, q1) and (p2, q2).

    The 4×4 system of eq. 22 is a similarity transform; its solution is, in closed form,
    ``(cos θ, sin θ) = (Δq·Δp, Δq×Δp) / |Δq|²`` (the determinant is −|Δq|²). SPEC: normalise
    (cos θ, sin θ), then recompute (a, b) from the two points with that rotation. Pairs whose
    primed points are closer than ``min_separation`` are ill-conditioned and flagged invalid.
    Returns ``(poses (n, 3) [a, b, θ], valid (n,))``.
    """
    dp = p2 - p1
    dq = q2 - q1
    nq2 = dq[:, 0] ** 2 + dq[:, 1] ** 2
    valid = nq2 > max(min_separation, 1e-9) ** 2
    c = dq[:, 0] * dp[:, 0] + dq[:, 1] * dp[:, 1]
    s = dq[:, 0] * dp[:, 1] - dq[:, 1] * dp[:, 0]
    theta = np.arctan2(s, c)
    ct, st = np.cos(theta), np.sin(theta)
    pm = 0.5 * (p1 + p2)
    qm = 0.5 * (q1 + q2)
    a = pm[:, 0] - (ct * qm[:, 0] - st * qm[:, 1])
    b = pm[:, 1] - (st * qm[:, 0] + ct * qm[:, 1])
    return stack_columns(a, b, theta), valid


@dataclass(frozen=True, eq=False)
class TwoPairSolutions:
    """Every two-pair solution: ``poses`` (n, 3), the pair indices ``(i, j)`` and the fused
    uncertainty ``f`` of eq. 23 (SPEC: the mean over the solution's four points)."""

    poses: FloatArray
    i: IntArray
    j: IntArray
    uncertainty: FloatArray

    def __len__(self) -> int:
        return int(self.poses.shape[0])


def two_pair_solutions(
    pairs: Pairs, min_separation: float, max_solutions: int, rng_seed: int = 0
) -> TwoPairSolutions:
    """The pose from every two pairs (§4), well-conditioned ones only."""
    m = len(pairs)
    if m < 2:
        return TwoPairSolutions(np.zeros((0, 3)), np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0))
    i, j = _index_pairs(m)
    if i.size > max_solutions:
        pick = np.random.default_rng(rng_seed).choice(i.size, max_solutions, replace=False)
        pick.sort()
        i, j = i[pick], j[pick]
    poses, valid = poses_from_two_pairs(
        pairs.prev[i], pairs.prev[j], pairs.curr[i], pairs.curr[j], min_separation
    )
    i, j, poses = i[valid], j[valid], poses[valid]
    f = 0.25 * (pairs.uncertainty[i].sum(axis=1) + pairs.uncertainty[j].sum(axis=1))  # eq. 23
    return TwoPairSolutions(poses, i.astype(np.int64), j.astype(np.int64), f)


def _certainty_weights(f: FloatArray) -> FloatArray:
    """SPEC's fix of eq. 24: weight = 1 − f; all-zero weights fall back to equal weights."""
    w = np.clip(1.0 - np.asarray(f, dtype=float), 0.0, 1.0)
    if not np.any(w > 0):
        w = np.ones_like(w)
    return w


def fuse_weighted_mean(poses: FloatArray, uncertainty: FloatArray) -> FloatArray:
    """Eq. 24 with SPEC's fixes: certainty-weighted mean of (a, b), circular mean of θ."""
    w = _certainty_weights(uncertainty)
    a = float(np.sum(w * poses[:, 0]) / np.sum(w))
    b = float(np.sum(w * poses[:, 1]) / np.sum(w))
    th = circular_mean(poses[:, 2], w)
    return np.array([a, b, th])


def fuse_least_squares(pairs: Pairs) -> FloatArray:
    """Certainty-weighted least squares over all pairs (closed-form 2D Procrustes): the rigid
    ``T`` minimising Σ w_i |p_i − T·q_i|², w_i = 1 − mean uncertainty of the pair."""
    w = _certainty_weights(pairs.uncertainty.mean(axis=1))
    ws = w.sum()
    pm = (w[:, None] * pairs.prev).sum(axis=0) / ws
    qm = (w[:, None] * pairs.curr).sum(axis=0) / ws
    p = pairs.prev - pm
    q = pairs.curr - qm
    c = np.sum(w * (q[:, 0] * p[:, 0] + q[:, 1] * p[:, 1]))
    s = np.sum(w * (q[:, 0] * p[:, 1] - q[:, 1] * p[:, 0]))
    th = float(np.arctan2(s, c))
    ct, st = np.cos(th), np.sin(th)
    a = pm[0] - (ct * qm[0] - st * qm[1])
    b = pm[1] - (st * qm[0] + ct * qm[1])
    return np.array([a, b, th])


def _residuals(pose: FloatArray, pairs: Pairs) -> FloatArray:
    """|p − T·q| for each pair under one or many poses: shape (pairs,) or (poses, pairs)."""
    pose = np.asarray(pose, dtype=float)
    single = pose.ndim == 1
    poses = pose[None, :] if single else pose
    c, s = np.cos(poses[:, 2])[:, None], np.sin(poses[:, 2])[:, None]
    qx, qy = pairs.curr[None, :, 0], pairs.curr[None, :, 1]
    ex = poses[:, 0][:, None] + c * qx - s * qy - pairs.prev[None, :, 0]
    ey = poses[:, 1][:, None] + s * qx + c * qy - pairs.prev[None, :, 1]
    r = np.sqrt(ex * ex + ey * ey)
    return r[0] if single else r


def consensus_inliers(pairs: Pairs, solutions: TwoPairSolutions, inlier_distance: float) -> NDArray[np.bool_]:
    """Robust fusion: the pairs consistent with the best-supported two-pair solution.

    Every solution maps every pair's primed point into frame k and is scored by the
    truncated squared distance to the unprimed points (MSAC: Σ min(r², τ²), τ =
    ``inlier_distance``), which prefers the solution that fits its supporters tightly rather
    than merely the one with most supporters. The winner's pairs within τ are the inliers.
    """
    r = _residuals(solutions.poses, pairs)
    tau2 = inlier_distance * inlier_distance
    score = np.minimum(r * r, tau2).sum(axis=1)
    best = int(score.argmin())
    return r[best] < inlier_distance


def _trim(pairs: Pairs, pose: FloatArray, floor: float, ceiling: float) -> NDArray[np.bool_]:
    """Pairs whose residual is within 3 robust standard deviations (between floor and ceiling)."""
    r = _residuals(pose, pairs)
    tol = min(max(3.0 * 1.4826 * _median(r), floor), ceiling)
    return r <= tol


def estimate_increment(
    pairs: Pairs, cfg: FusionConfig, min_separation: float, min_pairs: int = 2
) -> tuple[FloatArray | None, int]:
    """The increment from paired points, or ``None`` when no well-conditioned solution exists.

    ``weighted_mean``: eq. 23–24 over every two-pair solution. ``least_squares``: weighted
    least squares over the pairs that take part in an inlier solution. With ``robust`` the
    two-pair solutions far from their median are rejected first. Returns the pose and the
    number of pairs it rests on.
    """
    if len(pairs) < min_pairs:
        return None, len(pairs)
    sols = two_pair_solutions(pairs, min_separation, cfg.max_solutions)
    if len(sols) == 0:
        return None, len(pairs)
    if cfg.robust:
        # two pairs always agree with their own solution: a consensus needs a third witness
        if len(pairs) < cfg.min_inliers:
            return None, len(pairs)
        used = consensus_inliers(pairs, sols, cfg.inlier_distance)
        if used.sum() < max(min_pairs, cfg.min_inliers):
            return None, len(pairs)
        keep = used[sols.i] & used[sols.j]
        if not keep.any():
            return None, len(pairs)
        sols = TwoPairSolutions(sols.poses[keep], sols.i[keep], sols.j[keep], sols.uncertainty[keep])
    else:
        used = np.zeros(len(pairs), bool)
        used[sols.i] = True
        used[sols.j] = True
    if cfg.method == "weighted_mean":
        return fuse_weighted_mean(sols.poses, sols.uncertainty), int(used.sum())
    inliers = pairs.select(used)
    pose = fuse_least_squares(inliers)
    if cfg.robust:  # trim what the least-squares fit does not explain, and fit again
        for _ in range(2):
            keep = _trim(inliers, pose, cfg.trim_floor, cfg.inlier_distance)
            if keep.sum() < max(min_pairs, cfg.min_inliers) or keep.all():
                break
            inliers = inliers.select(keep)
            pose = fuse_least_squares(inliers)
    return pose, len(inliers)


@dataclass(frozen=True, eq=False)
class LinePairs:
    """Paired lines: ``prev[i]`` of scan k ↔ ``curr[i]`` of scan k+1 (indices into ``Lines``)."""

    prev_index: IntArray
    curr_index: IntArray

    def __len__(self) -> int:
        return int(self.prev_index.shape[0])


def pair_lines(
    prev: Lines, curr: Lines, pose: FloatArray, angle_gate: float, distance_gate: float, overlap_margin: float
) -> LinePairs:
    """Pair lines of scan k with lines of scan k+1 moved into frame k by ``pose``.

    Two lines pair when their directions differ by less than ``angle_gate``, their normal
    distances by less than ``distance_gate``, and their segments overlap along the line (the
    distance between their centres along it is at most their mean length plus
    ``overlap_margin``); each line keeps its best match, and only mutual best matches count.
    """
    if len(prev) == 0 or len(curr) == 0:
        z = np.zeros(0, dtype=np.int64)
        return LinePairs(z, z)
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
    cost = ang * (1.0 / angle_gate) + dd * (1.0 / distance_gate)
    cost[(ang >= angle_gate) | (dd >= distance_gate) | (np.abs(along) > reach)] = np.inf
    j = cost.argmin(axis=1)
    i = cost.argmin(axis=0)
    rows = np.arange(len(prev))
    good = (cost.min(axis=1) < np.inf) & (i[j] == rows)
    return LinePairs(rows[good], j[good])


def increment_from_lines(
    prev: Lines,
    curr: Lines,
    pairs: LinePairs,
    start: FloatArray,
    prior: FloatArray,
    prior_sigma: float,
    trim_floor_angle: float,
    inlier_distance: float,
) -> FloatArray | None:
    """Beyond the paper: the increment from paired lines (line-to-line matching).

    Rotation: the inverse-variance weighted mean of the paired normals' angle differences,
    after dropping those beyond 3 robust sigmas (at least ``trim_floor_angle``) of their
    median. Translation: each pair says ``n·t = d_k − d′`` (normal form, ``n`` the scan-k
    line's normal); the pairs consistent (within ``inlier_distance``) with the best
    translation two of them fix (:func:`_translation_consensus`) enter a weighted least-squares
    fit (inverse variances) together with the prior's translation as one more measurement of
    standard deviation ``prior_sigma``, which decides what the lines leave unobservable (the
    parallel walls of a corridor). Returns None with fewer than two pairs.
    """
    if len(pairs) < 2:
        return None
    P = pairs.prev_index
    C = pairs.curr_index
    raw = prev.normal_angle[P] - curr.normal_angle[C] - start[2]
    delta = (raw + _HALF_PI) % math.pi - _HALF_PI  # rotation left after ``start``
    sign = np.copysign(1.0, np.cos(raw - delta))  # opposite normals: flip d′
    w_a = 1.0 / (prev.angle_variance[P] + curr.angle_variance[C])
    keep = _robust_keep(delta, trim_floor_angle)
    theta = float(start[2] + np.dot(w_a[keep], delta[keep]) / w_a[keep].sum())
    # n: the mean of the previous normal and the current one rotated by θ (both lines agree)
    half = 0.5 * (prev.normal_angle[P] + curr.normal_angle[C] + theta + (raw - delta))
    nx = np.cos(half)
    ny = np.sin(half)
    rhs = prev.distance[P] - sign * curr.distance[C]
    used = keep & _translation_consensus(nx, ny, rhs, keep, inlier_distance)
    w = np.where(used, 1.0 / (prev.distance_variance[P] + curr.distance_variance[C]), 0.0)
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


def _translation_consensus(
    nx: FloatArray, ny: FloatArray, rhs: FloatArray, candidates: NDArray[np.bool_], tau: float
) -> NDArray[np.bool_]:
    """Line pairs consistent with the best translation that two non-parallel pairs fix.

    Every two candidate pairs at least 20° apart give ``t`` exactly (``n·t = rhs`` twice);
    the one with the smallest truncated squared residual over all pairs (MSAC, τ) wins and its
    pairs within τ are the inliers. With no such two (parallel walls) every candidate is kept.
    """
    idx = candidates.nonzero()[0]
    if idx.size < 3:
        return candidates
    a, b = _index_pairs(idx.size)
    i, j = idx[a], idx[b]
    det = nx[i] * ny[j] - ny[i] * nx[j]
    ok = np.abs(det) > 0.342  # sin 20°
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


def _median(values: FloatArray) -> float:
    """The median of a short 1-D array (np.median's generality costs more than the sort)."""
    v = np.sort(values)
    mid = v.shape[0] // 2
    return float(v[mid]) if v.shape[0] % 2 else 0.5 * float(v[mid - 1] + v[mid])


def _robust_keep(values: FloatArray, floor: float, center: float | None = None) -> NDArray[np.bool_]:
    """Values within 3 robust sigmas (1.4826 × MAD, at least ``floor``) of their median (or
    of ``center``)."""
    if center is None:
        center = _median(values)
    dev = np.abs(values - center)
    return dev <= max(3.0 * 1.4826 * _median(dev), floor)


# -- beyond the paper: fuzzy-weighted point-to-line refinement ---------------------------------
@dataclass(frozen=True, eq=False)
class SurfacePoints:
    """A keyframe's filtered points with the normal of the surface through each (unit,
    robot frame), their certainty ``weight`` (1 − the fuzzy uncertainty of eq. 4) and a
    KD-tree over them. Points with no neighbour on their surface are left out."""

    xy: FloatArray
    normal: FloatArray
    weight: FloatArray
    tree: cKDTree

    def __len__(self) -> int:
        return int(self.xy.shape[0])


def surface_lengths(points: FloatArray, ranges: FloatArray, angle_increment: float, cap: float) -> FloatArray:
    """The stretch of surface each scan point stands for: the distance to its nearer neighbour
    along the scan (``points`` in beam order), at most ``cap`` beam spacings at its range
    (``cap · range · |angle_increment|``: across a gap or a jump edge the neighbour is on
    another surface), and one beam spacing for a point alone. Points that sample a wall at
    grazing incidence or far away stand for more of it than a dense patch of clutter next to
    the robot."""
    points = np.asarray(points, dtype=float)
    ranges = np.asarray(ranges, dtype=float)
    spacing = ranges * abs(float(angle_increment))
    n = points.shape[0]
    if n < 2:
        return spacing.copy()
    d = np.hypot(*np.diff(points, axis=0).T)  # between consecutive points
    length = np.empty(n)
    length[0], length[-1] = d[0], d[-1]
    length[1:-1] = np.minimum(d[:-1], d[1:])
    return np.minimum(length, cap * spacing)


def surface_points(
    points: FloatArray,
    ranges: FloatArray,
    uncertainty: FloatArray,
    neighbour_distance: float,
    neighbour_step: int = 1,
    neighbour_ratio: float = 0.05,
    max_bend: float = math.radians(10.0),
) -> SurfacePoints:
    """Normals from the chord between each point's ``neighbour_step``-th neighbours on either
    side in scan order, within its run of points (consecutive points no further apart than
    ``neighbour_distance`` or ``neighbour_ratio`` × their range, whichever is larger, so that
    far walls, sampled sparsely, stay one surface; at a run's end the chord stops at its last
    point). Only points on a straight stretch keep a normal: the chords to either side must
    agree in direction within ``max_bend``. No Python loop runs over points."""
    xy = np.asarray(points, dtype=float).reshape(-1, 2)
    n = xy.shape[0]
    if n < 3:
        empty = np.zeros((0, 2))
        return SurfacePoints(empty, empty, np.zeros(0), cKDTree(empty))
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
    chord = np.where(straight[:, None], xy[next_i] - xy[prev_i], np.where(left_ok[:, None], left, right))
    length = np.hypot(chord[:, 0], chord[:, 1])
    ok = (straight | left_ok | right_ok) & (length > 1e-9)
    normal = stack_columns(-chord[ok, 1], chord[ok, 0]) / length[ok, None]
    w = np.clip(1.0 - np.asarray(uncertainty, dtype=float)[ok], 0.05, 1.0)
    xy_ok = xy[ok]
    return SurfacePoints(xy_ok, normal, w, cKDTree(xy_ok))


@dataclass(frozen=True)
class Refinement:
    """The refined increment, how many points paired at the last iteration, the fraction of
    the scan's points that did, and the fraction that lay within half the Huber scale of
    their surface (the finer score when two refinements are compared)."""

    increment: FloatArray
    n_paired: int
    inlier_fraction: float
    close_fraction: float = 0.0


def refine_point_to_line(
    reference: SurfacePoints,
    points: FloatArray,
    weights: FloatArray,
    start: FloatArray,
    prior: FloatArray,
    *,
    max_distance: float,
    min_distance: float,
    iterations: int,
    residual_scale: float,
    prior_sigma: float,
    prior_sigma_angle: float,
    point_sigma: float = 0.01,
    degenerate_ratio: float = 0.02,
    hold: FloatArray | None = None,
    hold_tolerance: float = 0.1,
) -> Refinement | None:
    """Refine the increment ``start`` (the pose of the scan in the reference's frame) so that
    the scan's ``points`` land on the reference's surfaces: Gauss-Newton on Σ w ρ(n·(T·p − q))
    with ρ Huber at ``residual_scale``, w the product of both points' certainties over
    ``point_sigma``² (a certain point's standard deviation along its normal), and the
    ``prior`` as one more measurement with standard deviations ``prior_sigma`` (translation)
    and ``prior_sigma_angle``. Where the points constrain one direction of the translation
    less than ``degenerate_ratio`` times the other (a corridor), the translation along it stays
    at ``start``'s where that lies within ``hold_tolerance`` of ``hold``'s (the odometry), else
    at ``hold``'s: the odometry keeps its say along a corridor. Each point pairs with the nearest reference point within a distance that
    shrinks from ``max_distance`` to ``min_distance``. None when no point pairs."""
    if len(reference) < 3 or points.shape[0] == 0:
        return None
    pose = np.asarray(start, dtype=float).copy()
    start_xy = pose[:2].copy()
    hold_xy = start_xy if hold is None else np.asarray(hold, dtype=float)[:2]
    prior = np.asarray(prior, dtype=float)
    info_prior = np.array([1.0 / prior_sigma**2, 1.0 / prior_sigma**2, 1.0 / prior_sigma_angle**2])
    gates = np.geomspace(max_distance, min_distance, 3)
    paired = 0
    trimming = False
    for it in range(iterations):
        gate = gates[min(it, gates.size - 1)]
        c, s = math.cos(pose[2]), math.sin(pose[2])
        rx = c * points[:, 0] - s * points[:, 1]
        ry = s * points[:, 0] + c * points[:, 1]
        qx, qy = rx + pose[0], ry + pose[1]
        dist, j = reference.tree.query(stack_columns(qx, qy), distance_upper_bound=gate)
        ok = np.isfinite(dist)
        paired = int(ok.sum())
        if paired < 3:
            return None
        j = j[ok]
        nx, ny = reference.normal[j, 0], reference.normal[j, 1]
        r = nx * (qx[ok] - reference.xy[j, 0]) + ny * (qy[ok] - reference.xy[j, 1])
        jt = nx * (-ry[ok]) + ny * rx[ok]  # d r / d θ
        absr = np.abs(r)
        huber = np.where(absr <= residual_scale, 1.0, residual_scale / np.maximum(absr, 1e-12))
        w = weights[ok] * reference.weight[j] * huber / point_sigma**2
        J = np.stack((nx, ny, jt))  # (3, m)
        # degeneracy (a corridor): where the points fix the translation in one direction only,
        # the other direction, which only the noise of the normals speaks for, stays at start
        a, b, c = (J[0] * w) @ J[0], (J[0] * w) @ J[1], (J[1] * w) @ J[1]
        if trimming:
            # once converged: pairs far beyond the residuals' robust spread are false (a far
            # wall's point next to a nearer object) and get no weight (never a tighter cut
            # than 2 mm)
            m = absr.size // 2
            cut = max(3.0 * 1.4826 * float(np.partition(absr, m)[m]), 0.002)
            w = np.where(absr > cut, 0.0, w)
        H = (J * w) @ J.T
        g = (J * w) @ r
        half = math.hypot(0.5 * (a - c), b)
        lo, hi = 0.5 * (a + c) - half, 0.5 * (a + c) + half  # eigenvalues of the 2×2 block
        if lo < degenerate_ratio * hi:
            # its eigenvector for ``lo``: the direction the points hardly fix
            v = np.array([b, lo - a]) if abs(b) > 1e-12 * hi else (
                np.array([1.0, 0.0]) if a <= c else np.array([0.0, 1.0]))
            v /= math.hypot(v[0], v[1])
            # keep the start's value along v where it agrees with ``hold`` (the odometry)
            # within ``hold_tolerance``, else the odometry's
            target = start_xy if abs(float(v @ (start_xy - hold_xy))) <= hold_tolerance else hold_xy
            H[:2, :2] += hi * np.outer(v, v)
            g[:2] += hi * v * float(v @ (pose[:2] - target))
        dp = pose - prior
        dp[2] = (dp[2] + math.pi) % (2 * math.pi) - math.pi
        H[np.diag_indices(3)] += info_prior
        g += info_prior * dp
        try:
            delta = -np.linalg.solve(H, g)
        except np.linalg.LinAlgError:
            return None
        pose += delta
        if it >= gates.size - 1 and abs(delta[0]) + abs(delta[1]) < 1e-4 and abs(delta[2]) < 1e-5:
            if trimming:
                break
            trimming = True  # converged: trim the false pairs and converge again
    pose[2] = (pose[2] + math.pi) % (2 * math.pi) - math.pi
    close = int(np.count_nonzero(absr < 0.5 * residual_scale))
    return Refinement(pose, paired, paired / points.shape[0], close / points.shape[0])


def search_start(
    reference: SurfacePoints,
    points: FloatArray,
    start: FloatArray,
    half_width: float,
    step: float,
    gate: float,
    translation_half_width: float = 0.0,
    translation_step: float = 0.2,
    max_points: int = 60,
    distance_penalty: float = 0.0,
) -> tuple[FloatArray, float]:
    """A wider search where the prior cannot be trusted (an odometry jump, a failed match):
    rotations ``start[2] ± half_width`` in steps of ``step`` and translations within
    ``± translation_half_width`` of the start's in steps of ``translation_step``, each scored by
    the fraction of (at most ``max_points``, evenly picked) ``points`` that land within ``gate``
    of a reference point, less ``distance_penalty`` per metre of translation from the start's
    (of near-equal scores, e.g. along a corridor's repeating doors, the one nearest the start
    wins). Returns the best start and its score (the fraction, without the penalty). KD-tree
    queries over all candidates at once, a chunk of rotations at a time; no Python loop over
    points."""
    start = np.asarray(start, dtype=float)
    if len(reference) == 0 or points.shape[0] == 0:
        return start, 0.0
    pts = points[:: max(1, points.shape[0] // max_points)]
    k = int(round(half_width / step))
    thetas = start[2] + step * np.arange(-k, k + 1)
    m = int(round(translation_half_width / translation_step))
    offs = translation_step * np.arange(-m, m + 1)
    tx, ty = np.meshgrid(start[0] + offs, start[1] + offs, indexing="ij")
    tx, ty = tx.ravel(), ty.ravel()
    penalty = distance_penalty * np.hypot(tx - start[0], ty - start[1])
    best_score, best_fraction, best = -np.inf, 0.0, start
    chunk = max(1, 200_000 // (tx.size * pts.shape[0]))
    for c0 in range(0, thetas.size, chunk):  # bounded memory: a chunk of rotations at a time
        th = thetas[c0 : c0 + chunk]
        c, s = np.cos(th)[:, None], np.sin(th)[:, None]
        rx = c * pts[None, :, 0] - s * pts[None, :, 1]  # (rotations, points)
        ry = s * pts[None, :, 0] + c * pts[None, :, 1]
        qx = rx[:, None, :] + tx[None, :, None]  # (rotations, translations, points)
        qy = ry[:, None, :] + ty[None, :, None]
        dist, _ = reference.tree.query(np.stack((qx.ravel(), qy.ravel()), axis=1), distance_upper_bound=gate)
        fraction = np.isfinite(dist).reshape(th.size, tx.size, -1).mean(axis=2)
        score = fraction - penalty[None, :]
        i = int(np.argmax(score))
        if score.flat[i] > best_score:
            r, t = divmod(i, tx.size)
            best_score, best_fraction = float(score.flat[i]), float(fraction.flat[i])
            best = np.array([tx[t], ty[t], th[r]])
    return best, best_fraction
