"""The configuration sections of how good each increment is: the covariance of the scan's fit
(``[covariance]``), the odometry's noise model learned online (``[odometry_noise]``) and the
gate between them (``[gate]``). Part of :mod:`fuzzypos.config`, which assembles every section
into ``Config``."""

from __future__ import annotations

import math
from dataclasses import dataclass

from .schema import _field, section

RAD = "rad"  # an angle: radians in code, degrees under "<name>_deg" in TOML
M = "m"


@dataclass(frozen=True)
@section("covariance")
class CovarianceConfig:
    """The covariance of every increment (``Estimate.covariance``) and of every scan's pose
    relative to its keyframe (``Estimate.keyframe_covariance``)."""

    point_correlation: float = _field(
        1.0,
        "the points' covariance from the fit (their information under the noise the residuals "
        "show) is multiplied by this, for errors the points share (a surface's normal, the "
        "keyframe's own noise). 1: the residuals' scale already holds the keyframe's noise "
        "and the surfaces' modelling error, and the normalised estimation error of simulated "
        "motions with known truth stays below a χ² with 3 degrees of freedom (the covariance "
        "errs on the large side)",
        ge=1.0,
    )
    floor_translation: float = _field(
        0.001,
        "every covariance is at least (1 mm)² in translation: the beams' spacing and the "
        "keyframe's discretisation leave that much however many points agree; never singular",
        unit=M,
        gt=0.0,
    )
    floor_rotation: float = _field(
        math.radians(0.01),
        "and (0.01°)² in rotation, for the same reason",
        unit=RAD,
        gt=0.0,
    )
    feature_translation: float = _field(
        0.03,
        "where the features alone gave the motion (no refinement), its standard deviation in "
        "translation: a feature point is a few centimetres off (break points, sampled corners)",
        unit=M,
        gt=0.0,
    )
    feature_rotation: float = _field(
        math.radians(0.5),
        "and in rotation: two feature points a few metres apart fix the heading to a fraction "
        "of a degree",
        unit=RAD,
        gt=0.0,
    )
    no_odometry_translation: float = _field(
        1.0,
        "without odometry the prior (the last increment) is this uncertain in translation: a "
        "broad prior that the scan overrules wherever it sees structure",
        unit=M,
        gt=0.0,
    )
    no_odometry_rotation: float = _field(
        math.radians(30.0),
        "and in rotation",
        unit=RAD,
        gt=0.0,
    )


@dataclass(frozen=True)
@section("odometry_noise")
class OdometryNoiseConfig:
    """The odometry's noise as a random walk: the variance of an increment grows with the
    distance and the rotation travelled (and, after a gap, with the time without odometry);
    its parameters start at the configured values and are learned online, within a floor and
    a ceiling, from where confident matches and the odometry disagree."""

    translation_per_sqrt_m: float = _field(
        0.03,
        "the starting translation noise: σ grows as 3 cm per √m travelled (good wheel "
        "odometry; poorer odometry is learned within a few hundred scans)",
        unit="m/√m",
        gt=0.0,
    )
    rotation_per_sqrt_m: float = _field(
        math.radians(0.2),
        "the starting rotation noise: σ grows as 0.2° per √m travelled (or per "
        "turning_distance of turning)",
        unit=RAD,
        gt=0.0,
    )
    turning_distance: float = _field(
        0.5,
        "turning one radian counts like travelling this far for the rotation noise (wheels "
        "slip when a robot turns on the spot)",
        unit="m/rad",
        ge=0.0,
    )
    floor_translation: float = _field(
        0.002,
        "an increment's translation σ is at least 2 mm however short (quantisation, timing)",
        unit=M,
        gt=0.0,
    )
    floor_rotation: float = _field(
        math.radians(0.05),
        "and its rotation σ at least 0.05°",
        unit=RAD,
        gt=0.0,
    )
    min_translation_per_sqrt_m: float = _field(
        0.005,
        "the learned translation noise never drops below 5 mm per √m: no odometry is perfect",
        unit="m/√m",
        gt=0.0,
    )
    max_translation_per_sqrt_m: float = _field(
        0.5,
        "nor rises above 0.5 m per √m: beyond that the odometry says nothing, and a run of "
        "false matches must not teach the gate to accept anything",
        unit="m/√m",
        gt=0.0,
    )
    min_rotation_per_sqrt_m: float = _field(
        math.radians(0.05),
        "the learned rotation noise never drops below 0.05° per √m",
        unit=RAD,
        gt=0.0,
    )
    max_rotation_per_sqrt_m: float = _field(
        math.radians(20.0),
        "nor rises above 20° per √m",
        unit=RAD,
        gt=0.0,
    )
    learn: bool = _field(
        True,
        "learn the noise online from the disagreement of confident matches with the odometry "
        "(a robust running estimate: the median over the last increments), so priors and "
        "gates fit the odometry at hand rather than the logs the defaults were chosen on",
    )
    window: int = _field(
        300,
        "the running estimate is the median over the last 300 confident matches: long enough "
        "that a stretch of false matches cannot move it, short enough to follow a change of "
        "floor",
        ge=10,
    )
    min_samples: int = _field(
        30,
        "the configured noise stands until 30 confident matches have been seen",
        ge=1,
    )
    stale_speed: float = _field(
        0.5,
        "after a gap in time (beyond the usual scan period) the odometry is stale: its "
        "translation σ grows by 0.5 m per second of the gap (a walking pace the robot may have "
        "covered unseen)",
        unit="m/s",
        ge=0.0,
    )
    stale_turn_rate: float = _field(
        0.5,
        "and its rotation σ by 0.5 rad per second of the gap (a robot may turn far during a "
        "gap the odometry missed)",
        unit="rad/s",
        ge=0.0,
    )
    stale_periods: float = _field(
        3.0,
        "a scan later than 3 usual scan periods (the running median of the time steps) after "
        "the previous one follows a gap: the time beyond that counts as stale",
        ge=1.0,
    )
    stale_quantile: float = _field(
        0.9,
        "the usual scan period is the 90th percentile of the last 51 time steps, not their "
        "median: where a log's stamps are logger times that come in bursts (a millisecond "
        "apart, then half a second), the long steps are as usual as the short ones and the "
        "odometry moved one usual step in each; on even stamps it is the period",
        ge=0.5,
        le=1.0,
    )
    learn_stale: bool = _field(
        True,
        "learn the stale rates from the matches after gaps (with learn): stale_speed and "
        "stale_turn_rate stand until stale_min_samples such matches, then each is the robust "
        "fit to how far the last window of them disagreed with the odometry beyond its "
        "on-time noise, bounded by odometry.max_speed and max_turn_rate. Where the odometry "
        "rides with each scan (CARMEN's FLASER lines) a gap in the scans is none in the "
        "odometry, and the configured rates make every edge of the pose graph after a logger "
        "gap claim degrees of heading, where loop closure then bends the trajectory; where the "
        "odometry stalls in gaps, the learned rates stay high",
    )
    stale_min_samples: int = _field(
        10,
        "the configured stale rates stand until 10 matches after gaps have been seen: each "
        "rate is one number, fitted robustly, and gaps are rare (a log may have a hundred in "
        "ten thousand scans, the noise's min_samples of them only near its end)",
        ge=1,
    )
    in_refinement: bool = _field(
        False,
        "once learned, the refinement's prior is everywhere the odometry's motion with its "
        "learned covariance (carried on from the previous scan's covariance relative to the "
        "keyframe) instead of the features' motion with the refinement section's fixed "
        "standard deviations. Off: on odometry poorer than matching, whose errors have heavy "
        "tails the learned median does not see, the prior pulls wrong at the bad increments "
        "(bench_switches.py shows it on the shared logs); trust_where_better turns it on "
        "where it helps",
    )
    calibrate: bool = _field(
        False,
        "correct the prior everywhere by the odometry's scale and rotation factor, "
        "calibrated online (least squares of the scan's own motion against the odometry's "
        "over confident matches). Off: where the odometry is the poorer, its noise dilutes "
        "the regression (the factors run to their bounds on the shared logs); "
        "trust_where_better turns it on where the regression is sound",
    )
    trust_where_better: bool = _field(
        True,
        "where the learned odometry is more precise than the matches (per unit of travel, in "
        "translation and rotation), the refinement's prior is the learned odometry "
        "(in_refinement) corrected by the calibration (calibrate): the scan then adds what "
        "it knows to odometry better than itself, and the regression of the scan's motion "
        "on the odometry's is sound. Off: the increments are the scans' where the odometry "
        "is ten times more precise step by step. The price: an odometry precise but biased "
        "(slip, skid) passes for better, and its bias can drift the trajectory a little, "
        "which a random walk does not model (bench_sim_kinds.py compares both)",
    )
    max_calibration: float = _field(
        0.05,
        "the calibration factors stay within 1 ± 0.05: wheel diameters and track widths are "
        "off by a few percent, not more",
        ge=0.0,
        le=0.5,
    )


