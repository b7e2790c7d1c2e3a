"""The numpy references of ``fuzzypos.pipeline``'s kernels (``_kernels.pipeline``,
``_kernels.refine``, ``_kernels.uncertainty``): the code each replaced, the tests' oracles."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from fuzzypos.features import Features, Lines
from fuzzypos.geometry import compose3, compose_jacobians, relative, relative3, stack_columns
from fuzzypos.matching import Refinement, surface_lengths
from fuzzypos.matching._robust import median as _median
from fuzzypos.matching.surface import SurfacePoints
from fuzzypos.pipeline import feature_match, local_map, refine, uncertainty
from fuzzypos.pipeline.feature_match import FeatureMatcher
from fuzzypos.pipeline.refine import Refiner, ScanPoints, Starts
from fuzzypos.pipeline.uncertainty import _MAX_CONDITION, Assessment, Uncertainty, local

FloatArray = NDArray[np.float64]


def moved(
    parts: list[tuple[SurfacePoints, FloatArray]], moves: list[tuple[float, float, float, float]]
) -> tuple[FloatArray, FloatArray]:
    """The parts' points and normals, each part moved by its ``(x, y, cos θ, sin θ)`` (the
    reference of the kernel ``move_surfaces``)."""
    xy, normal = [], []
    for (surf, _), (x, y, c, s_) in zip(parts, moves):
        p = surf.xy
        xy.append(stack_columns(x + c * p[:, 0] - s_ * p[:, 1], y + s_ * p[:, 0] + c * p[:, 1]))
        n = surf.normal
        normal.append(np.stack((c * n[:, 0] - s_ * n[:, 1], s_ * n[:, 0] + c * n[:, 1]), axis=1))
    return np.concatenate(xy), np.concatenate(normal)


def map_of(
    self: local_map.LocalMap, parts: list[tuple[SurfacePoints, FloatArray]]
) -> SurfacePoints:
    """``LocalMap._map_of`` with the parts moved by :func:`moved` (a few numpy calls a part)."""
    key = self._pose.tolist()
    moves = []
    for _surf, pose in parts:
        x, y, theta = relative3(key, pose.tolist())
        moves.append((x, y, math.cos(theta), math.sin(theta)))
    weight = np.concatenate([surf.weight for surf, _ in parts])
    return SurfacePoints(*moved(parts, moves), weight)


def _no_variances(_lines: object) -> bool:
    """``feature_match._has_variances``' stand-in: no lines go to the compiled steps' line
    matching (``FeatureMatcher.match_lines`` takes :func:`match_lines`' numpy passes)."""
    return False


def match_lines(
    self: FeatureMatcher, prev: Lines, curr: Lines, start: FloatArray | None, prior: FloatArray
) -> tuple[FloatArray | None, int]:
    """``FeatureMatcher.match_lines``' passes in numpy (the compiled kernel
    ``_kernels.lines.match_lines``' reference): pair the lines, the increment from the pairs,
    and again from it where it moved enough to change the pairs."""
    from oracles.matching import increment_from_lines, pair_lines

    m = self.matching
    if start is None:
        pose, gates = prior, (m.line_angle_gate_prior, m.line_distance_gate_prior)
    else:
        pose, gates = start, (m.line_angle_gate, m.line_distance_gate)
    est, n_pairs = None, 0
    for _ in range(m.line_passes):
        pairs = pair_lines(prev, curr, pose, gates[0], gates[1], m.line_overlap_margin)
        if len(pairs) < m.line_min_pairs:
            break
        new = increment_from_lines(
            prev, curr, pairs, pose, prior, m.line_prior_sigma, m.line_trim_angle,
            m.line_inlier_distance, m.line_consensus_angle,
        )  # fmt: skip
        if new is None:
            break
        moved = np.abs(new - pose)
        est = pose = new
        n_pairs = len(pairs)
        # pair again with the refined motion, unless it moved too little to change pairs
        f = m.line_repair_fraction
        if moved[0] + moved[1] < f * m.line_distance_gate and moved[2] < f * m.line_angle_gate:
            break
        gates = (m.line_angle_gate, m.line_distance_gate)
    return est, n_pairs


def weights(self: Refiner, features: Features, angle_increment: float) -> FloatArray:
    """The points' weights in numpy (the compiled kernel's reference)."""
    r = self.refinement
    pts = features.points
    weights: FloatArray = np.clip(1.0 - features.uncertainty, r.weight_floor, 1.0)
    if r.length_weight_max > 1.0:
        # each point weighs the stretch of surface it stands for (over the scan's median):
        # the fit is one over the surfaces' length, not over the beams, and dense clutter
        # next to the robot (people, a desk) no longer outvotes the walls
        length = surface_lengths(pts, features.ranges, angle_increment, r.length_cap)
        median = _median(length)
        if median > 0.0:
            weights = weights * np.clip(
                length / median, 1.0 / r.length_weight_max, r.length_weight_max
            )
    return weights


def points(self: Refiner, features: Features, angle_increment: float) -> ScanPoints | None:
    """``Refiner.points`` weighed in numpy (:func:`weights`) at once."""
    pts = features.points
    if pts.shape[0] < self.refinement.min_points:
        return None
    spacing = features.ranges * abs(float(angle_increment))
    return ScanPoints._of(pts, weights(self, features, angle_increment), spacing)


def refine_staged(
    self: Refiner,
    surface: SurfacePoints,
    points: ScanPoints,
    starts: Starts,
    max_distance: float,
    wide: bool,
) -> Refinement | None:
    """``Refiner.refine`` fit by fit (the fused call's reference)."""
    r = self.refinement
    start, hold = starts.start, starts.hold
    best = self.fit(
        surface, points, start, starts.prior, hold, max_distance=max_distance,
        prior_information=starts.prior_information,
    )  # fmt: skip
    if not wide and r.also_from_odometry and _differ(self, start, hold):
        other = self.fit(
            surface, points, hold, hold, hold, max_distance=r.max_distance,
            prior_information=starts.odometry_information,
        )  # fmt: skip
        if other is not None and (
            best is None or other.close_fraction > best.close_fraction + r.both_min_gain
        ):
            best = other
    return best


def _differ(self: Refiner, start: FloatArray, hold: FloatArray) -> bool:
    """Whether the features' motion and the odometry's differ by more than
    ``both_distance`` or ``both_angle`` (in floats: ``start - hold`` elementwise)."""
    r = self.refinement
    sx, sy, st = start.tolist()
    hx, hy, ht = hold.tolist()
    return math.hypot(sx - hx, sy - hy) > r.both_distance or abs(st - ht) > r.both_angle


def refine_fits(
    self: Refiner, surface: SurfacePoints, points: ScanPoints, starts: Starts, wide: bool
) -> Refinement | None:
    """``Refiner.refine`` by :func:`refine_staged` (each fit on its own)."""
    max_distance = self.search.jump_distance if wide else self.refinement.max_distance
    return refine_staged(self, surface, points, starts, max_distance, wide)


def key_prior_covariance(
    self: Uncertainty, t_prev: FloatArray, prior: FloatArray, prior_covariance: FloatArray
) -> FloatArray:
    """The additive covariance, in the keyframe's frame, of the prior from the keyframe: the
    previous scan's pose relative to it carried on by ``prior`` (the floor added)."""
    ja, jb = compose_jacobians(t_prev, prior)
    out: FloatArray = ja @ self._previous @ ja.T + jb @ prior_covariance @ jb.T + self.floor
    return out


def prior_information(
    self: Uncertainty, t_prev: FloatArray, prior: FloatArray, prior_covariance: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """``Uncertainty.prior_information`` in numpy (the kernel's reference)."""
    odometry = key_prior_covariance(self, t_prev, prior, prior_covariance)
    features = odometry + self.feature_covariance()
    inv_features = np.asarray(np.linalg.inv(features), dtype=np.float64)
    inv_odometry = np.asarray(np.linalg.inv(odometry), dtype=np.float64)
    return inv_features, inv_odometry


def assess(
    self: Uncertainty,
    t_prev: FloatArray,
    prior: FloatArray,
    prior_covariance: FloatArray,
    from_key: FloatArray | None,
    fit: Refinement | None,
    gate_open: bool,
    with_scan_only: bool = False,
    key_prior: FloatArray | None = None,
) -> Assessment:
    """``Uncertainty.assess`` in numpy (:func:`assess_numpy` and :func:`scan_only`)."""
    judged = assess_numpy(self, t_prev, prior, prior_covariance, from_key, fit, gate_open)
    return _with_scan_only(self, judged, fit, t_prev) if with_scan_only else judged


def _with_scan_only(
    self: Uncertainty, judged: Assessment, fit: Refinement | None, t_prev: FloatArray
) -> Assessment:
    """``judged`` with :func:`scan_only` of ``fit`` where the fit stands (from the previous
    covariance ``judged`` leaves)."""
    if fit is None or judged.rejected:
        return judged
    scan = scan_only(self, fit, t_prev)
    if scan is None:
        return judged
    return Assessment(
        judged.covariance, judged.keyframe_covariance, judged.gate, judged.rejected, scan
    )


def _compose(a: FloatArray, b: FloatArray) -> FloatArray:
    """``geometry.compose`` of one pose each, in floats."""
    return np.array(compose3(a.tolist(), b.tolist()))


def assess_numpy(
    self: Uncertainty,
    t_prev: FloatArray,
    prior: FloatArray,
    prior_covariance: FloatArray,
    from_key: FloatArray | None,
    fit: Refinement | None,
    gate_open: bool,
) -> Assessment:
    """``Uncertainty.assess`` in numpy (without the scan's own motion): the compiled kernels'
    reference (``_kernels.uncertainty.assessed`` and ``prior_stands``), also where the gate
    rejects the match or nothing was matched (``from_key`` None)."""
    ja, jb = compose_jacobians(t_prev, prior)
    prev = ja @ self._previous @ ja.T
    odo = jb @ prior_covariance @ jb.T
    if from_key is None:
        return prior_stands(self, t_prev, prior, prior_covariance, prev, odo)
    inc = relative(t_prev, from_key)
    jb_inv = jb.T  # a rotation: its inverse is its transpose
    feature = self.feature_covariance()
    if fit is None:  # the features alone: a measurement of the pose relative to the
        # keyframe, independent of the previous scan's error
        kf = feature
        scan_part = feature + prev
        pull = np.zeros((3, 3))
    else:
        kf, scan_part, pull = fit_parts(self, fit, _compose(t_prev, prior), prev, odo, feature)
    inc_cov = jb_inv @ (scan_part + pull @ odo @ pull.T) @ jb_inv.T
    gate, rejected = None, False
    if gate_open:
        # the disagreement with the prior: (pull − 1) of the odometry's error plus the scan's
        k = jb_inv @ pull @ jb - np.eye(3)
        cov_d = jb_inv @ scan_part @ jb_inv.T + k @ prior_covariance @ k.T + self.floor
        d = relative(prior, inc)
        gate = float(d @ np.linalg.solve(cov_d, d))
        rejected = gate > self.threshold
    if rejected:
        return prior_stands(self, t_prev, prior, prior_covariance, prev, odo, gate)
    self._previous = 0.5 * (kf + kf.T)
    return Assessment(
        local(inc_cov, float(inc[2])) + self.floor,
        local(self._previous, float(from_key[2])) + self.floor,
        gate,
    )


def fit_parts(
    self: Uncertainty,
    fit: Refinement,
    key_prior: FloatArray,
    prev: FloatArray,
    odo: FloatArray,
    feature: FloatArray,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """The sandwich of a fit (``fuzzypos.pipeline.uncertainty``'s docstring): the covariance
    relative to the keyframe, the increment's share that is not the odometry's error, and how
    much of the odometry's error the fit took over (``_kernels.uncertainty._fit_parts``'
    reference). The prior's and the hold's terms carry the odometry's error, and a target
    that is not the odometry's motion itself also the features' own error."""
    m = fit.information + fit.prior_information + fit.hold_information
    m_inv = np.linalg.inv(m + 1e-12 * np.eye(3))
    odometric = fit.prior_information + fit.hold_information
    other = np.zeros((3, 3))
    key = key_prior.tolist()
    for term, target in (
        (fit.prior_information, fit.prior),
        (fit.hold_information, fit.start if fit.hold_on_start else key_prior),
    ):
        if max(abs(t - k) for t, k in zip(target.tolist(), key)) > 1e-12:
            other = other + term
    points = self.settings.point_correlation * fit.gradient_covariance
    own = points + other @ feature @ other
    kf = m_inv @ (own + odometric @ (prev + odo) @ odometric) @ m_inv
    rest = m - odometric  # what pulls toward the scan's own evidence
    scan_part = m_inv @ (own + rest @ prev @ rest) @ m_inv
    return kf, scan_part, m_inv @ odometric


def prior_stands(
    self: Uncertainty,
    t_prev: FloatArray,
    prior: FloatArray,
    prior_covariance: FloatArray,
    prev: FloatArray,
    odo: FloatArray,
    gate: float | None = None,
) -> Assessment:
    """The prior stands (``_kernels.uncertainty.prior_stands``' reference): its own
    covariance for the increment; relative to the keyframe the previous scan's carried on
    by it."""
    pose = np.asarray(prior, dtype=float)
    theta = float(t_prev[2] + pose[2])
    kf = local(prev + odo, theta) + self.floor
    self._previous = prev + odo
    return Assessment(
        0.5 * (prior_covariance + prior_covariance.T) + self.floor, kf, gate, gate is not None
    )


def overruled(
    self: Uncertainty,
    held: FloatArray,
    t_prev: FloatArray,
    prior: FloatArray,
    prior_covariance: FloatArray,
) -> Assessment:
    """``Uncertainty.overruled`` in numpy (:func:`prior_stands` from ``held``)."""
    ja, jb = compose_jacobians(t_prev, prior)
    return prior_stands(
        self, t_prev, prior, prior_covariance, ja @ held @ ja.T, jb @ prior_covariance @ jb.T
    )


def scan_only(
    self: Uncertainty, fit: Refinement, t_prev: FloatArray
) -> tuple[FloatArray, FloatArray] | None:
    """``Uncertainty.scan_only`` in numpy (the kernel's reference)."""
    if np.count_nonzero(fit.hold_information):
        return None
    return scan_only_numpy(self, fit, t_prev)


def scan_only_numpy(
    self: Uncertainty, fit: Refinement, t_prev: FloatArray
) -> tuple[FloatArray, FloatArray] | None:
    """:meth:`scan_only` of a fit without a hold, in numpy (the compiled kernel's
    reference)."""
    a = fit.information
    if not np.isfinite(a).all() or np.linalg.cond(a) > _MAX_CONDITION:
        return None
    m = a + fit.prior_information
    x_f = np.asarray(fit.increment, dtype=float)
    # the prior's error is an additive one in the keyframe's frame: wrap its heading near x
    p = np.asarray(fit.prior, dtype=float).copy()
    p[2] = x_f[2] + math.remainder(p[2] - x_f[2], math.tau)
    x_s = np.linalg.solve(a, m @ x_f - fit.prior_information @ p)
    a_inv = np.linalg.inv(a)
    points = self.settings.point_correlation * fit.gradient_covariance
    inc = relative(t_prev, x_s)
    ja, jb = compose_jacobians(t_prev, inc)
    cov = jb.T @ (a_inv @ points @ a_inv + ja @ self._previous @ ja.T) @ jb
    return inc, local(cov, float(inc[2])) + self.floor


#: (module, attribute, its reference) for :func:`oracles.references`
STAND_INS = [
    (local_map.__name__, "LocalMap._map_of", map_of),
    (feature_match.__name__, "_has_variances", _no_variances),
    (feature_match.__name__, "FeatureMatcher.match_lines", match_lines),
    (refine.__name__, "Refiner.points", points),
    (refine.__name__, "Refiner.refine", refine_fits),
    (uncertainty.__name__, "Uncertainty.prior_information", prior_information),
    (uncertainty.__name__, "Uncertainty.assess", assess),
    (uncertainty.__name__, "Uncertainty.scan_only", scan_only),
    (uncertainty.__name__, "Uncertainty.overruled", overruled),
]
