"""The localizer: where in a known map the robot is, from its scans and odometry.

While it does not know (SEARCHING, or LOST after tracking failed) it keeps up to
``max_hypotheses`` distinct places: the whole map is searched for the places that explain the
scan (:class:`~.search.GlobalSearch`), again every ``research_interval`` scans; each place is
carried by the odometry and fitted to the map at every scan, and scores the scan's
log-likelihood there. A new place is scored back over the scans the window holds (followed
backward by the odometry, fitted at each), so all places are weighed over the same scans.
It decides when the best place beats every distinct rival by ``evidence_margin`` over the
window, fits the scans well, and agrees with the map in absolute terms (few beams through
its walls, few points in its free space: :mod:`.consistency`, within a binomial bound of
the share a right pose gives); places that look the same (two identical rooms) never do,
nor a map of another building, and it keeps searching. Then it tracks: the odometry's step
as the prior, the scan fitted to the map's walls (point-to-line Gauss-Newton), the
covariance from the fit's Hessian and residuals. A fit that fails ``lost_scans`` times in a
row, or beams crossing the map's walls over ``lost_scans`` scans beyond the bound, make it
LOST, and it searches again (docs/localization.md)."""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from .._kernels.localize import FIT_OK, fit, likelihood
from ..config import Config
from ..config.localization import LocalizationConfig
from ..geometry import Pose2D, compose, inverse, relative
from ..io.occupancy_map import OccupancyMap
from ..scan import LaserScan
from .consistency import agreement
from .field import MapField, field_of
from .search import MIN_POINTS, Candidate, GlobalSearch, thin
from .types import InitialPoseError, LocalizationEstimate, LocalizerState

__all__ = ["Localizer"]

FloatArray = NDArray[np.float64]


@dataclass
class _Place:
    """A hypothesis: its pose now (grid frame) and its log-likelihood and fit per scan of the
    window (oldest first)."""

    pose: FloatArray
    evidence: deque[float]
    fits: deque[float]
    poses: deque[FloatArray]
    information: FloatArray = field(default_factory=lambda: np.zeros((3, 3)))
    residual: float = 0.0

    def total(self) -> float:
        return float(sum(self.evidence))


@dataclass
class _Fit:
    """A fit of one scan: the pose, its covariance (grid frame), the fit (0..1) and the
    scan's log-likelihood (per effective point count)."""

    pose: FloatArray
    covariance: FloatArray
    fit: float
    evidence: float
    ok: bool


