"""A match the features alone give (no fit confirmed it) that contradicts the odometry is not
taken (``[gate] contradiction_check``): the odometry stands and the scan says why. Simulated
runs with a false feature match put in at known scans; the threshold rises with the confirmed
matches' own disagreement (odometry with heavy tails)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from fuzzypos import sim
from fuzzypos.config import Config
from fuzzypos.geometry import Pose2D, compose, relative
from fuzzypos.pipeline import Positioner, Reason
from fuzzypos.pipeline.feature_match import FeatureMatch

#: the scans whose feature match is made false: turned by this much
FALSE_AT = (40, 55)
FALSE_TURN = math.radians(6.0)


def _run() -> sim.SimulatedRun:
    world = sim.world_by_name("office")
    path = sim.CommandedPath.circle(1.0, laps=0.35, speed=0.3)
    return sim.simulate_run(world, path, sim.ScannerModel.sick_lms200(), sim.SlipModel(), 4)


def _positioner(check: bool, refine: bool = False) -> Positioner:
    """The default with the check on or off; without the refinement every match is the
    features' alone, and the odometry's noise is then its configured one (nothing to learn
    it from)."""
    cfg = Config()
    cfg = replace(
        cfg,
        gate=replace(cfg.gate, contradiction_check=check),
        refinement=replace(cfg.refinement, enabled=refine),
        odometry_noise=replace(cfg.odometry_noise, learn=refine),
    )
    return Positioner(cfg)


def _with_false_matches(p: Positioner, at: set[int]) -> list[int]:
    """The feature matcher's motion at the scans ``at`` (counted from 0) turned by
    FALSE_TURN; returns the counter the wrapper keeps (its one element: the scan number)."""
    seen = [0]
    match = p.feature_matcher.match

    def false_match(prev, features, key_prior):  # type: ignore[no-untyped-def]
        seen[0] += 1
        out = match(prev, features, key_prior)
        if seen[0] in at and out.increment is not None:
            inc = compose(out.increment, np.array([0.0, 0.0, FALSE_TURN]))
            return FeatureMatch._of(inc, out.n_pairs, out.reason)
        return out

    p.feature_matcher.match = false_match  # type: ignore[method-assign]
    return seen


def _errors(run: sim.SimulatedRun, estimates) -> np.ndarray:  # type: ignore[no-untyped-def]
    """Each increment's rotation error against the truth (rad)."""
    truth = run.true_poses
    out = []
    for k in range(1, len(estimates)):
        true_inc = relative(truth[k - 1], truth[k])
        out.append(relative(true_inc, estimates[k].increment.as_array())[2])
    return np.abs(np.array(out))


@pytest.mark.parametrize("check", [True, False])
def test_a_false_feature_match_falls_back_to_the_odometry(check: bool) -> None:
    run = _run()
    p = _positioner(check)
    _with_false_matches(p, set(FALSE_AT))
    odoms = [Pose2D.from_array(o) for o in run.odometry_poses]
    est = p.run(run.scans, odoms)
    flagged = [k for k, e in enumerate(est) if e.reason is Reason.CONTRADICTS_ODOMETRY]
    errors = _errors(run, est)
    if check:
        # the false matches, and nothing else, fall back: their increment is the odometry's
        assert len(flagged) == len(FALSE_AT)
        for k in flagged:
            assert est[k].degraded
            np.testing.assert_allclose(est[k].increment.as_array(), est[k].prior.as_array())
        assert errors.max() < math.radians(3.0)
    else:  # without the check the false turn is taken
        assert flagged == []
        assert errors.max() > math.radians(5.0)


def test_true_feature_matches_are_not_flagged() -> None:
    """On a run without false matches nothing contradicts the odometry (false alarms)."""
    run = _run()
    odoms = [Pose2D.from_array(o) for o in run.odometry_poses]
    for refine in (False, True):
        est = _positioner(True, refine).run(run.scans, odoms)
        assert not any(e.reason is Reason.CONTRADICTS_ODOMETRY for e in est)


def test_heavy_tailed_odometry_raises_the_bar() -> None:
    """The threshold is the larger of χ²(3)'s quantile and the confirmed matches' own: after
    confirmed matches that disagreed with the odometry by d² ≈ 100, a features-only match at
    d² ≈ 50 is taken, and one at d² ≈ 400 is not."""
    p = _positioner(True)
    run = _run()
    p.update(run.scans[0], Pose2D.from_array(run.odometry_poses[0]))
    noise = p.odometry_noise
    noise._warm = True  # (the noise known: as after min_samples matches)
    cov = p.odometry_noise.covariance(np.array([0.3, 0.0, 0.0]))
    total = cov + p.uncertainty.feature_covariance() + p.uncertainty.floor
    sigma_theta = math.sqrt(total[2, 2])
    prior = p.odometry_prior.predict(run.scans[1].stamp, Pose2D.from_array(run.odometry_poses[1]))
    t_prev = np.zeros(3)

    def off(d2: float) -> np.ndarray:  # the match d² away from the prior, in rotation
        return compose(prior.increment, np.array([0.0, 0.0, math.sqrt(d2) * sigma_theta]))

    pc = p.odometry_noise.covariance(prior.increment)
    contradicts = p.contradiction.contradicts
    assert contradicts(t_prev, prior, pc, off(50.0), False)  # χ²'s bar: 16.3
    for _ in range(Config().odometry_noise.min_samples):
        assert not contradicts(t_prev, prior, pc, off(100.0), True)  # confirmed: learned
    assert not contradicts(t_prev, prior, pc, off(50.0), False)
    assert contradicts(t_prev, prior, pc, off(400.0), False)