@dataclass(frozen=True)
@section("gate")
class GateConfig:
    """A match whose disagreement with the odometry is too unlikely under both covariances is
    rejected: the odometry is kept and the scan flagged."""

    enabled: bool = _field(
        True,
        "reject matches whose disagreement with the odometry has a Mahalanobis distance "
        "squared (under the sum of both covariances) above the χ²(3) quantile below, where "
        "the odometry is the more precise (see only_where_odometry_is_better): a false line "
        "pairing that turns the scan by degrees where a good odometry says it went straight "
        "is caught, and the odometry's increment is kept",
    )
    only_where_odometry_is_better: bool = _field(
        True,
        "the gate is open only where the learned odometry is more precise than the matches "
        "(per unit of travel, in translation and rotation): where the odometry is poorer, a "
        "disagreement says more about the odometry than about the match (on poor odometry "
        "the gate rejected true matches by the thousand)",
    )
    probability: float = _field(
        0.99,
        "the χ²(3) quantile of the gate: 99 %, so one true match in a hundred is rejected "
        "and falls back to the odometry, which is then good enough by construction",
        gt=0.0,
        lt=1.0,
    )
    contradiction_check: bool = _field(
        True,
        "a match that only the features give (no point-to-line fit confirmed it, often two "
        "pairs) and that contradicts the odometry beyond what the odometry's learned noise and "
        "the features' own error allow (contradiction_probability) is not taken: the odometry "
        "stands and the scan is flagged 'contradicts the odometry', wherever the gate is "
        "(the gate is open only where the odometry is the more precise). Two false feature "
        "pairs turned a scan by 6° and moved it 14 cm back while the odometry said it stood, "
        "with the features' covariance of 0.5°, and the next keyframe kept the error",
    )
    contradiction_probability: float = _field(
        0.999,
        "the quantile of the disagreement between a features-only match and the odometry, "
        "its d² under the sum of the odometry's learned covariance and the features' own "
        "(covariance.feature_translation, feature_rotation_deg), beyond which the match "
        "contradicts the odometry: the larger of χ²(3)'s and that of the d² of the matches a "
        "fit confirmed, over the odometry noise's window (odometry_noise.window), so that "
        "odometry whose errors have heavier tails than its covariance (turns whose odometry "
        "lags the scans) raises the bar. 99.9 %: one true match in a thousand falls back to an "
        "odometry that is good enough by construction",
        gt=0.0,
        lt=1.0,
    )
