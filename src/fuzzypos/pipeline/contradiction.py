"""The contradiction check: a features-only match that contradicts the odometry is overruled
and the odometry stands (``[gate]``'s ``contradiction_check``)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..config import GateConfig, OdometryNoiseConfig
from ..geometry import relative3
from ._window import Window
from .context import Matched, ScanContext
from .estimate import Reason
from .noise import OdometryNoise
from .prior import Prior
from .uncertainty import Uncertainty

__all__ = ["ContradictionCheck"]

FloatArray = NDArray[np.float64]


class ContradictionCheck:
    """Whether a features-only match contradicts the odometry (``[gate]``'s
    ``contradiction_check`` and ``contradiction_probability``), against the confirmed
    matches' own disagreements kept over ``[odometry_noise]``'s ``window`` (from
    ``min_samples`` of them)."""

    def __init__(
        self,
        gate: GateConfig,
        noise_settings: OdometryNoiseConfig,
        noise: OdometryNoise,
        uncertainty: Uncertainty,
    ) -> None:
        self.gate = gate
        self.noise_settings = noise_settings
        self.noise = noise
        self.uncertainty = uncertainty
        self.reset()

    def reset(self) -> None:
        """Forget the confirmed matches' disagreements."""
        #: the features' own error and the floor, the diagonal (:meth:`_disagreement`)
        both = self.uncertainty.feature_covariance() + self.uncertainty.floor
        self._feature_floor = (float(both[0, 0]), float(both[1, 1]), float(both[2, 2]))
        #: the confirmed (refined) matches' d² against the odometry (:meth:`contradicts`)
        self._disagreements = Window(self.noise_settings.window)

    def overrule(self, ctx: ScanContext) -> Matched:
        """The scan's step (``ctx.matched``), or where its match contradicts the odometry
        (:meth:`contradicts`) the odometry's: the prior stands, assessed from the previous
        scan's covariance before the match's assessment (``ctx.held``)."""
        matched = ctx.matched
        assert matched is not None
        from_key = matched.from_key
        if from_key is None or not self.contradicts(
            ctx.t_prev, ctx.prior, ctx.prior_covariance, from_key, matched.refined
        ):
            return matched
        judged = self.uncertainty.overruled(
            ctx.held, ctx.t_prev, ctx.prior.increment, ctx.prior_covariance
        )
        return matched._replace(
            from_key=None, reason=Reason.CONTRADICTS_ODOMETRY, assessment=judged
        )

    def contradicts(
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
        gate = self.gate
        if not (gate.contradiction_check and prior.from_odometry and self.noise.warm):
            return False
        if prior.odometry_rejected:
            return False
        d2 = self._disagreement(t_prev, prior.increment, prior_cov, from_key)
        seen = self._disagreements
        if refined:
            seen.append(d2)
            return False
        threshold = self.uncertainty.contradiction_threshold
        if len(seen) >= self.noise_settings.min_samples:
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
