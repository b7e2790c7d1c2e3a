"""The per-scan loop: features, pairing with the odometry prior, pose, trajectory.

``Positioner.update(scan, odom)`` takes each scan in turn with the odometry pose at that scan
(or ``None``). The prior for the motion since the previous scan is the odometry increment
``⊖o_k ⊕ o_{k+1}`` (SPEC) when both scans have odometry, else the last estimated increment. A
scan with too few features or pairs falls back to the prior and is flagged ``degraded``; an
empty or all-invalid scan is not an error but such a degraded estimate.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Iterable, Iterator, Sized, cast

import numpy as np
from scipy.spatial import cKDTree

from .config import Config
from .features import Features, FeaturePoints, Lines, extract_features
from .geometry import Pose2D, compose, relative, transform_points
from .matching import (
    SurfacePoints,
    estimate_increment,
    increment_from_lines,
    pair_features,
    pair_lines,
    refine_point_to_line,
    search_start,
    surface_lengths,
    surface_points,
)
from .scan import LaserScan

__all__ = ["Estimate", "Positioner"]

_END = object()


def _pose(a: np.ndarray) -> Pose2D:
    """A Pose2D from a pose array the pipeline computed (finite, angle wrapped by compose)."""
    x, y, th = float(a[0]), float(a[1]), float(a[2])
    if not (math.isfinite(x) and math.isfinite(y) and -math.pi <= th < math.pi):
        return Pose2D(x, y, th)  # validates and wraps
    return Pose2D._trusted(x, y, th)


@dataclass(frozen=True, eq=False)
class Estimate:
    """The estimate at one scan.

    ``pose``: the robot's pose in the trajectory frame (which starts at the first scan's
    odometry pose, or the origin). ``increment``: the pose of this scan in the frame of the
    previous one (the identity for the first scan). ``prior``: the increment pairing started
    from. ``n_pairs``: the pairs the increment rests on (line pairs where line-to-line matching
    gave it, feature-point pairs where the paper's pairing did). ``degraded``: True where the
    estimate fell back to the prior. ``features``: this scan's features (None unless kept).
    ``odometry_rejected``: the odometry increment was no robot's motion (a jump) and the last
    increment replaced it as the prior. ``refined``: the point-to-line refinement moved it.
    """

    stamp: float
    pose: Pose2D
    increment: Pose2D
    prior: Pose2D
    n_pairs: int
    degraded: bool
    features: Features | None = None
    reason: str = ""
    odometry_rejected: bool = False
    refined: bool = False


class Positioner:
    """Fuzzy-based positioning of a robot from consecutive scans and odometry."""

    def __init__(self, config: Config | None = None) -> None:
        self.config = config if config is not None else Config()
        self.reset()

    def reset(self) -> None:
        self._pose: np.ndarray | None = None
        self._prev_odom: Pose2D | None = None
        self._last_increment = np.zeros(3)
        # the keyframe: the scan the next ones are matched against, its pose and odometry
        self._key_features: Features | None = None
        self._key_pose = np.zeros(3)
        self._key_surface: SurfacePoints | None = None
        self._recent: list[tuple[SurfacePoints, np.ndarray]] = []
        # the previous scan's features where it is not the keyframe (its pose is ``_pose``)
        self._prev_features: Features | None = None
        self._prev_stamp: float | None = None
        self._last_dt = 0.0
        #: odometry increments rejected as jumps so far
        self.odometry_jumps = 0

    @property
    def pose(self) -> Pose2D | None:
        """The latest pose estimate (None before the first scan)."""
        return None if self._pose is None else Pose2D.from_array(self._pose)

    def update(self, scan: LaserScan, odom: Pose2D | None = None) -> Estimate:
        """Process the next scan; ``odom`` is the odometry pose at this scan, if any."""
        if not isinstance(scan, LaserScan):
            raise TypeError(f"update() needs a LaserScan, got {type(scan).__name__}")
        if odom is not None and not isinstance(odom, Pose2D):
            raise TypeError(f"odom must be a Pose2D or None, got {type(odom).__name__}")
        cfg = self.config

        if self._pose is None:  # the first scan: its odometry pose, or the origin
            features = extract_features(scan, cfg)
            start = odom.as_array() if odom is not None else np.zeros(3)
            self._pose = start
            self._prev_odom = odom
            self._prev_stamp = scan.stamp
            self._set_keyframe(features, start)
            zero = Pose2D()
            return Estimate(scan.stamp, Pose2D.from_array(start), zero, zero, 0, False, features)

        # the prior for this scan's motion: the odometry increment, else the last increment
        rejected = False
        odo_inc = None
        dt = max(0.0, scan.stamp - cast(float, self._prev_stamp))
        if odom is not None and self._prev_odom is not None:
            odo_inc = relative(self._prev_odom.as_array(), odom.as_array())
            rejected = self._is_jump(odo_inc, dt)
        self._prev_stamp = scan.stamp
        if odo_inc is not None and not rejected:
            prior = odo_inc
        elif rejected:  # the last motion, at most as far as it went in its own time step
            ratio = min(1.0, dt / self._last_dt) if self._last_dt > 0 else 1.0
            prior = self._last_increment * ratio
        else:
            prior = self._last_increment
        if rejected:
            self.odometry_jumps += 1
        standing = (
            odo_inc is not None
            and cfg.odometry.trust_stand_still
            and odom == self._prev_odom  # the very same pose: the wheels did not turn
        )
        self._prev_odom = odom

        if standing:  # the odometry says the robot stands still: so does the estimate
            self._last_increment = np.zeros(3)
            self._last_dt = dt
            zero = Pose2D()
            return Estimate(scan.stamp, _pose(self._pose), zero, zero, 0, False, None, "standing still")

        features = extract_features(scan, cfg)
        # the same prior from the keyframe: what was estimated up to the previous scan, then it
        key_prior = compose(relative(self._key_pose, self._pose), prior)
        from_key, n_pairs, reason = self._motion(cast(Features, self._key_features), features, key_prior)
        refined = False
        lines_suffice = (
            from_key is not None
            and cfg.refinement.skip_with_line_pairs > 0
            and n_pairs >= cfg.refinement.skip_with_line_pairs
        )
        if cfg.refinement.enabled and not lines_suffice:
            start = key_prior if from_key is None else from_key
            refine_from_start = from_key is not None and cfg.refinement.prior_from_features
            gap = dt > cfg.odometry.search_after_gap
            better = self._refine(
                features, start, start if refine_from_start else key_prior, key_prior, rejected, gap,
                scan.angle_increment,
            )
            if better is not None:
                from_key, refined = better, True
                if n_pairs == 0:
                    reason = ""
        degraded = from_key is None
        if from_key is None:  # fall back to the prior, and start afresh from this scan
            increment = np.asarray(prior, dtype=float)
            pose = compose(self._pose, increment)
        else:
            pose = compose(self._key_pose, from_key)
            increment = relative(self._pose, pose)
        m = cfg.matching
        if (
            degraded
            or math.hypot(from_key[0], from_key[1]) >= m.keyframe_distance
            or abs(from_key[2]) >= m.keyframe_angle
        ):
            self._set_keyframe(features, pose)
        else:
            self._prev_features = features
        self._pose = pose
        self._last_increment = increment
        self._last_dt = dt
        return Estimate(
            stamp=scan.stamp,
            pose=_pose(pose),
            increment=_pose(increment),
            prior=_pose(prior),
            n_pairs=n_pairs,
            degraded=degraded,
            features=features,
            reason=reason,
            odometry_rejected=rejected,
            refined=refined,
        )

    def _is_jump(self, increment: np.ndarray, dt: float) -> bool:
        """An odometry increment no robot makes: faster than ``max_speed`` / ``max_turn_rate``
        over ``dt`` plus the allowances (stamps of real logs are not acquisition times)."""
        o = self.config.odometry
        dist = math.hypot(increment[0], increment[1])
        return bool(
            dist > o.max_speed * dt + o.max_jump_distance
            or abs(increment[2]) > o.max_turn_rate * dt + o.max_jump_angle
        )

    def _refine(
        self, features: Features, start: np.ndarray, prior: np.ndarray, hold: np.ndarray,
        wide: bool, gap: bool, angle_increment: float,
    ) -> np.ndarray | None:
        """The point-to-line refinement of ``start`` against the keyframe; None where too few
        points pair or it moves further than ``max_correction``. After an odometry jump
        (``wide``), or where it fails after a gap in time (``gap``), a wider search of every
        rotation and of translations within ``jump_search_distance`` gives the start too."""
        r = self.config.refinement
        if self._key_surface is None:
            self._key_surface = self._local_map()
        # every valid point: the paper's filter (§3.1) drops grazing points that still tell
        # where a wall is
        pts = features.points
        if pts.shape[0] < r.min_points:
            return None
        weights = np.clip(1.0 - features.uncertainty, 0.05, 1.0)
        if r.length_weight_max > 1.0:
            # each point weighs the stretch of surface it stands for (over the scan's median):
            # the fit is one over the surfaces' length, not over the beams, and dense clutter
            # next to the robot (people, a desk) no longer outvotes the walls
            length = surface_lengths(pts, features.ranges, angle_increment, r.length_cap)
            median = float(np.median(length))
            if median > 0.0:
                weights = weights * np.clip(
                    length / median, 1.0 / r.length_weight_max, r.length_weight_max
                )
        o = self.config.odometry
        best = self._refine_from(
            pts, weights, start, prior, o.jump_search_distance if wide else r.max_distance, hold
        )
        differ = start - hold
        if not wide and r.also_from_odometry and (
            math.hypot(differ[0], differ[1]) > r.both_distance or abs(differ[2]) > r.both_angle
        ):
            # the features' motion and the odometry's disagree: refine from the odometry's too
            # (with it as the prior) and keep that one where it puts clearly more of the scan
            # (2 % of its points) close to its surfaces (a refinement settles where it starts)
            other = self._refine_from(pts, weights, hold, hold, r.max_distance, hold)
            if other is not None and (best is None or other[2] > best[2] + 0.02):
                best = other
        if wide or best is None:
            # a wider search: the prior is a jump or came after a gap in time (every rotation),
            # or nothing near it matched (a narrower one)
            full = wide or gap
            # after a jump or a gap the previous scan joins the map: the latest view of the
            # place overlaps most with a scan taken after a fast turn (aces, scan 2,945)
            surface = self._search_map() if full else self._key_surface
            searched, score = search_start(
                surface, pts, start,
                o.search_angle if full else o.failure_search_angle, o.search_angle_step,
                o.search_gate, o.jump_search_distance if full else o.failure_search_distance,
                o.search_translation_step, distance_penalty=o.search_distance_penalty,
            )
            if best is None or score > best[1]:
                if full:  # after a jump or a gap the odometry has lost its say
                    found = self._refine_from(
                        pts, weights, searched, searched, o.jump_search_distance, hold,
                        weak_prior=True, surface=surface,
                    )
                else:
                    # after a failure it keeps it: the search only gives another start, and
                    # the result must still agree with the odometry (a corridor's repeating
                    # doors would otherwise pull the scan along it)
                    found = self._refine_from(pts, weights, searched, hold, r.max_distance, hold)
                if found is not None and (best is None or found[1] > best[1]):
                    best = found
        return None if best is None else best[0]

    def _refine_from(
        self, pts: np.ndarray, weights: np.ndarray, start: np.ndarray, prior: np.ndarray,
        max_distance: float, hold: np.ndarray, weak_prior: bool = False,
        surface: SurfacePoints | None = None,
    ) -> tuple[np.ndarray, float, float] | None:
        """One refinement against ``surface`` (the keyframes' by default); ``weak_prior``: the
        prior barely counts (after a wide search)."""
        r = self.config.refinement
        res = refine_point_to_line(
            cast(SurfacePoints, self._key_surface if surface is None else surface), pts, weights,
            start, prior,
            max_distance=max_distance, min_distance=r.min_distance, iterations=r.iterations,
            residual_scale=r.residual_scale, point_sigma=r.point_sigma,
            degenerate_ratio=r.degenerate_ratio, hold=hold, hold_tolerance=r.hold_tolerance,
            prior_sigma=r.prior_sigma * (100.0 if weak_prior else 1.0),
            prior_sigma_angle=r.prior_sigma_angle * (100.0 if weak_prior else 1.0),
        )
        min_fraction = (
            self.config.odometry.search_min_inlier_fraction if weak_prior else r.min_inlier_fraction
        )
        if res is None or res.n_paired < r.min_points or res.inlier_fraction < min_fraction:
            return None
        limit = self.config.odometry.jump_search_distance if weak_prior else r.max_correction
        if math.hypot(res.increment[0] - start[0], res.increment[1] - start[1]) > limit:
            return None
        return res.increment, res.inlier_fraction, res.close_fraction

    def _set_keyframe(self, features: Features, pose: np.ndarray) -> None:
        self._key_features = features
        self._key_pose = pose
        self._key_surface = None
        self._prev_features = None  # the latest scan is the keyframe itself
        r = self.config.refinement
        if not r.enabled:
            return
        surface = self._surface_of(features)
        # the local map: the surfaces of the last ``local_map_keyframes`` keyframes, each with
        # the pose it was seen from
        self._recent.append((surface, np.asarray(pose, dtype=float)))
        del self._recent[: -r.local_map_keyframes]

    def _surface_of(self, features: Features) -> SurfacePoints:
        r = self.config.refinement
        return surface_points(
            features.points, features.ranges, features.uncertainty, r.neighbour_distance,
            r.neighbour_step, r.neighbour_ratio, r.max_bend_angle,
        )

    def _search_map(self) -> SurfacePoints:
        """The local map and the previous scan (where it is not the keyframe)."""
        if self._prev_features is None or self._prev_features.points.shape[0] == 0:
            return cast(SurfacePoints, self._key_surface)
        return self._map_of([*self._recent, (self._surface_of(self._prev_features), self._pose)])

    def _local_map(self) -> SurfacePoints:
        """The recent keyframes' surface points in the current keyframe's frame, one KD-tree."""
        parts = self._recent
        if len(parts) == 1:
            return parts[0][0]
        return self._map_of(parts)

    def _map_of(self, parts: list[tuple[SurfacePoints, np.ndarray]]) -> SurfacePoints:
        """Surface points seen from the given poses, in the keyframe's frame, one KD-tree."""
        xy, normal, weight = [], [], []
        for surf, pose in parts:
            rel = relative(self._key_pose, pose)
            xy.append(transform_points(rel, surf.xy))
            c, s_ = math.cos(rel[2]), math.sin(rel[2])
            n = surf.normal
            normal.append(np.stack((c * n[:, 0] - s_ * n[:, 1], s_ * n[:, 0] + c * n[:, 1]), axis=1))
            weight.append(surf.weight)
        all_xy = np.concatenate(xy)
        return SurfacePoints(all_xy, np.concatenate(normal), np.concatenate(weight), cKDTree(all_xy))

    def _motion(
        self, prev: Features, features: Features, prior: np.ndarray
    ) -> tuple[np.ndarray | None, int, str]:
        """The motion from ``prev`` to ``features``: line matching from the prior first (where
        configured), else the paper's point pairing (refined by line matching). None where
        nothing gives a motion."""
        m = self.config.matching
        increment = None
        n_pairs, reason = 0, ""
        lines_tried = m.match_lines and m.lines_first
        if lines_tried:
            increment, n_pairs = self._match_lines(prev.lines, features.lines, None, prior)
        if increment is None:  # the paper's point features (and lines from their motion)
            increment, n_pairs, reason = self._match(prev.points_of_interest, features.points_of_interest, prior)
            if m.match_lines and (increment is not None or not lines_tried):
                refined, n_lines = self._match_lines(prev.lines, features.lines, increment, prior)
                if refined is not None:
                    increment, n_pairs, reason = refined, n_lines, ""
        return increment, n_pairs, reason

    def _match(
        self, prev: FeaturePoints, curr: FeaturePoints, prior: np.ndarray
    ) -> tuple[np.ndarray | None, int, str]:
        """The paper's way (§3.7, §4): pair the feature points with the prior, the pose from
        every two pairs, fusion; re-paired with the refined motion where configured."""
        cfg = self.config
        m = cfg.matching
        if len(prev) < m.min_pairs or len(curr) < m.min_pairs:
            return None, 0, "too few features"
        pairs = pair_features(prev, curr, prior, m.pairing_distance, m.same_kind_only, m.mutual)
        est, n_used = estimate_increment(pairs, cfg.fusion, m.min_pair_separation, m.min_pairs)
        if est is None:
            return None, len(pairs), "too few pairs"
        for _ in range(m.repair_iterations):  # re-pair with the refined motion
            pairs = pair_features(prev, curr, est, m.repair_distance, m.same_kind_only, m.mutual)
            refined, n_refined = estimate_increment(pairs, cfg.fusion, m.min_pair_separation, m.min_pairs)
            if refined is None:
                break
            est, n_used = refined, n_refined
        return est, n_used, ""

    def _match_lines(
        self, prev: Lines, curr: Lines, start: np.ndarray | None, prior: np.ndarray
    ) -> tuple[np.ndarray | None, int]:
        """Line-to-line matching from the point features' motion (or the prior), and once more
        from its own result where that moved enough to change the pairs. Returns the increment
        (None where the lines give none) and the number of line pairs."""
        m = self.config.matching
        if start is None:
            pose, gates = prior, (m.line_angle_gate_prior, m.line_distance_gate_prior)
        else:
            pose, gates = start, (m.line_angle_gate, m.line_distance_gate)
        est, n_pairs = None, 0
        for _ in range(2):
            pairs = pair_lines(prev, curr, pose, gates[0], gates[1], m.line_overlap_margin)
            if len(pairs) < m.line_min_pairs:
                break
            new = increment_from_lines(
                prev, curr, pairs, pose, prior, m.line_prior_sigma, m.line_trim_angle,
                m.line_inlier_distance,
            )
            if new is None:
                break
            moved = np.abs(new - pose)
            est = pose = new
            n_pairs = len(pairs)
            # pair again with the refined motion, unless it moved too little to change pairs
            if moved[0] + moved[1] < 0.1 * m.line_distance_gate and moved[2] < 0.1 * m.line_angle_gate:
                break
            gates = (m.line_angle_gate, m.line_distance_gate)
        return est, n_pairs

    def run(
        self,
        scans: Iterable[LaserScan],
        odoms: Iterable[Pose2D | None] | None = None,
        keep_features: bool = False,
    ) -> list[Estimate]:
        """Process a sequence; ``odoms`` (same length, entries may be None) is optional."""
        if odoms is not None and isinstance(scans, Sized) and isinstance(odoms, Sized):
            if len(odoms) != len(scans):
                raise ValueError(
                    f"odoms has {len(odoms)} poses for {len(scans)} scans: give one per scan"
                )
        return list(self.iter_run(scans, odoms, keep_features))

    def iter_run(
        self,
        scans: Iterable[LaserScan],
        odoms: Iterable[Pose2D | None] | None = None,
        keep_features: bool = False,
    ) -> Iterator[Estimate]:
        """Like :meth:`run`, one estimate at a time (for streaming long logs)."""
        odom_iter = iter(odoms) if odoms is not None else None
        for k, scan in enumerate(scans):
            odom = None
            if odom_iter is not None:
                try:
                    odom = next(odom_iter)
                except StopIteration:
                    raise ValueError(f"odoms ran out at scan {k}: give one odometry pose per scan") from None
            est = self.update(scan, odom)
            if not keep_features:
                est = replace(est, features=None)
            yield est
        if odom_iter is not None and next(odom_iter, _END) is not _END:
            raise ValueError("odoms has more poses than there were scans: give one per scan")
