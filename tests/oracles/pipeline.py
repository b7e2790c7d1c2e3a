"""The numpy references of ``fuzzypos.pipeline``'s kernels (``_kernels.pipeline``,
``_kernels.refine``, ``_kernels.uncertainty``): the code each replaced, the tests' oracles."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from fuzzypos.features import Features
from fuzzypos.geometry import compose_jacobians, relative, relative3, stack_columns
from fuzzypos.matching import Refinement, surface_lengths
from fuzzypos.matching._robust import median as _median
from fuzzypos.matching.surface import SurfacePoints
from fuzzypos.pipeline import feature_match, local_map, refine, uncertainty
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
    """``feature_match._has_variances``' stand-in: no lines go to the compiled line matching
    (``FeatureMatcher.match_lines`` takes its staged passes)."""
    return False


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


def prior_information(
    self: Uncertainty, t_prev: FloatArray, prior: FloatArray, prior_covariance: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """``Uncertainty.prior_information`` in numpy (the kernel's reference)."""
    odometry = self.key_prior_covariance(t_prev, prior, prior_covariance)
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
    """``Uncertainty.assess`` in numpy (``_assess_numpy`` and :func:`scan_only`)."""
    judged = self._assess_numpy(t_prev, prior, prior_covariance, from_key, fit, gate_open)
    return self._with_scan_only(judged, fit, t_prev) if with_scan_only else judged


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
    (refine.__name__, "Refiner.points", points),
    (refine.__name__, "Refiner.refine", refine_fits),
    (uncertainty.__name__, "Uncertainty.prior_information", prior_information),
    (uncertainty.__name__, "Uncertainty.assess", assess),
    (uncertainty.__name__, "Uncertainty.scan_only", scan_only),
]
