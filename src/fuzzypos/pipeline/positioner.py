"""The per-scan loop: the odometry prior, feature matching against the keyframe, the
refinement and the search, the trajectory.

``Positioner.update(scan, odom)`` takes each scan in turn with the odometry pose at that scan
(or ``None``). The prior for the motion since the previous scan is the odometry increment
``⊖o_k ⊕ o_{k+1}`` (SPEC) when both scans have odometry, else the last estimated increment. A
scan with too few features or pairs falls back to the prior and is flagged ``degraded``; an
empty or all-invalid scan is not an error but such a degraded estimate.
"""

from __future__ import annotations

import functools
import importlib
import math
from collections.abc import Iterable, Iterator, Sequence, Sized
from dataclasses import replace
from types import ModuleType
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._kernels import packing
from ..config import Config
from ..features import Features, extract_features, rule_bases
from ..features.chain import chain_inputs
from ..features.extract import features_of_chain
from ..geometry import Pose2D, Pose3, compose3, relative3
from ..matching import Refinement
from ..scan import LaserScan
from ._window import Window
from .estimate import Estimate, Reason
from .feature_match import FeatureMatch, FeatureMatcher
from .local_map import LocalMap
from .noise import OdometryNoise
from .prior import OdometryPrior, Prior
from .refine import Refiner, ScanPoints, Starts
from .search import Relocaliser
from .uncertainty import Assessment, Uncertainty, _AssessmentInputs

__all__ = ["Positioner"]

FloatArray = NDArray[np.float64]

_END = object()


@functools.cache
def _step() -> ModuleType:
    """The compiled match, refinement and assessment (``_kernels.step``), imported with
    numba on first use and kept."""
    return importlib.import_module("fuzzypos._kernels.step")


_IDENTITY = Pose2D()


def _pose(a: FloatArray) -> Pose2D:
    """A Pose2D from a pose array the pipeline computed (finite, angle wrapped by compose)."""
    return _pose3(a.tolist())


def _pose3(p: Pose3) -> Pose2D:
    """:func:`_pose` of a pose as three floats."""
    x, y, th = p
    if not (math.isfinite(x) and math.isfinite(y) and -math.pi <= th < math.pi):
        return Pose2D(x, y, th)  # validates and wraps
    return Pose2D._trusted(x, y, th)


