"""The step from the keyframe: a scan's features, matched against the keyframe's, the
refinement against the local map (and the relocalisation search where it fails), the
assessment and what it teaches the odometry's noise. One stage for the positioner
(:meth:`Step.run`): where it can, one compiled call (``_kernels.step``) does all four, and
where that call leaves the common path the staged calls go on from where it stopped; else the
staged calls alone, which give the same values to the bit."""

from __future__ import annotations

import functools
import importlib
from types import ModuleType
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from .._kernels import packing
from ..config import Config
from ..features import Features, extract_features, rule_bases
from ..features.chain import chain_inputs
from ..features.extract import features_of_chain
from ..matching import Refinement
from ..scan import LaserScan
from .context import Matched, ScanContext
from .estimate import Reason
from .feature_match import FeatureMatch, FeatureMatcher
from .local_map import LocalMap
from .noise import OdometryNoise
from .prior import Prior
from .refine import Refiner, ScanPoints, Starts
from .search import Relocaliser
from .uncertainty import Assessment, Uncertainty

if TYPE_CHECKING:  # (the compiled module is imported on first use)
    from .._kernels.step import Stepped

__all__ = ["Step"]

FloatArray = NDArray[np.float64]


@functools.cache
def _step() -> ModuleType:
    """The compiled match, refinement and assessment (``_kernels.step``), imported with
    numba on first use and kept."""
    return importlib.import_module("fuzzypos._kernels.step")


