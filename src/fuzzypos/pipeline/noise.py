"""The odometry's noise, learned online: a random walk whose variance grows with the distance
and the rotation travelled and with the time the odometry was stale, its parameters a robust
running estimate from where confident matches and the odometry disagree; and a running
calibration of the odometry's scale and rotation factor."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..config import OdometryConfig, OdometryNoiseConfig
from ..geometry import relative, relative3
from ._stale import StaleRates
from ._window import Window
from .prior import Prior

__all__ = ["OdometryNoise"]

FloatArray = NDArray[np.float64]

#: the medians of χ² with 2 and 1 degrees of freedom: a robust variance from squared errors
_MEDIAN_CHI2_2 = 2.0 * math.log(2.0)
_MEDIAN_CHI2_1 = 0.454936423119572
#: increments shorter than this (m, or m-equivalent of turning) teach the model nothing
_MIN_TRAVEL = 1e-3


class OdometryNoise:
    """The covariance of an odometry increment (``[odometry_noise]``), learned online.

    Translation: σ² = floor² + α_t² d (+ (stale_speed · stale)²); rotation: σ² = floor² +
    α_r² (d + turning_distance · |Δθ|) (+ (stale_turn_rate · stale)²), for an increment of
    length d turning Δθ, ``stale`` seconds of it without odometry. α_t and α_r start at the
    configured values; once ``min_samples`` confident matches have been seen, each is the
    median over the last ``window`` of their disagreement with the odometry, normalised by
    the travel, kept between its floor and ceiling. The stale rates likewise, from the matches
    after gaps once ``stale_min_samples`` have been seen (``learn_stale``, :mod:`._stale`),
    bounded by ``odometry``'s ``max_speed`` and ``max_turn_rate``.
    """

    def __init__(
        self, settings: OdometryNoiseConfig, odometry: OdometryConfig | None = None
    ) -> None:
        self.settings = settings
        bounds = odometry if odometry is not None else OdometryConfig()
        #: the stale odometry's rates (m/s, rad/s): configured, then learned after gaps
        self.stale = StaleRates(
            settings.stale_speed, settings.stale_turn_rate, bounds.max_speed,
            bounds.max_turn_rate, settings.window, settings.stale_min_samples,
        )  # fmt: skip
        self.reset()

    def reset(self) -> None:
        s = self.settings
        self.alpha_translation = s.translation_per_sqrt_m
        self.alpha_rotation = s.rotation_per_sqrt_m
        self._translation = Window(s.window)
        self._rotation = Window(s.window)
        # the matches' own variance per unit of travel, beside the disagreements
        self._translation_own = Window(s.window)
        self._rotation_own = Window(s.window)
        # least squares of the matched against the odometry's motion: Σ m·o and Σ o² (floats:
        # the same sums as float64 arrays', without an array operation per sample)
        self._scale_sums = (0.0, 0.0)
        self._turn_sums = (0.0, 0.0)
        self._better: bool | None = None  # better_than_matching, until the next sample
        self._warm = self._is_warm()  # warm, until the next sample
        self._factors: tuple[float, float] | None = None  # (scale, rotation_factor), likewise
        self.stale.reset()

    def _is_warm(self) -> bool:
        s = self.settings
        return not s.learn or min(len(self._translation), len(self._rotation)) >= s.min_samples

    @property
    def warm(self) -> bool:
        """Whether the noise is known: learned from ``min_samples`` matches (or not learned)."""
        return self._warm

    @property
    def scale(self) -> float:
        """The odometry's translation scale factor (the matched distance over the odometry's)."""
        return self._calibration()[0]

    @property
    def rotation_factor(self) -> float:
        """The odometry's rotation factor (the matched rotation over the odometry's)."""
        return self._calibration()[1]

    @property
    def trusted(self) -> bool:
        """Whether the odometry is trusted as the refinement's prior and its calibration
        applied: everywhere with ``in_refinement``/``calibrate``, else with
        ``trust_where_better`` where the learned odometry is the more precise."""
        return self.settings.trust_where_better and self.warm and self.better_than_matching

    def as_dict(self) -> dict[str, Any]:
        """What the noise is now, as plain values (``summary.json``'s ``odometry_noise``):
        ``translation_per_sqrt_m`` and ``rotation_per_sqrt_m`` (α_t in m/√m, α_r in rad/√m,
        learned or configured), ``stale_speed`` (m/s) and ``stale_turn_rate`` (rad/s),
        ``samples`` and ``stale_samples`` (the matches learned from, within the window),
        :attr:`warm`, :attr:`better_than_matching`, :attr:`trusted`, ``calibrated`` (whether
        the calibration is applied) with :attr:`scale` and :attr:`rotation_factor` (1 where it
        is not)."""
        s = self.settings
        scale, rotation_factor = self._calibration()
        return {
            "translation_per_sqrt_m": self.alpha_translation,
            "rotation_per_sqrt_m": self.alpha_rotation,
            "stale_speed": self.stale.speed,
            "stale_turn_rate": self.stale.turn_rate,
            "samples": min(len(self._translation), len(self._rotation)),
            "stale_samples": self.stale.samples,
            "warm": self.warm,
            "better_than_matching": self.better_than_matching,
            "trusted": self.trusted,
            "calibrated": bool(s.calibrate or self.trusted),
            "scale": scale,
            "rotation_factor": rotation_factor,
        }

    def _calibration(self) -> tuple[float, float]:
        """(:attr:`scale`, :attr:`rotation_factor`), computed once per sample."""
        if self._factors is None:
            self._factors = (self._factor(self._scale_sums), self._factor(self._turn_sums))
        return self._factors

    def _factor(self, sums: tuple[float, float]) -> float:
        s = self.settings
        if not (s.calibrate or self.trusted) or sums[1] <= 0.0:
            return 1.0
        bound = s.max_calibration
        return float(min(max(sums[0] / sums[1], 1.0 - bound), 1.0 + bound))

    @property
    def informs_refinement(self) -> bool:
        """Whether the learned noise gives the refinement's priors their information
        (``in_refinement`` once it is known, or where it is :attr:`trusted`)."""
        return (self.settings.in_refinement and self.warm) or self.trusted

    def calibrated_prior(self, prior: Prior) -> Prior:
        """The odometry ``prior``, its increment corrected by the learned calibration (the
        prior itself where it is no odometry's or there is no calibration to apply)."""
        if not prior.from_odometry:
            return prior
        increment = self.calibrated(prior.increment)
        if increment is prior.increment:  # no calibration to apply
            return prior
        return Prior._of(
            increment, prior.odometry, prior.dt, prior.odometry_rejected, prior.standing_still,
            prior.stale,
        )  # fmt: skip

    def prior_covariance(self, prior: Prior, broad: FloatArray) -> FloatArray:
        """The covariance of the prior: this noise's (grown by the time the odometry was
        stale), or the ``broad`` one where the prior is the last increment (a writable copy
        of it: the kernels that read it are compiled for writable arrays, not once more for
        read-only ones)."""
        if not prior.from_odometry:
            out: FloatArray = broad.copy()
            return out
        return self.covariance(prior.increment, prior.stale)

    def calibrated(self, increment: FloatArray) -> FloatArray:
        """The odometry ``increment`` corrected by the calibration factors."""
        k, r = self._calibration()
        if k == 1.0 and r == 1.0:
            return increment
        return np.array([increment[0] * k, increment[1] * k, increment[2] * r])

    def covariance(self, increment: FloatArray, stale: float = 0.0) -> FloatArray:
        """The 3×3 covariance of an odometry ``increment`` (x, y, θ in its start's frame),
        ``stale`` seconds of it without odometry."""
        s = self.settings
        x, y, theta = increment.tolist()
        d = math.hypot(x, y)
        turn = abs(theta)
        var_t = s.floor_translation**2 + self.alpha_translation**2 * d
        var_r = s.floor_rotation**2 + self.alpha_rotation**2 * (d + s.turning_distance * turn)
        if stale > 0.0:
            var_t += (self.stale.speed * stale) ** 2
            var_r += (self.stale.turn_rate * stale) ** 2
        # (filled in place: a nested list of nine floats makes a slower array)
        out = np.zeros((3, 3))
        out[0, 0] = out[1, 1] = var_t
        out[2, 2] = var_r
        return out

    def learn(
        self,
        odometry: FloatArray,
        matched: FloatArray,
        matched_covariance: FloatArray | None = None,
    ) -> None:
        """A confident match ``matched`` (with its own covariance, where known) of an
        increment the odometry says was ``odometry``: their disagreement teaches the noise,
        their ratio the calibration."""
        # in floats: three numbers each, a numpy operation apiece would cost more than the
        # arithmetic (the same float64 operations, so the very same values)
        s = self.settings
        ox, oy, ot = odometry.tolist()
        d = math.hypot(ox, oy)
        travel = d + s.turning_distance * abs(ot)
        if travel < _MIN_TRAVEL:
            return
        mx, my, mt = matched.tolist()
        if s.calibrate or s.trust_where_better:
            dm = math.hypot(mx, my)
            mo, oo = self._scale_sums
            self._scale_sums = (mo + dm * d, oo + d * d)
            mo, oo = self._turn_sums
            self._turn_sums = (mo + mt * ot, oo + ot**2)
            self._factors = None
        if not s.learn:
            return
        k, r = self._calibration()
        odo = (ox, oy, ot) if k == 1.0 and r == 1.0 else (ox * k, oy * k, ot * r)
        ex, ey, et = relative3(odo, (mx, my, mt))
        # the disagreement is the odometry's error and the match's; the match's share (its
        # own variance) is taken off the medians, not sample by sample (a difference of two
        # noisy estimates clipped at zero would bias the median toward the floor)
        if d >= _MIN_TRAVEL:
            e2 = (ex**2 + ey**2) / _MEDIAN_CHI2_2 - s.floor_translation**2
            self._translation.append(max(e2, 0.0) / d)
            if matched_covariance is not None:
                own_xy = float(matched_covariance[0, 0]) + float(matched_covariance[1, 1])
                self._translation_own.append(own_xy / 2.0 / d)
        e2r = et**2 / _MEDIAN_CHI2_1 - s.floor_rotation**2
        self._rotation.append(max(e2r, 0.0) / travel)
        if matched_covariance is not None:
            self._rotation_own.append(float(matched_covariance[2, 2]) / travel)
        self._update()

    def learn_stale(
        self,
        odometry: FloatArray,
        matched: FloatArray,
        matched_covariance: FloatArray,
        stale: float,
    ) -> None:
        """A match ``matched`` (with its own covariance) of an increment the odometry says was
        ``odometry`` after a gap of ``stale`` seconds: their disagreement beyond what it is on
        time teaches the stale rates (``learn_stale``)."""
        if not (self.settings.learn and self.settings.learn_stale):
            return
        err = relative(self.calibrated(odometry), matched)
        on_time = np.diag(self.covariance(odometry)) + np.diag(matched_covariance)
        self.stale.learn(
            (float(err[0]), float(err[1]), float(err[2])),
            (float(on_time[0]), float(on_time[1]), float(on_time[2])),
            stale,
        )

    @property
    def better_than_matching(self) -> bool:
        """Whether the learned odometry is more precise than the matches, per unit of travel,
        in translation and in rotation (False until both are known)."""
        if self._better is None:
            self._better = self._compare()
        return self._better

    def _compare(self) -> bool:
        s = self.settings
        if min(len(self._translation_own), len(self._rotation_own)) < s.min_samples:
            return False
        own_t = self._translation_own.median()
        own_r = self._rotation_own.median()
        return self.alpha_translation**2 < own_t and self.alpha_rotation**2 < own_r

    def _update(self) -> None:
        self._better = None
        self._factors = None
        self._warm = self._is_warm()
        s = self.settings
        if len(self._translation) >= s.min_samples:
            own = self._translation_own.median() if len(self._translation_own) else 0.0
            a = math.sqrt(max(self._translation.median() - own, 0.0))
            lo, hi = s.min_translation_per_sqrt_m, s.max_translation_per_sqrt_m
            self.alpha_translation = min(max(a, lo), hi)
        if len(self._rotation) >= s.min_samples:
            own = self._rotation_own.median() if len(self._rotation_own) else 0.0
            a = math.sqrt(max(self._rotation.median() - own, 0.0))
            lo, hi = s.min_rotation_per_sqrt_m, s.max_rotation_per_sqrt_m
            self.alpha_rotation = min(max(a, lo), hi)