class Positioner:
    """Fuzzy-based positioning of a robot from consecutive scans and odometry.

    A sequence of stages, each built from its own config section and owning its state: the
    odometry prior (:class:`~.prior.OdometryPrior`), the local map of keyframes
    (:class:`~.local_map.LocalMap`), feature matching (:class:`~.feature_match.FeatureMatcher`),
    the refinement (:class:`~.refine.Refiner`) and the relocalisation search
    (:class:`~.search.Relocaliser`). ``fused``: a scan's features, line matching,
    refinement and assessment in one compiled call where they can be (the same values to the
    bit as the staged calls; False: the staged calls alone).
    """

    def __init__(self, config: Config | None = None, *, fused: bool = True) -> None:
        self.config = config if config is not None else Config()
        cfg = self.config
        noise = cfg.odometry_noise
        self.odometry_prior = OdometryPrior(cfg.odometry, noise.stale_periods, noise.stale_quantile)
        self.odometry_noise = OdometryNoise(cfg.odometry_noise, cfg.odometry)
        self.local_map = LocalMap(cfg.matching, cfg.refinement)
        self.feature_matcher = FeatureMatcher(cfg.matching, cfg.fusion)
        self.refiner = Refiner(cfg.refinement, cfg.search)
        self.relocaliser = Relocaliser(cfg.search, self.refiner)
        self.uncertainty = Uncertainty(cfg.covariance, cfg.gate)
        # the common path in one compiled call (:meth:`_features_match_refine_assess`), fixed
        # for the positioner's life; False: the staged calls it fuses, which give the same
        # values to the bit (the tests' reference, and ``warm_up``'s second drive)
        self._fused = fused
        self.reset()

    @property
    def fused(self) -> bool:
        """Whether a scan's features, line matching, refinement and assessment are one
        compiled call where they can be (the constructor's ``fused``)."""
        return self._fused

    def reset(self) -> None:
        """Forget every scan: the next one starts a new trajectory."""
        self._pose: FloatArray | None = None
        self.odometry_prior.reset()
        self.odometry_noise.reset()
        self.local_map.reset()
        self.uncertainty.reset()
        #: the features' own error and the floor, the diagonal (:meth:`_disagreement`)
        both = self.uncertainty.feature_covariance() + self.uncertainty.floor
        self._feature_floor = (float(both[0, 0]), float(both[1, 1]), float(both[2, 2]))
        #: the confirmed (refined) matches' d² against the odometry (:meth:`_contradicts`)
        self._disagreements = Window(self.config.odometry_noise.window)

    @property
    def pose(self) -> Pose2D | None:
        """The latest pose estimate (None before the first scan)."""
        return None if self._pose is None else Pose2D.from_array(self._pose)

    @property
    def odometry_jumps(self) -> int:
        """Odometry increments rejected as jumps so far."""
        return self.odometry_prior.jumps

    def update(self, scan: LaserScan, odom: Pose2D | Sequence[float] | None = None) -> Estimate:
        """Process the next scan; ``odom`` is the odometry pose at this scan, if any."""
        if not isinstance(scan, LaserScan):
            raise TypeError(f"update() needs a LaserScan, got {type(scan).__name__}")
        if odom is not None and not isinstance(odom, Pose2D):
            odom = Pose2D.of(odom, "odom")  # (x, y, theta) too
        if self._pose is None:
            return self._first(scan, odom)
        prior = self._prior(scan.stamp, odom)
        t_prev = self.local_map.at(self._pose)  # the previous scan's pose from the keyframe
        if prior.standing_still:  # the odometry says the robot stands still: so does the estimate
            self.odometry_prior.accept(np.zeros(3), prior.dt)
            still = self.uncertainty.standing_still(t_prev)
            return Estimate(
                scan.stamp, _pose(self._pose), _IDENTITY, _IDENTITY, 0, False, None,
                Reason.STANDING_STILL, covariance=still.covariance,
                keyframe_covariance=still.keyframe_covariance,
            )  # fmt: skip
        # the same prior from the keyframe: what was estimated up to the previous scan, then it
        key_prior = self.local_map.from_keyframe(self._pose, prior.increment)
        prior_cov = self._prior_covariance(prior)
        information = self._prior_information(t_prev, prior, prior_cov)
        held = self.uncertainty.held()
        features, (n_pairs, reason, refined, from_key, judged) = self._matched(
            scan, key_prior, prior, prior_cov, information, t_prev
        )
        if from_key is not None and self._contradicts(t_prev, prior, prior_cov, from_key, refined):
            from_key, reason, judged = self._overruled(held, t_prev, prior, prior_cov)
        # (the poses as floats once: the arrays' tolist() gives these very floats back)
        previous = self._pose.tolist()
        if from_key is None:  # fall back to the prior, and start afresh from this scan
            increment = np.asarray(prior.increment, dtype=float)
            increment3 = increment.tolist()
            pose3 = compose3(previous, increment3)
        else:
            pose3 = self.local_map.pose3_of(from_key)
            increment3 = relative3(previous, pose3)
            increment = np.array(increment3)
        pose = np.array(pose3)
        renewed = self.local_map.add(features, pose, from_key)
        if renewed:
            self.uncertainty.renewed()
        self._pose = pose
        self.odometry_prior.accept(increment, prior.dt)
        reason = Reason.GATED if judged.rejected else reason
        refined = refined and from_key is not None
        return Estimate._trusted(
            stamp=scan.stamp, pose=_pose3(pose3), increment=_pose3(increment3),
            prior=_pose(prior.increment), n_pairs=n_pairs, degraded=from_key is None,
            features=features, reason=Reason.MATCHED if from_key is not None else reason,
            odometry_rejected=prior.odometry_rejected, refined=refined,
            covariance=judged.covariance, keyframe_covariance=judged.keyframe_covariance,
            gate=judged.gate, keyframe=renewed,
        )  # fmt: skip

    def _matched(
        self,
        scan: LaserScan,
        key_prior: FloatArray,
        prior: Prior,
        prior_cov: FloatArray,
        information: tuple[FloatArray, FloatArray] | None,
        t_prev: FloatArray,
    ) -> tuple[Features, tuple[int, Reason, bool, FloatArray | None, Assessment]]:
        """The scan's features and :meth:`_match_refine_assess` of them: in one compiled call
        where it can be (:meth:`_features_match_refine_assess`), else staged."""
        chained = self._features_match_refine_assess(
            scan, key_prior, prior, prior_cov, information, t_prev
        )
        if chained is not None:
            return chained
        features = extract_features(scan, self.config)
        return features, self._match_refine_assess(
            features, key_prior, prior, prior_cov, information, t_prev, scan.angle_increment
        )

    def _match_refine_assess(
        self,
        features: Features,
        key_prior: FloatArray,
        prior: Prior,
        prior_cov: FloatArray,
        information: tuple[FloatArray, FloatArray] | None,
        t_prev: FloatArray,
        angle_increment: float,
    ) -> tuple[int, Reason, bool, FloatArray | None, Assessment]:
        """The scan's features matched against the keyframe's, the refinement, the
        assessment and what it teaches the odometry's noise (:meth:`_learn`), in the staged
        calls. Returns the match's pairs and reason, whether a fit gave the motion, the motion
        from the keyframe (None: the prior stands) and the assessment."""
        match = self.feature_matcher.match(self.local_map.features, features, key_prior)
        return self._staged(match, features, key_prior, prior, prior_cov, information,
                            t_prev, angle_increment)  # fmt: skip

    def _features_match_refine_assess(
        self,
        scan: LaserScan,
        key_prior: FloatArray,
        prior: Prior,
        prior_cov: FloatArray,
        information: tuple[FloatArray, FloatArray] | None,
        t_prev: FloatArray,
    ) -> tuple[Features, tuple[int, Reason, bool, FloatArray | None, Assessment]] | None:
        """The scan's features and :meth:`_match_refine_assess` of them in one compiled call
        (``_kernels.step.features_and_step``: the feature chain's and the common path's), where
        both would be compiled calls; its values to the bit. None where they would not be
        (then :func:`extract_features` and :meth:`_match_refine_assess` run)."""
        if not self._fuses(prior):
            return None
        chain = chain_inputs(scan, self.config, rule_bases(self.config.fuzzy))
        if chain is None:
            return None
        keyframe = self.feature_matcher.keyframe_inputs(self.local_map.features)
        if keyframe is None:
            return None
        held = None if information is None else information[1]
        of_surface = self.refiner.surface_inputs(self.local_map.surface(), held)
        if of_surface is None:
            return None
        step = _step()
        (prev, prev_first, prev_n), line_gates, line_params, passes, min_pairs = keyframe
        geometry, shape, cells, table, gates, params, iterations, diag, info, full = of_surface
        r = self.config.refinement
        gate_open, assessment = self._assessment_inputs(prior, prior_cov, t_prev)
        match = step.MatchSettings(
            line_gates, line_params, passes, min_pairs, packing.lines_at(), int(r.min_points)
        )
        refine = step.RefineSettings(
            self.refiner.weighing_settings(scan.angle_increment), gates, params, iterations,
            diag, info, full, bool(r.prior_from_features), self.refiner.checks(False),
        )  # fmt: skip
        surface = step.KeyframeInputs(prev, prev_first, prev_n, geometry, shape, cells, table)
        assess = step.AssessInputs(*assessment, key_prior, self._is_key_prior(t_prev))
        done, scale, line_scale, sizes, fl, it, bl, *stepped = step.features_and_step(
            step.ScanInputs(*chain), surface, match, refine, assess
        )
        if not done:  # (a gapless 360° ring: the staged chain's)
            features = extract_features(scan, self.config)
        else:
            features = features_of_chain(scan, self.config, (scale, line_scale, sizes, fl, it, bl))
        if not done or stepped[0] == step.FEATURES_ONLY:
            return features, self._match_refine_assess(
                features, key_prior, prior, prior_cov, information, t_prev, scan.angle_increment
            )
        return features, self._after_step(
            tuple(stepped), gate_open, features, key_prior, prior, prior_cov, information,
            t_prev, scan.angle_increment,
        )  # fmt: skip

    def _fuses(self, prior: Prior) -> bool:
        """Whether the staged calls would be the ones the compiled call fuses: it is switched on
        (``fused``), the refinement too, and the prior is no odometry jump's."""
        return self._fused and not prior.odometry_rejected and self.config.refinement.enabled

    def _assessment_inputs(
        self, prior: Prior, prior_cov: FloatArray, t_prev: FloatArray
    ) -> tuple[bool, _AssessmentInputs]:
        """Whether the gate is open and what the compiled call reads for the assessment of a
        refined match (``Uncertainty.assessment_inputs``, with the scan's own motion where it
        would teach the odometry's noise)."""
        gate_open = self._gate_open(prior)
        assessment = self.uncertainty.assessment_inputs(
            t_prev, prior.increment, prior_cov, gate_open, self._learns_from(prior, True)
        )
        return gate_open, assessment

    def _after_step(
        self,
        stepped: tuple[Any, ...],
        gate_open: bool,
        features: Features,
        key_prior: FloatArray,
        prior: Prior,
        prior_cov: FloatArray,
        information: tuple[FloatArray, FloatArray] | None,
        t_prev: FloatArray,
        angle_increment: float,
    ) -> tuple[int, Reason, bool, FloatArray | None, Assessment]:
        """:meth:`_match_refine_assess` from the compiled call's values (``stepped``), going
        on with the staged calls where it left the common path."""
        step = _step()
        stage, n_pairs, which, paired, close, on_start, gate, ok, out = stepped
        prev = self.local_map.features
        if stage == step.NO_LINES:
            match = self.feature_matcher.match_after_lines(prev, features, key_prior)
            return self._staged(match, features, key_prior, prior, prior_cov, information,
                                t_prev, angle_increment)  # fmt: skip
        est = out[step.LINES, 0]
        match = FeatureMatch._of(est, n_pairs, Reason.MATCHED)
        if stage == step.ASSESSED:
            judged = self.uncertainty.assessed(gate, ok, out, step.ASSESSMENT, gate_open)
            if judged is not None:  # (a fit's own values are read for a rejected match only)
                self._learn(prior, t_prev, None, judged)
                return n_pairs, Reason.MATCHED, True, out[step.FIT, 0], judged
        # (the compiled call read the points from the chain's arrays: they are there)
        points = self.refiner.points(features, angle_increment)
        assert points is not None
        held = None if information is None else information[1]
        refinement = self.refiner.lines_start_inputs(self.local_map.surface(), points, held)
        assert refinement is not None
        if stage == step.NOT_REFINED:  # (neither fit counts: the search, as _refine goes on)
            starts = self._starts(match, key_prior, information)
            fit, on_previous = self._searched(None, points, starts, prior)
            return self._judged(match, fit, on_previous, t_prev, prior, prior_cov, key_prior)
        starts = self._starts(match, key_prior, information)
        fit = self.refiner.from_lines(
            which == step.FROM_START, paired, close, on_start, out[step.FIT : step.FIT + 4],
            points, starts, refinement,
        )  # fmt: skip
        return self._judged(match, fit, False, t_prev, prior, prior_cov, key_prior)

    def _staged(
        self,
        match: FeatureMatch,
        features: Features,
        key_prior: FloatArray,
        prior: Prior,
        prior_cov: FloatArray,
        information: tuple[FloatArray, FloatArray] | None,
        t_prev: FloatArray,
        angle_increment: float,
    ) -> tuple[int, Reason, bool, FloatArray | None, Assessment]:
        """:meth:`_match_refine_assess` in the staged calls from the ``match``: the
        refinement and its searches, then :meth:`_judged`."""
        fit, on_previous = self._refine(features, match, key_prior, prior, angle_increment,
                                        information)  # fmt: skip
        return self._judged(match, fit, on_previous, t_prev, prior, prior_cov, key_prior)

    def _judged(
        self,
        match: FeatureMatch,
        fit: Refinement | None,
        on_previous: bool,
        t_prev: FloatArray,
        prior: Prior,
        prior_cov: FloatArray,
        key_prior: FloatArray,
    ) -> tuple[int, Reason, bool, FloatArray | None, Assessment]:
        """:meth:`_match_refine_assess`' values of a match and its fit (None: none)."""
        from_key = match.increment if fit is None else fit.increment
        judged = self._assess(t_prev, prior, prior_cov, from_key, fit, on_previous, key_prior)
        if judged.rejected:  # too unlikely under both covariances: the odometry stands
            from_key = None
        self._learn(prior, t_prev, fit, judged)
        return match.n_pairs, match.reason, fit is not None, from_key, judged

    def _contradicts(
        self,
        t_prev: FloatArray,
        prior: Prior,
        prior_cov: FloatArray,
        from_key: FloatArray,
        refined: bool,
    ) -> bool:
        """Whether a features-only match ``from_key`` (from the keyframe; ``refined``: a fit
        confirmed it) contradicts the odometry: its disagreement's d² under the odometry's
        learned covariance plus the features' own error beyond the larger of χ²(3)'s and the
        confirmed matches' own ``gate.contradiction_probability`` quantile (their d², kept
        over the odometry noise's window: odometry whose errors have heavier tails than its
        learned covariance says, as in turns whose odometry lags the scans, raises it).
        Where the prior is the odometry's (no jump) and its noise is known."""
        gate = self.config.gate
        if not (gate.contradiction_check and prior.from_odometry and self.odometry_noise.warm):
            return False
        if prior.odometry_rejected:
            return False
        d2 = self._disagreement(t_prev, prior.increment, prior_cov, from_key)
        seen = self._disagreements
        if refined:
            seen.append(d2)
            return False
        threshold = self.uncertainty.contradiction_threshold
        if len(seen) >= self.config.odometry_noise.min_samples:
            threshold = max(threshold, seen.quantile(gate.contradiction_probability))
        return d2 > threshold

    def _disagreement(
        self, t_prev: FloatArray, increment: FloatArray, prior_cov: FloatArray, from_key: FloatArray
    ) -> float:
        """d² of the match ``from_key``'s increment from ``increment`` (the odometry's) under
        ``prior_cov`` plus the features' own error and the floor, all three diagonal (the
        learned noise's, :meth:`OdometryNoise.covariance`, or the broad one; and two
        constants), in floats."""
        ex, ey, et = relative3(increment.tolist(), relative3(t_prev.tolist(), from_key.tolist()))
        fx, fy, ft = self._feature_floor
        return (
            ex * ex / (float(prior_cov[0, 0]) + fx)
            + ey * ey / (float(prior_cov[1, 1]) + fy)
            + et * et / (float(prior_cov[2, 2]) + ft)
        )

    def _overruled(
        self, held: FloatArray, t_prev: FloatArray, prior: Prior, prior_cov: FloatArray
    ) -> tuple[None, Reason, Assessment]:
        """A match that contradicts the odometry (:meth:`_contradicts`): the odometry stands,
        assessed from the previous scan's covariance ``held`` before the match's assessment."""
        judged = self.uncertainty.overruled(held, t_prev, prior.increment, prior_cov)
        return None, Reason.CONTRADICTS_ODOMETRY, judged

    def _prior(self, stamp: float, odom: Pose2D | None) -> Prior:
        """The odometry prior, its increment corrected by the learned calibration."""
        prior = self.odometry_prior.predict(stamp, odom)
        if not prior.from_odometry:
            return prior
        increment = self.odometry_noise.calibrated(prior.increment)
        if increment is prior.increment:  # no calibration to apply
            return prior
        return Prior._of(
            increment, prior.odometry, prior.dt, prior.odometry_rejected, prior.standing_still,
            prior.stale,
        )  # fmt: skip

    def _prior_covariance(self, prior: Prior) -> FloatArray:
        """The covariance of the prior: the odometry's learned noise (grown by the time it was
        stale), or a broad one where the prior is the last increment."""
        if not prior.from_odometry:  # (a writable copy of the read-only constant: the kernels
            # that read it are compiled for writable arrays, not once more for read-only ones)
            broad: FloatArray = self.uncertainty.broad().copy()
            return broad
        return self.odometry_noise.covariance(prior.increment, prior.stale)

    def _prior_information(
        self, t_prev: FloatArray, prior: Prior, prior_cov: FloatArray
    ) -> tuple[FloatArray, FloatArray] | None:
        """The information of the features' and of the odometry's motion from the keyframe
        for the refinement's prior, from the learned noise where it is trusted (None: the
        fixed sigmas)."""
        noise = self.odometry_noise
        if not ((self.config.odometry_noise.in_refinement and noise.warm) or noise.trusted):
            return None
        if not prior.from_odometry:
            return None
        return self.uncertainty.prior_information(t_prev, prior.increment, prior_cov)

    def _gate_open(self, prior: Prior) -> bool:
        """Whether a match is compared with the odometry: where the prior is the odometry's
        and its noise is known (learned from enough matches, or not learned at all)."""
        noise, gate = self.odometry_noise, self.config.gate
        if not (gate.enabled and prior.from_odometry and noise.warm):
            return False
        return noise.better_than_matching or not gate.only_where_odometry_is_better

    def _assess(
        self,
        t_prev: FloatArray,
        prior: Prior,
        prior_cov: FloatArray,
        from_key: FloatArray | None,
        fit: Refinement | None,
        on_previous: bool,
        key_prior: FloatArray,
    ) -> Assessment:
        """The uncertainty stage's assessment of the match (with the scan's own motion where
        it teaches the odometry's noise); a fit against the previous scan too carries that
        scan's error relative to the keyframe; ``key_prior``: the prior from the keyframe."""
        previous_cov = self.uncertainty.previous_covariance() if on_previous else None
        known = key_prior if self._is_key_prior(t_prev) else None
        judged = self.uncertainty.assess(
            t_prev, prior.increment, prior_cov, from_key, fit, gate_open=self._gate_open(prior),
            with_scan_only=self._learns_from(prior, fit), key_prior=known,
        )  # fmt: skip
        if previous_cov is not None and from_key is not None and not judged.rejected:
            # the fit placed the previous scan's points by its estimate: their error too
            judged = self.uncertainty.widened(judged, previous_cov, float(from_key[2]))
        return judged

    @staticmethod
    def _is_key_prior(t_prev: FloatArray) -> bool:
        """Whether the prior from the keyframe is compose(t_prev, prior) to the bit, as the
        assessment computes it: where t_prev is the keyframe's relative pose itself, no
        coordinate of it zero (``LocalMap.at``)."""
        return 0.0 not in t_prev.tolist()

    @staticmethod
    def _learns_from(prior: Prior, fit: Refinement | bool | None) -> bool:
        """Whether a refined match (its prior the odometry's) would teach the odometry's noise
        and calibration (on time) or the stale rates (after a gap), where it stands: the
        assessment then gives the scan's own motion with it (one compiled call for both).
        ``fit``: the fit (None: none), or whether there is one."""
        has_fit = fit is not None and fit is not False
        return has_fit and prior.from_odometry and prior.odometry is not None

    def _learn(
        self, prior: Prior, t_prev: FloatArray, fit: Refinement | None, judged: Assessment
    ) -> None:
        """A refined match on time that stands teaches the odometry's noise and calibration:
        the scan's own motion (the fit without its prior, ``judged.scan_only``), never the
        fused one, which would teach the odometry its own weight back. A refined match after
        a gap teaches the stale rates, standing or not: the gate is drawn with those rates,
        and learning only from what it let through would keep rates learned low on a log
        whose odometry stalls in later gaps (the median stands against the false matches)."""
        if prior.odometry is None:
            return
        scan = judged.scan_only
        if prior.stale != 0.0:  # after a gap: how stale the odometry was
            if scan is None and judged.rejected and fit is not None and prior.from_odometry:
                scan = self.uncertainty.scan_only(fit, t_prev)
            if scan is not None:
                self.odometry_noise.learn_stale(prior.odometry, *scan, prior.stale)
        elif scan is not None:
            self.odometry_noise.learn(prior.odometry, *scan)

    def _first(self, scan: LaserScan, odom: Pose2D | None) -> Estimate:
        """The first scan: the trajectory starts at its odometry pose, or the origin."""
        features = extract_features(scan, self.config)
        start = odom.as_array() if odom is not None else np.zeros(3)
        self._pose = start
        self.odometry_prior.start(scan.stamp, odom)
        self.local_map.set_keyframe(features, start)
        first = self.uncertainty.first()
        return Estimate(
            scan.stamp, Pose2D.from_array(start), _IDENTITY, _IDENTITY, 0, False, features,
            Reason.FIRST_SCAN, covariance=first.covariance,
            keyframe_covariance=first.keyframe_covariance, keyframe=True,
        )  # fmt: skip

    def _refine(
        self,
        features: Features,
        match: FeatureMatch,
        key_prior: FloatArray,
        prior: Prior,
        angle_increment: float,
        information: tuple[FloatArray, FloatArray] | None,
    ) -> tuple[Refinement | None, bool]:
        """The refinement of the features' motion (else the prior's) against the local map,
        and the search where the prior cannot be trusted (after an odometry jump), or where the
        refinement fails (a wider one after a gap in time); where still nothing fits, the
        refinement against the local map and the previous scan (``with_previous_scan``). None
        where nothing fits; and whether that last refinement gave it."""
        r = self.config.refinement
        if not r.enabled:
            return None, False
        surface = self.local_map.surface()
        points = self.refiner.points(features, angle_increment)
        if points is None:
            return None, False
        starts = self._starts(match, key_prior, information)
        best = self.refiner.refine(surface, points, starts, prior.odometry_rejected)
        return self._searched(best, points, starts, prior)

    def _starts(
        self,
        match: FeatureMatch,
        key_prior: FloatArray,
        information: tuple[FloatArray, FloatArray] | None,
    ) -> Starts:
        """Where the refinement starts: the features' motion, else the prior from the
        keyframe ``key_prior``; held to the features' motion (``prior_from_features``) or to
        the prior, with the learned ``information`` where given."""
        start = key_prior if match.increment is None else match.increment
        from_features = match.increment is not None and self.config.refinement.prior_from_features
        if information is None:
            return Starts._of(start, start if from_features else key_prior, key_prior, None, None)
        # the learned odometry is the prior, the features the start
        return Starts._of(start, key_prior, key_prior, information[1], information[1])

    def _searched(
        self, best: Refinement | None, points: ScanPoints, starts: Starts, prior: Prior
    ) -> tuple[Refinement | None, bool]:
        """:meth:`_refine` after the refinement gave ``best`` (None: no fit counts): the
        searches, and the fit against the previous scan too."""
        r = self.config.refinement
        wide = prior.odometry_rejected
        if wide or best is None:
            full = wide or prior.dt > self.config.search.after_gap
            best = self.relocaliser.relocalise(self.local_map, points, starts, best, full)
        if best is None and not wide and r.with_previous_scan and self.local_map.has_previous:
            best = self.refiner.refine(self.local_map.search_surface(), points, starts, False)
            return best, best is not None
        return best, False

    def run(
        self,
        scans: Iterable[LaserScan],
        odoms: Iterable[Pose2D | None] | None = None,
        keep_features: bool = False,
    ) -> list[Estimate]:
        """Process a sequence; ``odoms`` (same length, entries may be None) is optional."""
        if isinstance(scans, Sized) and isinstance(odoms, Sized) and len(odoms) != len(scans):
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
                    raise ValueError(
                        f"odoms ran out at scan {k}: give one odometry pose per scan"
                    ) from None
            est = self.update(scan, odom)
            if not keep_features:
                est = replace(est, features=None)
            yield est
        if odom_iter is not None and next(odom_iter, _END) is not _END:
            raise ValueError("odoms has more poses than there were scans: give one per scan")