class Localizer:
    """Localisation in ``occupancy_map`` (module docstring); ``initial_pose`` (map frame,
    with ``initial_sigma`` = (m, rad)) as :meth:`set_initial_pose`."""

    def __init__(
        self,
        occupancy_map: OccupancyMap,
        config: Config | None = None,
        *,
        initial_pose: Pose2D | Sequence[float] | None = None,
        initial_sigma: tuple[float, float] | None = None,
    ) -> None:
        cfg = config if config is not None else Config()
        self._cfg = cfg.localization
        self._bands = tuple(cfg.scanner.no_return_bands)
        self._field: MapField = field_of(occupancy_map, self._cfg)
        self._search = GlobalSearch(self._field, self._cfg)
        self._state = LocalizerState.SEARCHING
        self._places: list[_Place] = []
        self._history: deque[tuple[FloatArray, FloatArray]] = deque(
            maxlen=self._cfg.evidence_window
        )
        self._since_search = 0
        self._last_odom: FloatArray | None = None
        self._pose: FloatArray | None = None
        self._covariance: FloatArray | None = None
        self._bad = 0
        self._drop = 0
        self._level = 0.0
        self._cooldown = 0
        self._pending: tuple[FloatArray, tuple[float, float]] | None = None
        self._sensor = np.zeros(2)
        self._crossings: deque[float] = deque(maxlen=self._cfg.lost_scans)
        # the crossing and contradicted shares of the tracked scans (running means)
        self._levels = [self._cfg.crossing_share, self._cfg.contradicted_share]
        if initial_pose is not None:
            self.set_initial_pose(initial_pose, initial_sigma)

    @property
    def state(self) -> LocalizerState:
        return self._state

    @property
    def field(self) -> MapField:
        """The map as the localizer reads it."""
        return self._field

    @property
    def settings(self) -> LocalizationConfig:
        """Its ``[localization]`` settings."""
        return self._cfg

    @property
    def search(self) -> GlobalSearch:
        """Its search of the whole map."""
        return self._search

    def points_of(self, scan: LaserScan) -> FloatArray:
        """The scan's points the localizer fits (robot frame): its usable readings (not in
        the scanner's no-return bands), one per map cell, at most max_points."""
        return self._points(scan)

    # -- the user's word ---------------------------------------------------------------------
    def set_initial_pose(
        self, pose: Pose2D | Sequence[float], sigma: tuple[float, float] | None = None
    ) -> None:
        """Where the robot is (map frame), to within ``sigma`` = (m, rad) (default
        initial_sigma_*): the next scan is searched for within 3σ of it and tracked from
        there, whatever the localizer believed. Raises :class:`InitialPoseError` for a pose
        off the map or farther than initial_free_distance from its free space."""
        p = Pose2D.of(pose, "initial pose")
        if sigma is None:
            sigma = (self._cfg.initial_sigma_translation, self._cfg.initial_sigma_rotation)
        st, sr = (float(v) for v in sigma)
        if not (math.isfinite(st) and math.isfinite(sr) and st >= 0.0 and sr >= 0.0):
            raise InitialPoseError(
                f"initial pose sigma must be two finite values >= 0, got {sigma!r}"
            )
        grid = self._field.to_grid(p.as_array())
        gap = self._field.distance_to_free(grid)
        if gap > self._cfg.initial_free_distance:
            where = "off the map" if math.isinf(gap) else f"{gap:.2f} m from the map's free space"
            raise InitialPoseError(
                f"initial pose ({p.x:.3f}, {p.y:.3f}, {math.degrees(p.theta):.1f}°) lies {where}"
            )
        self._pending = (grid, (st, sr))

    # -- each scan ---------------------------------------------------------------------------
    def update(
        self, scan: LaserScan, odom: Pose2D | Sequence[float] | None = None
    ) -> LocalizationEstimate:
        """The estimate at this scan, with the odometry pose at it (None: no odometry, the
        robot taken as standing still between scans)."""
        step = np.zeros(3)
        if odom is not None:
            o = Pose2D.of(odom, "odometry").as_array()
            if self._last_odom is not None:
                step = relative(self._last_odom, o)
            self._last_odom = o
        points = self._points(scan)
        self._sensor = scan.sensor_pose.as_array()[:2]
        if self._pending is not None:
            return self._start_at(scan.stamp, points, step)
        if self._state is LocalizerState.TRACKING:
            return self._track(scan.stamp, points, step)
        return self._look(scan.stamp, points, step)

    def _points(self, scan: LaserScan) -> FloatArray:
        pts = scan.points_robot(self._bands)
        pts = pts[np.isfinite(pts).all(axis=1)]
        return thin(
            np.ascontiguousarray(pts, dtype=np.float64),
            self._field.resolution,
            self._cfg.max_points,
        )

    # -- fitting -----------------------------------------------------------------------------
    def _prior(self, step: FloatArray) -> FloatArray:
        """The information of the odometry's step as the fit's prior."""
        cfg = self._cfg
        st = cfg.odometry_translation + cfg.odometry_fraction * math.hypot(step[0], step[1])
        sr = cfg.odometry_rotation + cfg.odometry_fraction * abs(step[2])
        return np.diag([st**-2, st**-2, sr**-2])

    def _fit(
        self,
        points: FloatArray,
        start: FloatArray,
        information: FloatArray,
        prior: FloatArray | None = None,
    ) -> _Fit:
        """The scan fitted to the walls from ``start``, the prior's centre ``prior`` (default
        ``start``) with ``information``."""
        cfg = self._cfg
        settings = np.array(
            [cfg.fit_gate, cfg.hit_sigma / 2.0, cfg.fit_iterations], dtype=np.float64
        )
        centre = start if prior is None else prior
        pose, h, sse, wsum, used, status = fit(
            points, start, centre, information, self._field.walls, settings
        )
        loglik, quality = likelihood(
            points, pose, self._field.walls, cfg.hit_sigma, cfg.outlier_probability
        )
        evidence = loglik * cfg.effective_points / max(points.shape[0], 1)
        cov = self._covariance_of(h, sse, wsum, used, quality)
        ok = status == FIT_OK and quality >= cfg.min_fit and cov is not None
        return _Fit(pose, cov if cov is not None else np.eye(3), quality, evidence, ok)

    def _covariance_of(
        self, h: FloatArray, sse: float, wsum: float, used: int, quality: float
    ) -> FloatArray | None:
        """σ̂² H⁻¹ (σ̂² the weighted residual variance), the points counted as
        covariance_points independent ones, plus the floor, grown by the fit's power."""
        cfg = self._cfg
        if used < 6 or abs(np.linalg.det(h)) < 1e-12:
            return None
        var = sse / max(wsum - 3.0, 1.0)
        scale = max(1.0, used / cfg.covariance_points)
        cov = var * scale * np.linalg.inv(h)
        floor_t = cfg.covariance_floor_cells * self._field.resolution
        floor = np.diag([floor_t**2, floor_t**2, cfg.covariance_floor_rotation**2])
        grow = max(quality, 0.05) ** -cfg.covariance_fit_power
        out: FloatArray = (0.5 * (cov + cov.T) + floor) * grow
        return out

    # -- tracking ----------------------------------------------------------------------------
    def _start_at(self, stamp: float, points: FloatArray, step: FloatArray) -> LocalizationEstimate:
        """The first scan after an initial pose: searched for around it, then tracked."""
        assert self._pending is not None
        grid, (st, sr) = self._pending
        self._pending = None
        reach = (3.0 * st, 3.0 * sr)
        found = self._search.search(points, grid, reach, limit=1)
        start = found[0].pose if found else grid
        result = self._fit(points, start, self._prior(np.zeros(3)) * 1e-6)
        if not result.ok:
            result = _Fit(
                grid, np.diag([st**2 + 1e-6, st**2 + 1e-6, sr**2 + 1e-8]), result.fit, 0.0, False
            )
        self._begin_tracking(result)
        return self._tracking_estimate(
            stamp, None, result, "initial pose" if result.ok else "initial pose (no fit)"
        )

    def _begin_tracking(self, result: _Fit) -> None:
        self._state = LocalizerState.TRACKING
        self._pose = result.pose
        self._covariance = result.covariance
        self._places.clear()
        self._history.clear()
        self._bad = 0
        self._drop = 0
        self._level = result.fit
        self._cooldown = 0
        self._crossings.clear()

    def _track(self, stamp: float, points: FloatArray, step: FloatArray) -> LocalizationEstimate:
        assert self._pose is not None and self._covariance is not None
        cfg = self._cfg
        self._history.append((points, step))
        predicted = compose(self._pose, step)
        information = self._prior(step)
        result = self._fit(points, predicted, information)
        st, sr = information[0, 0] ** -0.5, information[2, 2] ** -0.5
        large = st > cfg.hit_sigma or sr > 2.0 * cfg.odometry_rotation
        poor = not result.ok or result.fit < self._level - cfg.fit_drop
        if large or poor:
            # a long step (a keyframe log), a failed fit or one well below the fit's level (an
            # odometry that jumped): the scan searched for around the prediction, within 3σ
            # of the odometry (at least 0.5 m and 10° after a poor fit)
            reach = (3.0 * st, 3.0 * sr)
            if poor:
                reach = (max(reach[0], 0.5), max(reach[1], math.radians(10.0)))
            found = self._search.search(points, predicted, reach, limit=1)
            if found:
                retry = self._fit(points, found[0].pose, information)
                if retry.ok and (not result.ok or retry.evidence > result.evidence):
                    result = retry
        previous = self._covariance
        self._watch(result.fit if result.ok else 0.0)
        if result.ok:
            self._bad = 0
            self._pose, self._covariance = result.pose, result.covariance
            if not self._agrees(points, result.pose):
                self._go_lost(points, result.pose, keep=False)
                return self._searching_estimate(
                    stamp, 0.0, "lost: the scans' beams cross the map's walls"
                )
            if self._drop >= cfg.lost_scans and self._cooldown == 0 and self._elsewhere(points):
                return self._searching_estimate(stamp, 0.0, "lost: another place fits better")
            return self._tracking_estimate(stamp, previous, result, "matched")
        self._bad += 1
        if self._bad >= cfg.lost_scans:
            self._go_lost(points, self._pose, keep=False)
            return self._searching_estimate(stamp, 0.0, "lost: the map no longer fits the scans")
        grown = _propagate(previous, self._pose, step, self._prior(step))
        self._pose, self._covariance = predicted, grown
        coasting = _Fit(predicted, grown, result.fit, result.evidence, False)
        return self._tracking_estimate(
            stamp, previous, coasting, "odometry only: the scan does not fit"
        )

    def _watch(self, quality: float) -> None:
        """The fit's level (its running mean over about 1/fit_level_rate scans) and how many
        scans in a row fell below it by fit_drop: a sudden lasting drop is a robot carried to
        a place alike enough to fit, or a map that no longer holds."""
        cfg = self._cfg
        self._cooldown = max(0, self._cooldown - 1)
        if quality < self._level - cfg.fit_drop:
            self._drop += 1
        else:
            self._drop = 0
            self._level += cfg.fit_level_rate * (quality - self._level)

    def _elsewhere(self, points: FloatArray) -> bool:
        """Whether a place of the whole map explains the scans since the fit dropped better
        than the tracked one by evidence_margin: then LOST, those places its hypotheses."""
        assert self._pose is not None
        cfg = self._cfg
        recent = list(self._history)[-self._drop :]
        self._history = deque(recent, maxlen=cfg.evidence_window)
        # the tracked place's evidence over the same scans, fitted backward like the others
        here = self._backfill(self._fit(points, self._pose, self._prior(np.zeros(3)) * 1e-4))
        candidates = self._search.search(points)
        for cand in candidates:
            if _same(cand.pose, self._pose, cfg.separation, cfg.separation_angle):
                continue
            result = self._fit(points, cand.pose, self._prior(np.zeros(3)) * 1e-4)
            there = self._backfill(result)
            if there.total() - here.total() >= cfg.evidence_margin:
                self._go_lost(points, self._pose, keep=True, recent=recent, found=candidates)
                return True
        self._history = deque(recent, maxlen=cfg.evidence_window)
        self._drop = 0
        self._cooldown = 10 * cfg.research_interval
        return False

    # -- the scans against the map, in absolute terms --------------------------------------
    def _shares(self, points: FloatArray, pose: FloatArray) -> tuple[float, float]:
        """The shares of the scan's points the map contradicts at ``pose``: beams crossing its
        walls, and those plus points ending in its free space away from every wall (all of
        them where the robot would stand off the map's free space)."""
        near = 2.0 * self._cfg.hit_sigma
        if self._field.distance_to_free(pose) > near:
            return 1.0, 1.0
        a = agreement(self._field, points, self._sensor, pose, near)
        n = max(a.points, 1)
        return a.through / n, (a.through + a.strays) / n

    def _bound(self, expected: float, scans: int, z: float) -> float:
        """The largest mean share over ``scans`` scans a right pose gives: ``expected`` plus
        ``z`` binomial standard errors of effective_points per scan."""
        n = self._cfg.effective_points * scans
        return expected + z * math.sqrt(expected * (1.0 - expected) / n)

    def _contradicted(self, place: _Place) -> tuple[float, float]:
        """A place's contradicted share (crossings and strays) over the last min_scans scans
        (its poses there): their mean and the last scan's."""
        scans = list(self._history)[-self._cfg.min_scans :]
        poses = list(place.poses)[-len(scans) :]
        shares = [self._shares(pts, pose)[1] for (pts, _), pose in zip(scans, poses, strict=True)]
        return (float(np.mean(shares)), shares[-1]) if shares else (1.0, 1.0)

    def _agrees(self, points: FloatArray, pose: FloatArray) -> bool:
        """Whether the tracked scans still agree with the map: the mean crossing share of the
        last lost_scans scans within its bound; the levels learned from the scans that do."""
        cfg = self._cfg
        crossing, contradicted = self._shares(points, pose)
        self._crossings.append(crossing)
        if len(self._crossings) < cfg.lost_scans:
            return True
        mean = float(np.mean(self._crossings))
        expected = max(cfg.crossing_share, self._levels[0])
        if mean > self._bound(expected, cfg.lost_scans, cfg.crossing_lost_z):
            return False
        self._levels[0] += cfg.fit_level_rate * (crossing - self._levels[0])
        self._levels[1] += cfg.fit_level_rate * (contradicted - self._levels[1])
        return True

    def _go_lost(
        self,
        points: FloatArray,
        pose: FloatArray,
        *,
        keep: bool,
        recent: list | None = None,
        found: list[Candidate] | None = None,
    ) -> None:
        """LOST: the places of a global search (and the tracked one, where ``keep``) are the
        hypotheses, weighed over the ``recent`` scans."""
        cfg = self._cfg
        self._state = LocalizerState.LOST
        self._pose = self._covariance = None
        self._history = deque(recent or [], maxlen=cfg.evidence_window)
        self._places = []
        if keep and self._history:
            now = self._fit(points, pose, self._prior(np.zeros(3)) * 1e-4)
            self._places.append(self._backfill(now))
        if self._history:
            self._add_places(points, found)
            self._since_search = 1
        else:
            self._since_search = 0
        self._prune()

    def _tracking_estimate(
        self, stamp: float, previous: FloatArray | None, result: _Fit, reason: str
    ) -> LocalizationEstimate:
        assert self._pose is not None and self._covariance is not None
        yaw = float(self._field.origin[2])
        cov = _rotated(self._covariance, yaw)
        robot = _rotated(self._covariance, -float(self._pose[2]))
        step_cov = robot + (
            _rotated(previous, -float(self._pose[2])) if previous is not None else 0.0
        )
        return LocalizationEstimate(
            stamp,
            LocalizerState.TRACKING,
            self._field.pose_of(self._pose),
            cov,
            step_cov,
            float(np.clip(result.fit, 0.0, 1.0)),
            reason,
        )

    # -- searching ---------------------------------------------------------------------------
    def _look(self, stamp: float, points: FloatArray, step: FloatArray) -> LocalizationEstimate:
        """One scan while not localised: the places followed, new ones searched for, and the
        vote."""
        cfg = self._cfg
        self._history.append((points, step))
        for place in self._places:
            result = self._fit(points, compose(place.pose, step), self._prior(step))
            place.pose = result.pose
            place.information = result.covariance
            place.evidence.append(result.evidence)
            place.fits.append(result.fit)
            place.poses.append(result.pose)
        if self._since_search % cfg.research_interval == 0:
            self._add_places(points)
        self._since_search += 1
        self._prune()
        return self._vote(stamp, points)

    def _add_places(self, points: FloatArray, found: list[Candidate] | None = None) -> None:
        """The places a search of the whole map finds for this scan (``found``: already
        searched), backfilled, where they are new."""
        cfg = self._cfg
        for cand in self._search.search(points) if found is None else found:
            result = self._fit(points, cand.pose, self._prior(np.zeros(3)) * 1e-4)
            if any(
                _same(result.pose, p.pose, cfg.separation, cfg.separation_angle)
                for p in self._places
            ):
                continue
            self._places.append(self._backfill(result))

    def _backfill(self, now: _Fit) -> _Place:
        """A new place scored over the window's scans: followed backward by the odometry and
        fitted at each."""
        window = self._cfg.evidence_window
        evidence: deque[float] = deque(maxlen=window)
        fits: deque[float] = deque(maxlen=window)
        poses: deque[FloatArray] = deque(maxlen=window)
        evidence.append(now.evidence)
        fits.append(now.fit)
        poses.append(now.pose)
        history = list(self._history)
        pose = now.pose
        for k in range(len(history) - 1, 0, -1):
            _, step = history[k]
            points, _ = history[k - 1]
            back = compose(pose, inverse(step))
            result = self._fit(points, back, self._prior(step))
            pose = result.pose
            evidence.appendleft(result.evidence)
            fits.appendleft(result.fit)
            poses.appendleft(pose)
        return _Place(now.pose, evidence, fits, poses, now.covariance)

    def _prune(self) -> None:
        """Places that became the same are merged (the better kept); at most max_hypotheses,
        the best by evidence; places far behind the best (3 margins) dropped."""
        cfg = self._cfg
        self._places.sort(key=lambda p: -p.total())
        kept: list[_Place] = []
        for place in self._places:
            if any(
                _same(place.pose, k.pose, cfg.separation / 2, cfg.separation_angle / 2)
                for k in kept
            ):
                continue
            if kept and place.total() < kept[0].total() - 3.0 * cfg.evidence_margin:
                continue
            kept.append(place)
        self._places = kept[: cfg.max_hypotheses]

    def _vote(self, stamp: float, points: FloatArray) -> LocalizationEstimate:
        cfg = self._cfg
        prefix = "lost: " if self._state is LocalizerState.LOST else ""
        if not self._places:
            why = "no place in the map fits the scan"
            if points.shape[0] < MIN_POINTS:
                why = f"the scan has {points.shape[0]} usable points"
            return self._searching_estimate(stamp, 0.0, prefix + why)
        best = self._places[0]
        rivals = [
            p
            for p in self._places[1:]
            if not _same(p.pose, best.pose, cfg.separation, cfg.separation_angle)
        ]
        lead = best.total() - max((r.total() for r in rivals), default=-math.inf)
        recent = list(best.fits)[-cfg.min_scans :]
        fits_well = bool(recent) and float(np.mean(recent)) >= cfg.min_fit
        enough = len(self._history) >= cfg.min_scans
        decisiveness = min(1.0, lead / cfg.evidence_margin) if math.isfinite(lead) else 1.0
        crossing = 0.0
        if enough and fits_well and lead >= cfg.evidence_margin:
            # over the last min_scans scans on average, and at the last one
            crossing, last = self._contradicted(best)
            expected = max(cfg.contradicted_share, self._levels[1])
            if (
                crossing <= self._bound(expected, cfg.min_scans, cfg.crossing_z)
                and last <= self._bound(expected, 1, cfg.crossing_z)
                and recent[-1] >= cfg.min_fit
            ):
                result = _Fit(best.pose, best.information, recent[-1], 0.0, True)
                self._begin_tracking(result)
                return self._tracking_estimate(stamp, None, result, "localised")
        if crossing > 0.0:
            why = f"no place agrees with the map: it contradicts {crossing:.0%} of the points"
            decisiveness = 0.0
        elif not fits_well:
            why = "no place in the map fits the scans well"
        elif rivals and lead < cfg.evidence_margin:
            why = f"ambiguous: {len(rivals) + 1} places explain the scans"
        else:
            why = "gathering evidence"
        return self._searching_estimate(stamp, max(0.0, decisiveness) * 0.99, prefix + why)

    def _searching_estimate(
        self, stamp: float, confidence: float, reason: str
    ) -> LocalizationEstimate:
        return LocalizationEstimate(stamp, self._state, None, None, None, float(confidence), reason)


def _same(a: FloatArray, b: FloatArray, distance: float, angle: float) -> bool:
    turn = abs((a[2] - b[2] + math.pi) % (2.0 * math.pi) - math.pi)
    return math.hypot(a[0] - b[0], a[1] - b[1]) < distance and turn < angle


def _rotated(cov: FloatArray, angle: float) -> FloatArray:
    """A covariance (x, y, θ) in a frame turned by ``angle``."""
    c, s = math.cos(angle), math.sin(angle)
    r = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    out: FloatArray = r @ cov @ r.T
    return out


def _propagate(
    cov: FloatArray, pose: FloatArray, step: FloatArray, information: FloatArray
) -> FloatArray:
    """The covariance after an odometry step of the given information (first order)."""
    c, s = math.cos(pose[2]), math.sin(pose[2])
    ja = np.array(
        [
            [1.0, 0.0, -s * step[0] - c * step[1]],
            [0.0, 1.0, c * step[0] - s * step[1]],
            [0.0, 0.0, 1.0],
        ]
    )
    jb = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    out: FloatArray = ja @ cov @ ja.T + jb @ np.linalg.inv(information) @ jb.T
    return out
