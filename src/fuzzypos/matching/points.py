"""The paper's method: pairing feature points between scans (§3.7), the pose from every two
pairs (§4), fusion (eq. 23–24).

Frames (SPEC step 9): unprimed points are scan k's (frame k), primed points scan k+1's, and the
transform sought, ``T`` with ``p = T · p′`` (eq. 20), is the increment ``u_k``: the pose of
scan k+1 in the frame of scan k. Pairing maps scan k's points into frame k+1 with the prior
increment, ``⊖u_k · p`` (eq. 17 with SPEC's fix).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..config import FusionConfig
from ..features import FeaturePoints
from ..geometry import circular_mean, inverse, stack_columns, transform_points
from ._robust import FloatArray, IntArray, index_pairs, outlier_cut

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
]


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

    def select(self, mask: NDArray[np.bool_]) -> Pairs:
        return Pairs(
            self.prev_index[mask],
            self.curr_index[mask],
            self.prev[mask],
            self.curr[mask],
            self.uncertainty[mask],
        )


def pair_features(
    prev: FeaturePoints,
    curr: FeaturePoints,
    increment: FloatArray,
    max_distance: float,
    same_kind_only: bool,
    mutual: bool,
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
        return TwoPairSolutions(
            np.zeros((0, 3)), np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0)
        )
    i, j = index_pairs(m)
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


def consensus_inliers(
    pairs: Pairs, solutions: TwoPairSolutions, inlier_distance: float
) -> NDArray[np.bool_]:
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
    inliers: NDArray[np.bool_] = r[best] < inlier_distance
    return inliers


def _trim(pairs: Pairs, pose: FloatArray, floor: float, ceiling: float) -> NDArray[np.bool_]:
    """Pairs whose residual is within 3 robust standard deviations (between floor and ceiling)."""
    r = _residuals(pose, pairs)
    tol = min(outlier_cut(r, floor), ceiling)
    return r <= tol


def estimate_increment(
    pairs: Pairs, cfg: FusionConfig, min_separation: float, min_pairs: int
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
        sols = TwoPairSolutions(
            sols.poses[keep], sols.i[keep], sols.j[keep], sols.uncertainty[keep]
        )
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
