"""Beyond the paper: fuzzy-weighted point-to-line refinement of the increment against a
keyframe's surfaces (every filtered point of the scan, not only the features)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from ..config import RefinementConfig
from ..geometry import stack_columns
from ._robust import MAD_TO_SIGMA, OUTLIER_SIGMAS, FloatArray

__all__ = [
    "SurfacePoints",
    "surface_lengths",
    "surface_points",
    "Refinement",
    "refine_point_to_line",
]


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


def surface_lengths(
    points: FloatArray, ranges: FloatArray, angle_increment: float, cap: float
) -> FloatArray:
    """The stretch of surface each scan point stands for: the distance to its nearer neighbour
    along the scan (``points`` in beam order), at most ``cap`` beam spacings at its range
    (``cap · range · |angle_increment|``: across a gap or a jump edge the neighbour is on
    another surface), and one beam spacing for a point alone. Points that sample a wall at
    grazing incidence or far away stand for more of it than a dense patch of clutter next to
    the robot."""
    points = np.asarray(points, dtype=float)
    ranges = np.asarray(ranges, dtype=float)
    spacing: FloatArray = ranges * abs(float(angle_increment))
    n = points.shape[0]
    if n < 2:
        alone: FloatArray = spacing.copy()
        return alone
    d = np.hypot(*np.diff(points, axis=0).T)  # between consecutive points
    length = np.empty(n)
    length[0], length[-1] = d[0], d[-1]
    length[1:-1] = np.minimum(d[:-1], d[1:])
    return np.minimum(length, cap * spacing)


def surface_points(
    points: FloatArray,
    ranges: FloatArray,
    uncertainty: FloatArray,
    settings: RefinementConfig,
) -> SurfacePoints:
    """The keyframe's surfaces (``settings``: ``neighbour_distance``, ``neighbour_step``,
    ``neighbour_ratio``, ``max_bend_angle``, ``weight_floor`` of the refinement section).

    Normals from the chord between each point's ``neighbour_step``-th neighbours on either
    side in scan order, within its run of points (consecutive points no further apart than
    ``neighbour_distance`` or ``neighbour_ratio`` × their range, whichever is larger, so that
    far walls, sampled sparsely, stay one surface; at a run's end the chord stops at its last
    point). Only points on a straight stretch keep a normal: the chords to either side must
    agree in direction within ``max_bend``. No Python loop runs over points."""
    neighbour_distance, neighbour_step = settings.neighbour_distance, settings.neighbour_step
    neighbour_ratio, max_bend = settings.neighbour_ratio, settings.max_bend_angle
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
    chord = np.where(
        straight[:, None], xy[next_i] - xy[prev_i], np.where(left_ok[:, None], left, right)
    )
    length = np.hypot(chord[:, 0], chord[:, 1])
    ok = (straight | left_ok | right_ok) & (length > 1e-9)
    normal = stack_columns(-chord[ok, 1], chord[ok, 0]) / length[ok, None]
    w = np.clip(1.0 - np.asarray(uncertainty, dtype=float)[ok], settings.weight_floor, 1.0)
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
    hold: FloatArray,
    settings: RefinementConfig,
    *,
    max_distance: float,
    prior_scale: float,
) -> Refinement | None:
    """Refine the increment ``start`` (the pose of the scan in the reference's frame) so that
    the scan's ``points`` land on the reference's surfaces (``settings``: the refinement
    section; the prior's standard deviations are its ``prior_sigma``/``prior_sigma_angle``
    times ``prior_scale``): Gauss-Newton on Σ w ρ(n·(T·p − q))
    with ρ Huber at ``residual_scale``, w the product of both points' certainties over
    ``point_sigma``² (a certain point's standard deviation along its normal), and the
    ``prior`` as one more measurement with standard deviations ``prior_sigma`` (translation)
    and ``prior_sigma_angle``. Where the points constrain one direction of the translation
    less than ``degenerate_ratio`` times the other (a corridor), the translation along it stays
    at ``start``'s where that lies within ``hold_tolerance`` of ``hold``'s (the odometry), else
    at ``hold``'s: the odometry keeps its say along a corridor. Each point pairs with the
    nearest reference point within a distance that shrinks from ``max_distance`` to
    ``min_distance`` over ``gate_steps`` iterations. None when no point pairs."""
    if len(reference) < 3 or points.shape[0] == 0:
        return None
    cfg = settings
    min_distance, iterations, residual_scale = cfg.min_distance, cfg.iterations, cfg.residual_scale
    point_sigma, degenerate_ratio, hold_tolerance = (
        cfg.point_sigma,
        cfg.degenerate_ratio,
        cfg.hold_tolerance,
    )
    prior_sigma, prior_sigma_angle = (
        cfg.prior_sigma * prior_scale,
        cfg.prior_sigma_angle * prior_scale,
    )
    pose = np.asarray(start, dtype=float).copy()
    start_xy = pose[:2].copy()
    hold_xy = np.asarray(hold, dtype=float)[:2]
    prior = np.asarray(prior, dtype=float)
    info_prior = np.array([1.0 / prior_sigma**2, 1.0 / prior_sigma**2, 1.0 / prior_sigma_angle**2])
    gates = np.geomspace(max_distance, min_distance, cfg.gate_steps)
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
            # than ``trim_floor``)
            m = absr.size // 2
            cut = max(
                OUTLIER_SIGMAS * MAD_TO_SIGMA * float(np.partition(absr, m)[m]), cfg.trim_floor
            )
            w = np.where(absr > cut, 0.0, w)
        H = (J * w) @ J.T
        g = (J * w) @ r
        _hold_degenerate(H, g, (a, b, c), pose, start_xy, hold_xy, degenerate_ratio, hold_tolerance)
        dp = pose - prior
        dp[2] = (dp[2] + math.pi) % (2 * math.pi) - math.pi
        H[np.diag_indices(3)] += info_prior
        g += info_prior * dp
        try:
            delta = -np.linalg.solve(H, g)
        except np.linalg.LinAlgError:
            return None
        pose += delta
        if (
            it >= gates.size - 1
            and abs(delta[0]) + abs(delta[1]) < cfg.converged_translation
            and abs(delta[2]) < cfg.converged_rotation
        ):
            if trimming:
                break
            trimming = True  # converged: trim the false pairs and converge again
    pose[2] = (pose[2] + math.pi) % (2 * math.pi) - math.pi
    close = int(np.count_nonzero(absr < 0.5 * residual_scale))
    return Refinement(pose, paired, paired / points.shape[0], close / points.shape[0])


def _hold_degenerate(
    H: FloatArray,
    g: FloatArray,
    block: tuple[float, float, float],
    pose: FloatArray,
    start_xy: FloatArray,
    hold_xy: FloatArray,
    degenerate_ratio: float,
    hold_tolerance: float,
) -> None:
    """Where the points fix the translation in one direction less than ``degenerate_ratio``
    times the other (``block``: the translation block ``(a, b, c)`` of their information), a
    strong term (in place, on ``H`` and ``g``) keeps the translation along it at ``start_xy``'s
    where that lies within ``hold_tolerance`` of ``hold_xy``'s (the odometry), else at
    ``hold_xy``'s."""
    a, b, c = block
    half = math.hypot(0.5 * (a - c), b)
    lo, hi = 0.5 * (a + c) - half, 0.5 * (a + c) + half  # eigenvalues of the 2×2 block
    if lo < degenerate_ratio * hi:
        # its eigenvector for ``lo``: the direction the points hardly fix
        v = (
            np.array([b, lo - a])
            if abs(b) > 1e-12 * hi
            else (np.array([1.0, 0.0]) if a <= c else np.array([0.0, 1.0]))
        )
        v /= math.hypot(v[0], v[1])
        # keep the start's value along v where it agrees with ``hold`` (the odometry)
        # within ``hold_tolerance``, else the odometry's
        target = start_xy if abs(float(v @ (start_xy - hold_xy))) <= hold_tolerance else hold_xy
        H[:2, :2] += hi * np.outer(v, v)
        g[:2] += hi * v * float(v @ (pose[:2] - target))