class Step:
    """Features → match → refine → assess, for one scan against the local map: the feature
    extraction (``config``'s feature sections), the :class:`FeatureMatcher`, the
    :class:`Refiner` and the :class:`Relocaliser`, the :class:`Uncertainty` stage and the
    :class:`OdometryNoise` it teaches. ``fused``: in one compiled call where it can be."""

    def __init__(
        self,
        config: Config,
        local_map: LocalMap,
        feature_matcher: FeatureMatcher,
        refiner: Refiner,
        relocaliser: Relocaliser,
        uncertainty: Uncertainty,
        odometry_noise: OdometryNoise,
        fused: bool,
    ) -> None:
        self.config = config
        self.local_map = local_map
        self.feature_matcher = feature_matcher
        self.refiner = refiner
        self.relocaliser = relocaliser
        self.uncertainty = uncertainty
        self.odometry_noise = odometry_noise
        #: fixed for the stage's life; False: the staged calls it fuses (the tests'
        #: reference, and ``warm_up``'s second drive)
        self.fused = fused

    def run(self, ctx: ScanContext) -> Matched:
        """The scan's features, matched, refined and assessed: in one compiled call where it
        can be (:meth:`_fused`), else staged (:meth:`features`, :meth:`match`)."""
        fused = self._fused(ctx) if self._fuses(ctx.prior) else None
        if fused is not None:
            return fused
        return self.match(ctx, self.features(ctx.scan))

    def features(self, scan: LaserScan) -> Features:
        """The scan's features (``fuzzypos.features.extract_features``)."""
        return extract_features(scan, self.config)

    def match(self, ctx: ScanContext, features: Features) -> Matched:
        """The scan's ``features`` matched against the keyframe's, then :meth:`refine`."""
        match = self.feature_matcher.match(self.local_map.features, features, ctx.key_prior)
        return self.refine(ctx, features, match)

    def refine(self, ctx: ScanContext, features: Features, match: FeatureMatch) -> Matched:
        """The refinement of the ``match`` and its searches (:meth:`_refined`), then
        :meth:`assess`."""
        fit, on_previous = self._refined(ctx, features, match)
        return self.assess(ctx, features, match, fit, on_previous)

    def assess(
        self,
        ctx: ScanContext,
        features: Features,
        match: FeatureMatch,
        fit: Refinement | None,
        on_previous: bool,
    ) -> Matched:
        """The assessment of a match and its fit (None: none; ``on_previous``: against the
        previous scan too) and what it teaches the odometry's noise (:meth:`_learn`)."""
        from_key = match.increment if fit is None else fit.increment
        judged = self._assessment(ctx, from_key, fit, on_previous)
        if judged.rejected:  # too unlikely under both covariances: the odometry stands
            from_key = None
        self._learn(ctx, fit, judged)
        return Matched(features, match.n_pairs, match.reason, fit is not None, from_key, judged)

    def _refined(
        self, ctx: ScanContext, features: Features, match: FeatureMatch
    ) -> tuple[Refinement | None, bool]:
        """The refinement of the features' motion (else the prior's) against the local map,
        and the search where the prior cannot be trusted (after an odometry jump), or where the
        refinement fails (a wider one after a gap in time); where still nothing fits, the
        refinement against the local map and the previous scan (``with_previous_scan``). None
        where nothing fits; and whether that last refinement gave it."""
        if not self.refiner.enabled:
            return None, False
        surface = self.local_map.surface()
        points = self.refiner.points(features, ctx.scan.angle_increment)
        if points is None:
            return None, False
        starts = self.refiner.starts(match.increment, ctx.key_prior, ctx.information)
        best = self.refiner.refine(surface, points, starts, ctx.prior.odometry_rejected)
        return self._searched(best, points, starts, ctx.prior)

    def _searched(
        self, best: Refinement | None, points: ScanPoints, starts: Starts, prior: Prior
    ) -> tuple[Refinement | None, bool]:
        """:meth:`_refined` after the refinement gave ``best`` (None: no fit counts): the
        searches, and the fit against the previous scan too."""
        wide = prior.odometry_rejected
        if wide or best is None:
            full = self.relocaliser.is_full(wide, prior.dt)
            best = self.relocaliser.relocalise(self.local_map, points, starts, best, full)
        previous = best is None and not wide and self.refiner.with_previous_scan
        if previous and self.local_map.has_previous:
            best = self.refiner.refine(self.local_map.search_surface(), points, starts, False)
            return best, best is not None
        return best, False

    def _assessment(
        self,
        ctx: ScanContext,
        from_key: FloatArray | None,
        fit: Refinement | None,
        on_previous: bool,
    ) -> Assessment:
        """The uncertainty stage's assessment of the match (with the scan's own motion where
        it teaches the odometry's noise); a fit against the previous scan too carries that
        scan's error relative to the keyframe."""
        prior = ctx.prior
        previous_cov = self.uncertainty.previous_covariance() if on_previous else None
        known = ctx.key_prior if _is_key_prior(ctx.t_prev) else None
        gate_open = self.uncertainty.gate_open(prior.from_odometry, self.odometry_noise)
        judged = self.uncertainty.assess(
            ctx.t_prev, prior.increment, ctx.prior_covariance, from_key, fit,
            gate_open=gate_open, with_scan_only=_learns_from(prior, fit), key_prior=known,
        )  # fmt: skip
        if previous_cov is not None and from_key is not None and not judged.rejected:
            # the fit placed the previous scan's points by its estimate: their error too
            judged = self.uncertainty.widened(judged, previous_cov, float(from_key[2]))
        return judged

    def _learn(self, ctx: ScanContext, fit: Refinement | None, judged: Assessment) -> None:
        """A refined match on time that stands teaches the odometry's noise and calibration:
        the scan's own motion (the fit without its prior, ``judged.scan_only``), never the
        fused one, which would teach the odometry its own weight back. A refined match after
        a gap teaches the stale rates, standing or not: the gate is drawn with those rates,
        and learning only from what it let through would keep rates learned low on a log
        whose odometry stalls in later gaps (the median stands against the false matches)."""
        prior = ctx.prior
        if prior.odometry is None:
            return
        scan = judged.scan_only
        if prior.stale != 0.0:  # after a gap: how stale the odometry was
            if scan is None and judged.rejected and fit is not None and prior.from_odometry:
                scan = self.uncertainty.scan_only(fit, ctx.t_prev)
            if scan is not None:
                self.odometry_noise.learn_stale(prior.odometry, *scan, prior.stale)
        elif scan is not None:
            self.odometry_noise.learn(prior.odometry, *scan)

    def _fuses(self, prior: Prior) -> bool:
        """Whether the staged calls would be the ones the compiled call fuses: it is switched on
        (``fused``), the refinement too, and the prior is no odometry jump's."""
        return self.fused and not prior.odometry_rejected and self.refiner.enabled

    def _fused(self, ctx: ScanContext) -> Matched | None:
        """:meth:`run` in one compiled call (``_kernels.step.run``: the feature chain's and
        the common path's), where the staged calls would all be compiled ones; its values to
        the bit, going on with the staged calls where it left the common path
        (:meth:`_after`). None where it cannot be made."""
        scan, config = ctx.scan, self.config
        chain = chain_inputs(scan, config, rule_bases(config.fuzzy))
        if chain is None:
            return None
        keyframe = self.feature_matcher.keyframe_inputs(self.local_map.features)
        if keyframe is None:
            return None
        of_surface = self.refiner.surface_inputs(self.local_map.surface(), ctx.held_information)
        if of_surface is None:
            return None
        step = _step()
        (prev, prev_first, prev_n), line_gates, line_params, passes, min_pairs = keyframe
        geometry, shape, cells, table, gates, params, iterations, diag, info, full = of_surface
        refiner, prior = self.refiner, ctx.prior
        gate_open = self.uncertainty.gate_open(prior.from_odometry, self.odometry_noise)
        assess = self.uncertainty.assess_inputs(
            ctx.t_prev, prior.increment, ctx.prior_covariance, gate_open,
            _learns_from(prior, True), ctx.key_prior, _is_key_prior(ctx.t_prev),
        )  # fmt: skip
        stepped = step.run(
            step.ScanInputs(*chain),
            step.KeyframeInputs(prev, prev_first, prev_n, geometry, shape, cells, table),
            step.MatchSettings(
                line_gates, line_params, passes, min_pairs, packing.lines_at(), refiner.min_points
            ),
            step.RefineSettings(
                refiner.weighing_settings(scan.angle_increment), gates, params, iterations, diag,
                info, full, refiner.prior_from_features, refiner.checks(False),
            ),
            assess,
        )  # fmt: skip
        features = features_of_chain(scan, config, stepped.chain)
        if stepped.stage == step.FEATURES_ONLY:
            return self.match(ctx, features)
        return self._after(ctx, features, stepped, gate_open)

    def _after(
        self, ctx: ScanContext, features: Features, stepped: Stepped, gate_open: bool
    ) -> Matched:
        """:meth:`run` from the compiled call's values (``stepped``), going on with the staged
        calls where it left the common path."""
        step = _step()
        stage = stepped.stage
        if stage == step.NO_LINES:
            prev = self.local_map.features
            match = self.feature_matcher.match_after_lines(prev, features, ctx.key_prior)
            return self.refine(ctx, features, match)
        match = FeatureMatch._of(stepped.lines_motion, stepped.n_pairs, Reason.MATCHED)
        if stage == step.ASSESSED:
            judged = self.uncertainty.assessed(
                stepped.gate, stepped.scan_alone, stepped.assessment, gate_open
            )
            if judged is not None:  # (a fit's own values are read for a rejected match only)
                self._learn(ctx, None, judged)
                return Matched(
                    features, stepped.n_pairs, Reason.MATCHED, True, stepped.fit[0, 0], judged
                )
        # (the compiled call read the points from the chain's arrays: they are there)
        points = self.refiner.points(features, ctx.scan.angle_increment)
        assert points is not None
        refinement = self.refiner.lines_start_inputs(
            self.local_map.surface(), points, ctx.held_information
        )
        assert refinement is not None
        starts = self.refiner.starts(match.increment, ctx.key_prior, ctx.information)
        if stage == step.NOT_REFINED:  # (neither fit counts: the search, as _refined goes on)
            fit, on_previous = self._searched(None, points, starts, ctx.prior)
            return self.assess(ctx, features, match, fit, on_previous)
        fit = self.refiner.from_lines(stepped, points, starts, refinement)
        return self.assess(ctx, features, match, fit, False)


def _is_key_prior(t_prev: FloatArray) -> bool:
    """Whether the prior from the keyframe is compose(t_prev, prior) to the bit, as the
    assessment computes it: where t_prev is the keyframe's relative pose itself, no
    coordinate of it zero (``LocalMap.at``)."""
    return 0.0 not in t_prev.tolist()


def _learns_from(prior: Prior, fit: Refinement | bool | None) -> bool:
    """Whether a refined match (its prior the odometry's) would teach the odometry's noise
    and calibration (on time) or the stale rates (after a gap), where it stands: the
    assessment then gives the scan's own motion with it (one compiled call for both).
    ``fit``: the fit (None: none), or whether there is one."""
    has_fit = fit is not None and fit is not False
    return has_fit and prior.from_odometry and prior.odometry is not None
