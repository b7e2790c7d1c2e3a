"""The per-scan loop: the odometry prior, the step from the keyframe (features → match →
refine → assess), the contradiction check and the commit of the estimate to the trajectory.

``Positioner.update(scan, odom)`` takes each scan in turn with the odometry pose at that scan
(or ``None``). The prior for the motion since the previous scan is the odometry increment
``⊖o_k ⊕ o_{k+1}`` (SPEC) when both scans have odometry, else the last estimated increment. A
scan with too few features or pairs falls back to the prior and is flagged ``degraded``; an
empty or all-invalid scan is not an error but such a degraded estimate.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Iterator, Sequence, Sized
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from ..config import Config
from ..geometry import Pose2D, Pose3, compose3, relative3
from ..scan import LaserScan
from .context import ScanContext
from .contradiction import ContradictionCheck
from .estimate import Estimate, Reason
from .feature_match import FeatureMatcher
from .local_map import LocalMap
from .noise import OdometryNoise
from .prior import OdometryPrior, Prior
from .refine import Refiner
from .search import Relocaliser
from .step import Step
from .uncertainty import Uncertainty

__all__ = ["Positioner"]

FloatArray = NDArray[np.float64]

_END = object()

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

    A sequence of stages, each built from its own config section and owning its state; the
    positioner reads no section itself. Each stage's formula lives in one file:

    ================  ============================================================
    stage             its formula (its entry point)
    ================  ============================================================
    prior             ``pipeline/prior.py`` (:class:`~.prior.OdometryPrior`)
    odometry noise    ``pipeline/noise.py`` (:class:`~.noise.OdometryNoise`)
    features          ``_kernels/front.py`` (``features.extract_features``: §3.1–3.5)
    angular points    ``_kernels/points.py`` (§3.4, §3.6, in the same call)
    match (lines)     ``_kernels/lines.py`` (:class:`~.feature_match.FeatureMatcher`)
    match (points)    ``matching/points.py`` (its fallback, §3.7)
    refine            ``_kernels/refine.py`` (:class:`~.refine.Refiner`)
    search            ``_kernels/search.py`` (:class:`~.search.Relocaliser`)
    assess            ``_kernels/uncertainty.py`` (:class:`~.uncertainty.Uncertainty`)
    contradiction     ``pipeline/contradiction.py`` (``ContradictionCheck``)
    commit            ``pipeline/local_map.py`` (:class:`~.local_map.LocalMap`)
    ================  ============================================================

    Features → match → refine → assess are one stage for the positioner
    (:class:`~.step.Step`, ``pipeline/step.py``): ``fused``, in one compiled call where they
    can be (the same values to the bit as the staged calls; False: the staged calls alone).
    A scan's way through them is a :class:`~.context.ScanContext`.
    """

    def __init__(self, config: Config | None = None, *, fused: bool = True) -> None:
        self.config = config if config is not None else Config()
        cfg = self.config
        self.odometry_prior = OdometryPrior.of_sections(cfg.odometry, cfg.odometry_noise)
        self.odometry_noise = OdometryNoise(cfg.odometry_noise, cfg.odometry)
        self.local_map = LocalMap(cfg.matching, cfg.refinement)
        self.feature_matcher = FeatureMatcher(cfg.matching, cfg.fusion)
        self.refiner = Refiner(cfg.refinement, cfg.search)
        self.relocaliser = Relocaliser(cfg.search, self.refiner)
        self.uncertainty = Uncertainty(cfg.covariance, cfg.gate)
        self.step = Step(
            cfg, self.local_map, self.feature_matcher, self.refiner, self.relocaliser,
            self.uncertainty, self.odometry_noise, fused,
        )  # fmt: skip
        self.contradiction = ContradictionCheck(
            cfg.gate, cfg.odometry_noise, self.odometry_noise, self.uncertainty
        )
        self.reset()

    @property
    def fused(self) -> bool:
        """Whether a scan's features, line matching, refinement and assessment are one
        compiled call where they can be (the constructor's ``fused``)."""
        return self.step.fused

    def reset(self) -> None:
        """Forget every scan: the next one starts a new trajectory."""
        self._pose: FloatArray | None = None
        self.odometry_prior.reset()
        self.odometry_noise.reset()
        self.local_map.reset()
        self.uncertainty.reset()
        self.contradiction.reset()

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
        prior = self.odometry_noise.calibrated_prior(self.odometry_prior.predict(scan.stamp, odom))
        t_prev = self.local_map.at(self._pose)  # the previous scan's pose from the keyframe
        if prior.standing_still:  # the odometry says the robot stands still: so does the estimate
            return self._standing_still(scan, prior, t_prev)
        ctx = self._context(scan, prior, t_prev)
        ctx.matched = self.step.run(ctx)  # features → match → refine → assess
        ctx.matched = self.contradiction.overrule(ctx)
        return self._commit(ctx)

    def _context(self, scan: LaserScan, prior: Prior, t_prev: FloatArray) -> ScanContext:
        """The scan's context for the later stages: the prior from the keyframe (what was
        estimated up to the previous scan, then the prior), its covariance, the information
        of the features' and of the odometry's motion for the refinement's prior from the
        learned noise where it is trusted (None: the fixed sigmas), and the previous scan's
        covariance before the assessment replaces it."""
        assert self._pose is not None
        key_prior = self.local_map.from_keyframe(self._pose, prior.increment)
        prior_cov = self.odometry_noise.prior_covariance(prior, self.uncertainty.broad())
        information = None
        if self.odometry_noise.informs_refinement and prior.from_odometry:
            information = self.uncertainty.prior_information(t_prev, prior.increment, prior_cov)
        held = self.uncertainty.held()
        return ScanContext(scan, prior, t_prev, key_prior, prior_cov, information, held)

    def _standing_still(self, scan: LaserScan, prior: Prior, t_prev: FloatArray) -> Estimate:
        """The odometry says the robot stands still: so does the estimate."""
        assert self._pose is not None
        self.odometry_prior.accept(np.zeros(3), prior.dt)
        still = self.uncertainty.standing_still(t_prev)
        return Estimate(
            scan.stamp, _pose(self._pose), _IDENTITY, _IDENTITY, 0, False, None,
            Reason.STANDING_STILL, covariance=still.covariance,
            keyframe_covariance=still.keyframe_covariance,
        )  # fmt: skip

    def _commit(self, ctx: ScanContext) -> Estimate:
        """The scan's estimate committed: its pose (from the keyframe, else the prior's from
        the previous scan, starting afresh from this scan), the local map and the prior's
        last increment updated."""
        assert self._pose is not None and ctx.matched is not None
        features, n_pairs, reason, refined, from_key, judged = ctx.matched
        prior = ctx.prior
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
        return Estimate._trusted(
            stamp=ctx.scan.stamp, pose=_pose3(pose3), increment=_pose3(increment3),
            prior=_pose(prior.increment), n_pairs=n_pairs, degraded=from_key is None,
            features=features, reason=Reason.MATCHED if from_key is not None else reason,
            odometry_rejected=prior.odometry_rejected, refined=refined and from_key is not None,
            covariance=judged.covariance, keyframe_covariance=judged.keyframe_covariance,
            gate=judged.gate, keyframe=renewed,
        )  # fmt: skip

    def _first(self, scan: LaserScan, odom: Pose2D | None) -> Estimate:
        """The first scan: the trajectory starts at its odometry pose, or the origin."""
        features = self.step.features(scan)
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
