"""The stale odometry's rates learned from the matches after gaps: the robust fit against
samples of known rate, and two simulated logs with gaps, one whose odometry rides with the
scans (a CARMEN log: a gap in the scans is none in the odometry) and one whose odometry
misses a turn in every gap (with 20° both the learned and the configured rates lose 9°
there: the refinement after a 1.5 s gap starts from the odometry, no wide search)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fuzzypos import Config, Pose2D, Positioner, Reason, sim
from fuzzypos.geometry import compose, relative
from fuzzypos.pipeline._stale import StaleRates, fit_stale_rate

GATED = Config().with_overrides({"gate": {"enabled": True}})
#: a gap every this many scans
GAP_EVERY = 12


def samples(rate: float, n: int, rng: np.random.Generator) -> list[tuple[float, float, float]]:
    """``(e², v, τ²)`` of disagreements whose variance is v + rate² τ² (v, τ at random)."""
    out = []
    for _ in range(n):
        v = rng.uniform(1e-6, 1e-4)
        tau = rng.uniform(0.5, 3.0)
        e = rng.normal(0.0, math.sqrt(v + (rate * tau) ** 2))
        out.append((e * e, v, tau * tau))
    return out


@settings(max_examples=25, deadline=None)
@given(rate=st.floats(0.01, 1.0), seed=st.integers(0, 2**31 - 1))
def test_the_fit_recovers_a_known_rate(rate: float, seed: int) -> None:
    fitted = fit_stale_rate(samples(rate, 600, np.random.default_rng(seed)), bound=2.0)
    assert fitted == pytest.approx(rate, rel=0.25)


def test_gaps_that_are_on_time_fit_a_rate_of_zero_or_next_to_it() -> None:
    fitted = fit_stale_rate(samples(0.0, 600, np.random.default_rng(1)), bound=2.0)
    # the on-time spread alone: at most what its own scale (v ≤ 1e-4, τ ≥ 0.5 s) allows
    assert fitted < 0.005


def test_the_fit_is_bounded_and_grows_with_the_disagreement() -> None:
    rng = np.random.default_rng(2)
    base = samples(0.1, 200, rng)
    doubled = [(4.0 * e2, v, t2) for e2, v, t2 in base]
    assert fit_stale_rate(doubled, 2.0) > fit_stale_rate(base, 2.0)
    huge = [(1e6, v, t2) for _, v, t2 in base]
    assert fit_stale_rate(huge, 2.0) == 2.0


def test_the_configured_rates_stand_until_enough_samples() -> None:
    rates = StaleRates(0.5, 0.4, 1.5, 2.0, window=50, min_samples=10)
    for k in range(9):
        rates.learn((0.001, -0.001, 0.0005), (1e-5, 1e-5, 1e-6), 1.0 + 0.1 * k)
        assert (rates.speed, rates.turn_rate) == (0.5, 0.4)
    rates.learn((0.001, 0.001, 0.0005), (1e-5, 1e-5, 1e-6), 2.0)
    assert rates.samples == 10
    assert rates.speed < 0.01 and rates.turn_rate < 0.01
    rates.learn((math.nan, 0.0, 0.0), (1e-5, 1e-5, 1e-6), 2.0)  # not a sample
    assert rates.samples == 10
    rates.reset()
    assert (rates.speed, rates.turn_rate, rates.samples) == (0.5, 0.4, 0)


def gap_run(
    unseen_turn_deg: float, config: Config, n: int = 200, beams: int = 360, fov: float = 360.0
) -> tuple[list, list, Positioner]:
    """A robot driving an arc in a furnished room with precise odometry, scans 0.2 s apart
    but every 12th from scan 36 on after a 1.5 s gap (rare enough that 0.2 s stays the usual
    period); in each gap the robot turns
    ``unseen_turn_deg`` (alternately left and right) that the odometry does not see (0: the
    odometry rides with the scans)."""
    world = sim.furnished_room(1)
    odom = sim.arc_path(Pose2D(-1.0, -0.5, 0.2), n, 0.03, 1.0)
    truth, stamps, t, sign = [odom[0]], [0.0], 0.0, 1.0
    for k in range(1, n):
        step = relative(odom[k - 1].as_array(), odom[k].as_array())
        gap = k >= 36 and (k - 36) % GAP_EVERY == 0
        t += 1.5 if gap else 0.2
        pose = truth[-1].as_array()
        if gap:
            pose = compose(pose, np.array([0.0, 0.0, sign * math.radians(unseen_turn_deg)]))
            sign = -sign
        truth.append(Pose2D.from_array(compose(pose, step)))
        stamps.append(t)
    rng = np.random.default_rng(0)
    model = sim.ScannerModel(
        n_beams=beams, field_of_view_deg=fov, angle_min_deg=-fov / 2, range_max=8.0,
        range_noise_std=0.005 if beams >= 360 else 0.01,
    )  # fmt: skip
    scans = [sim.simulate_scan(world, p, model, rng, stamp=s) for p, s in zip(truth, stamps)]
    pos = Positioner(config)
    est = [pos.update(s, o) for s, o in zip(scans, odom)]
    return truth, est, pos


def gaps(est: list) -> list[int]:
    return [k for k in range(36, len(est)) if (k - 36) % GAP_EVERY == 0]


def test_odometry_that_rides_with_the_scans_learns_that_gaps_are_not_stale() -> None:
    """A 180° scanner of 180 beams (intel's kind): the rates learned from the first ten gaps
    are next to zero, so after the later gaps the increments claim less than with the
    configured rates, whose covariance also blinds the gate there (d² ≈ 0)."""
    truth, est, pos = gap_run(0.0, GATED, beams=180, fov=180.0)
    stale = pos.odometry_noise.stale
    assert stale.samples >= 10
    assert stale.turn_rate < 0.05 and stale.speed < 0.05, (stale.turn_rate, stale.speed)
    late = gaps(est)[11:]  # after the 10th sample (the 11th gap's is the first learned from)
    assert late
    off = GATED.with_overrides({"odometry_noise": {"learn_stale": False}})
    fixed = gap_run(0.0, off, beams=180, fov=180.0)[1]
    for k in late:
        learned_sigma, fixed_sigma = (math.sqrt(e[k].covariance[2, 2]) for e in (est, fixed))
        assert learned_sigma < 0.6 * fixed_sigma, (k, learned_sigma, fixed_sigma)
        assert fixed[k].gate is not None and fixed[k].gate < 0.01
        assert est[k].gate is not None and est[k].gate > 10.0 * fixed[k].gate
    d = relative(truth[-1].as_array(), est[-1].pose.as_array())
    assert abs(math.degrees(d[2])) < 0.5 and math.hypot(d[0], d[1]) < 0.03, d


def test_odometry_that_misses_turns_in_gaps_keeps_the_rates_high() -> None:
    """Each gap hides a 10° turn: the learned turn rate stays near what the turns need
    (10° in the 0.9 s of the gap beyond 3 usual periods: 0.19 rad/s, as the median of
    a normal's square: 0.29), every scan after a gap is matched (the gate lets the turn
    through) and the trajectory ends where the robot did."""
    truth, est, pos = gap_run(10.0, GATED)
    stale = pos.odometry_noise.stale
    assert stale.samples >= 10
    assert 0.15 < stale.turn_rate < 0.5, stale.turn_rate
    for k in gaps(est):
        assert est[k].reason is Reason.MATCHED and not est[k].degraded, (k, est[k].reason)
    d = relative(truth[-1].as_array(), est[-1].pose.as_array())
    assert abs(math.degrees(d[2])) < 0.5 and math.hypot(d[0], d[1]) < 0.03, d
