"""How good every increment is: covariances against simulated motions with known truth, the
odometry noise learned online, and the gate between the two."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fuzzypos import Config, Pose2D, Positioner, Reason, sim
from fuzzypos.geometry import compose, compose_jacobians, relative
from fuzzypos.matching import Refinement
from fuzzypos.pipeline import OdometryNoise, Uncertainty
from fuzzypos.pipeline.uncertainty import local

CFG = Config()
#: the gate on (it is off by default)
GATED = Config().with_overrides({"gate": {"enabled": True}})


def scanner(noise: float = 0.01, beams: int = 180, fov: float = 180.0) -> sim.ScannerModel:
    return sim.ScannerModel(
        n_beams=beams, field_of_view_deg=fov, angle_min_deg=-fov / 2, range_max=8.0,
        range_noise_std=noise,
    )  # fmt: skip


def positive_definite(cov: np.ndarray) -> bool:
    return bool(np.allclose(cov, cov.T) and np.linalg.eigvalsh(cov).min() > 0.0)


# -- geometry of the covariances ---------------------------------------------------------------
@settings(max_examples=50, deadline=None)
@given(
    st.tuples(*[st.floats(-3.0, 3.0)] * 2, st.floats(-math.pi, math.pi)),
    st.tuples(*[st.floats(-1.0, 1.0)] * 2, st.floats(-math.pi, math.pi)),
)
def test_compose_jacobians_match_numerical_derivatives(a, b) -> None:
    a, b = np.array(a), np.array(b)
    ja, jb = compose_jacobians(a, b)
    h = 1e-6
    for k in range(3):
        d = np.zeros(3)
        d[k] = h
        num_a = (compose(a + d, b) - compose(a - d, b)) / (2 * h)
        num_b = (compose(a, b + d) - compose(a, b - d)) / (2 * h)
        for num in (num_a, num_b):
            num[2] = (num[2] + math.pi / h) % (2 * math.pi / h) - math.pi / h
        np.testing.assert_allclose(ja[:, k], num_a, atol=1e-6)
        np.testing.assert_allclose(jb[:, k], num_b, atol=1e-6)


def test_local_covariance_is_that_of_the_right_perturbation() -> None:
    """Samples of an additive error δ, seen as ε = ⊖true ⊕ (true + δ), have covariance
    ``local(cov, θ)`` (Monte Carlo, 20,000 samples)."""
    rng = np.random.default_rng(0)
    true = np.array([1.0, -2.0, 1.1])
    cov = np.array([[4e-4, 1e-4, 0.0], [1e-4, 1e-4, 2e-5], [0.0, 2e-5, 1e-4]])
    deltas = rng.multivariate_normal(np.zeros(3), cov, 20_000)
    eps = np.array([relative(true, true + d) for d in deltas])
    np.testing.assert_allclose(np.cov(eps.T), local(cov, true[2]), rtol=0.05, atol=2e-6)


# -- covariances of simulated motions ------------------------------------------------------------
def motion_nees(noise: float, n: int = 30) -> np.ndarray:
    """NEES of ``n`` simulated increments whose odometry error is drawn from the model."""
    world = sim.furnished_room(0)
    sc = scanner(noise)
    model = OdometryNoise(CFG.odometry_noise)
    out = []
    for i, trial in enumerate(sim.random_motions(world, sc, n, 5, odometry_error=(0.0, 0.0))):
        rng = np.random.default_rng((11, i))
        e = rng.multivariate_normal(np.zeros(3), model.covariance(trial.increment))
        pos = Positioner()
        pos.update(sim.simulate_scan(world, trial.start, sc, rng, stamp=0.0), Pose2D())
        est = pos.update(
            sim.simulate_scan(world, trial.end, sc, rng, stamp=1.0),
            Pose2D.from_array(compose(trial.increment, e)),
        )
        assert est.covariance is not None and positive_definite(est.covariance)
        err = relative(trial.increment, est.increment.as_array())
        out.append(float(err @ np.linalg.solve(est.covariance, err)))
    return np.array(out)


@pytest.mark.parametrize("noise", [0.005, 0.02])
def test_the_covariance_is_honest_on_simulated_motions(noise: float) -> None:
    """The NEES of simulated increments looks like a χ²(3) draw (median 2.37, 90th percentile
    6.25): neither overconfident nor hiding the error behind a huge covariance."""
    nees = motion_nees(noise)
    assert 0.3 <= float(np.median(nees)) <= 8.0, np.median(nees)
    assert float(np.percentile(nees, 90)) <= 25.0, np.percentile(nees, 90)


def corridor_run(odometry: bool) -> list:
    walls = sim.World.from_segments([[-30.0, -1.0, 30.0, -1.0], [-30.0, 1.0, 30.0, 1.0]])
    truth = [Pose2D(0.1 * k, 0.0, 0.0) for k in range(4)]
    rng = np.random.default_rng(3)
    scans = [sim.simulate_scan(walls, p, scanner(0.005, 360, 360.0), rng, stamp=0.2 * k)
             for k, p in enumerate(truth)]  # fmt: skip
    return Positioner().run(scans, truth if odometry else None)


def test_in_a_featureless_corridor_the_covariance_is_long_along_it() -> None:
    for odometry in (True, False):
        est = corridor_run(odometry)[1]
        cov = est.covariance
        assert cov is not None and positive_definite(cov)
        along, across = math.sqrt(cov[0, 0]), math.sqrt(cov[1, 1])
        assert along > 5.0 * across, (odometry, along, across)
        if odometry:  # along the corridor the odometry's own uncertainty, no better
            odo = OdometryNoise(CFG.odometry_noise).covariance(np.array([0.1, 0.0, 0.0]))
            assert along >= 0.5 * math.sqrt(odo[0, 0]), (along, odo)
        else:  # without odometry: the broad prior's
            assert along > 0.3, along


def test_first_scan_and_standing_still_have_a_small_positive_floor() -> None:
    world = sim.furnished_room(0)
    scans = [sim.simulate_scan(world, Pose2D(), scanner(), stamp=0.1 * k) for k in range(3)]
    est = Positioner().run(scans, [Pose2D()] * 3)
    assert est[0].reason is Reason.FIRST_SCAN and est[1].reason is Reason.STANDING_STILL
    for e in est:
        assert positive_definite(e.covariance) and positive_definite(e.keyframe_covariance)
        assert np.sqrt(np.diag(e.covariance)).max() < 0.01


def test_a_degraded_scan_takes_the_odometry_covariance() -> None:
    world = sim.furnished_room(0)
    poses = [Pose2D(0.1 * k, 0.0, 0.0) for k in range(3)]
    scans = [sim.simulate_scan(world, p, scanner(), stamp=0.1 * k) for k, p in enumerate(poses)]
    scans[2] = replace(scans[2], ranges=np.full(scans[2].n_beams, np.inf))
    est = Positioner().run(scans, poses)
    assert est[2].degraded
    odo = OdometryNoise(CFG.odometry_noise).covariance(np.array([0.1, 0.0, 0.0]))
    # the odometry's (its increment corrected by the calibration learned so far)
    floor = Uncertainty(CFG.covariance, CFG.gate).floor
    np.testing.assert_allclose(est[2].covariance, odo + floor, rtol=0.02)
    assert est[1].covariance[0, 0] < odo[0, 0]  # a matched scan knows better than odometry


def test_keyframe_covariance_is_the_fit_against_the_keyframe() -> None:
    """Scans fitted against one keyframe: their keyframe covariance does not grow as the sum
    of the increments' covariances would."""
    world = sim.furnished_room(0)
    poses = [Pose2D(0.05 * k, 0.0, 0.01 * k) for k in range(8)]
    rng = np.random.default_rng(2)
    scans = [
        sim.simulate_scan(world, p, scanner(), rng, stamp=0.1 * k) for k, p in enumerate(poses)
    ]
    est = Positioner().run(scans, poses)
    summed = sum(e.covariance for e in est[1:])
    last = est[-1].keyframe_covariance
    assert positive_definite(last)
    assert np.trace(last) < np.trace(summed), (np.trace(last), np.trace(summed))


# -- the odometry's noise, learned --------------------------------------------------------------
def test_the_noise_is_learned_from_disagreements_and_kept_within_bounds() -> None:
    rng = np.random.default_rng(4)
    noise = OdometryNoise(CFG.odometry_noise)
    true_t, true_r = 0.08, math.radians(1.0)  # per √m: a poorer odometry than configured
    for _ in range(400):
        u = np.array([rng.uniform(0.05, 0.3), rng.normal(0, 0.02), rng.normal(0, 0.05)])
        d = math.hypot(u[0], u[1])
        var_r = true_r**2 * (d + CFG.odometry_noise.turning_distance * abs(u[2]))
        err = rng.normal(0.0, [true_t * math.sqrt(d)] * 2 + [math.sqrt(var_r)])
        matched = compose(u, err)  # the truth, which a confident match sees
        noise.learn(u, matched)
    assert noise.warm
    assert noise.alpha_translation == pytest.approx(true_t, rel=0.2)
    assert noise.alpha_rotation == pytest.approx(true_r, rel=0.2)
    # a ceiling: a run of nonsense cannot teach it to accept anything
    for _ in range(400):
        noise.learn(np.array([0.1, 0.0, 0.0]), np.array([5.0, 3.0, 2.0]))
    assert noise.alpha_translation == CFG.odometry_noise.max_translation_per_sqrt_m
    assert noise.alpha_rotation == CFG.odometry_noise.max_rotation_per_sqrt_m


def test_the_calibration_learns_a_rotation_under_read() -> None:
    noise = OdometryNoise(replace(CFG.odometry_noise, calibrate=True))
    rng = np.random.default_rng(5)
    for _ in range(200):
        u = np.array([0.2, 0.0, rng.uniform(-0.3, 0.3)])
        noise.learn(u, np.array([0.2, 0.0, u[2] / 0.99]))  # under-reads 1 %
    assert noise.rotation_factor == pytest.approx(1 / 0.99, abs=1e-6)
    assert OdometryNoise(CFG.odometry_noise).rotation_factor == 1.0  # off by default
    assert noise.scale == pytest.approx(1.0, abs=1e-9)
    np.testing.assert_allclose(noise.calibrated(np.array([1.0, 0.0, 0.5])), [1.0, 0.0, 0.5 / 0.99])


def test_a_stale_odometry_is_uncertain() -> None:
    noise = OdometryNoise(CFG.odometry_noise)
    u = np.array([0.2, 0.0, 0.1])
    on_time, stale = noise.covariance(u), noise.covariance(u, stale=2.0)
    assert stale[2, 2] > (math.radians(45.0)) ** 2 > on_time[2, 2]
    assert stale[0, 0] > 0.5**2 > on_time[0, 0]


# -- the gate ------------------------------------------------------------------------------------
def fit_at(increment: np.ndarray, sigma: float) -> Refinement:
    """A refinement that measured ``increment`` with ``sigma`` in every direction."""
    info = np.eye(3) / sigma**2
    return Refinement(
        increment, 100, 1.0, 1.0, information=info, gradient_covariance=info * sigma**4,
        start=increment, prior=increment,
    )  # fmt: skip


def test_the_gate_rejects_what_both_covariances_make_unlikely() -> None:
    u = np.array([0.2, 0.0, 0.0])
    odo = np.diag([0.01**2, 0.01**2, math.radians(0.3) ** 2])
    for turn_deg, rejected in ((0.2, False), (7.0, True)):
        unc = Uncertainty(GATED.covariance, GATED.gate)
        match = compose(u, np.array([0.0, 0.0, math.radians(turn_deg)]))
        judged = unc.assess(np.zeros(3), u, odo, match, fit_at(match, 0.002), gate_open=True)
        assert judged.rejected is rejected, judged.gate
        assert judged.gate is not None and (judged.gate > unc.threshold) is rejected
    assert Uncertainty(CFG.covariance, CFG.gate).threshold == pytest.approx(11.3449, abs=1e-3)


@pytest.mark.parametrize("probability", [0.5, 0.9, 0.99, 0.999, 0.9999, 1 - 1e-9])
def test_gate_threshold_is_scipy_stats_chi2_quantile(probability):
    from scipy.stats import chi2

    gate = replace(CFG.gate, probability=probability)
    assert Uncertainty(CFG.covariance, gate).threshold == float(chi2.ppf(probability, 3))


def learning_run(turn_at: int | None, gap_at: int | None, n: int = 60) -> list:
    """A robot driving an arc in a furnished room with precise odometry; at ``turn_at`` the
    scan is matched 7° off by a false match (the refinement forced there); at ``gap_at`` the
    robot turns 50° during a 3 s gap the odometry missed."""
    world = sim.furnished_room(1)
    truth = sim.arc_path(Pose2D(-1.0, -0.5, 0.2), n, 0.03, 1.0)
    odom = list(truth)
    stamps = [0.2 * k for k in range(n)]
    if gap_at is not None:
        # the robot turns 50° on the spot where the gap begins, unseen by the odometry
        pivot = compose(truth[gap_at].as_array(), np.array([0.0, 0.0, math.radians(50.0)]))
        base = truth[gap_at].as_array()
        turned = [compose(pivot, relative(base, p.as_array())) for p in truth[gap_at:]]
        truth = truth[:gap_at] + [Pose2D.from_array(p) for p in turned]
        stamps = stamps[:gap_at] + [s + 3.0 for s in stamps[gap_at:]]
    rng = np.random.default_rng(0)
    scans = [sim.simulate_scan(world, p, scanner(0.005, 360, 360.0), rng, stamp=t)
             for p, t in zip(truth, stamps)]  # fmt: skip
    # (the false match forced in the staged refinement: the compiled call that fuses it with
    # the matching and the assessment off, tests/pipeline/test_step.py checks both agree)
    pos = Positioner(GATED, fused=turn_at is None)
    if turn_at is not None:
        real = pos.refiner.refine

        def false_match(surface, points, starts, wide):
            best = real(surface, points, starts, wide)
            if len(out) == turn_at and best is not None:
                wrong = best.increment + np.array([0.0, 0.0, math.radians(7.0)])
                return replace(best, increment=wrong)
            return best

        pos.refiner.refine = false_match  # type: ignore[method-assign]
    out: list = []
    for s, o in zip(scans, odom):
        out.append(pos.update(s, o))
    return [truth, out]


def test_a_false_match_is_gated_once_the_odometry_noise_is_known() -> None:
    truth, est = learning_run(turn_at=50, gap_at=None)
    assert est[50].reason is Reason.GATED and est[50].degraded
    assert est[50].gate is not None and est[50].gate > 11.34
    assert not any(e.reason is Reason.GATED for e in est[:50])
    d = relative(truth[-1].as_array(), est[-1].pose.as_array())
    assert abs(math.degrees(d[2])) < 0.5 and math.hypot(d[0], d[1]) < 0.03, d


def test_after_a_gap_the_stale_odometry_lets_the_search_find_the_turn() -> None:
    """The robot turns 50° during a 3 s gap: the odometry there is stale, its covariance
    wide, and the wide search's match passes the gate (aces, scan 2,945)."""
    truth, est = learning_run(turn_at=None, gap_at=45)
    assert est[45].reason is Reason.MATCHED and not est[45].degraded, est[45]
    d = relative(truth[-1].as_array(), est[-1].pose.as_array())
    assert abs(math.degrees(d[2])) < 0.5 and math.hypot(d[0], d[1]) < 0.03, d


@pytest.mark.parametrize(
    "odometry_sigma, match_sigma, better", [(0.01, 0.03, True), (0.08, 0.01, False)]
)
def test_the_matches_share_is_taken_off_and_the_better_one_known(
    odometry_sigma: float, match_sigma: float, better: bool
) -> None:
    """Disagreements of an odometry with σ per √m and matches with their own (known)
    covariance: the learned noise is the odometry's alone, and the noise model knows which
    of the two is the more precise."""
    rng = np.random.default_rng(6)
    noise = OdometryNoise(CFG.odometry_noise)
    for _ in range(400):
        u = np.array([0.25, 0.0, 0.0])
        d = 0.25
        own = np.diag([match_sigma**2 * d] * 2 + [(math.radians(2.0) * match_sigma) ** 2 * d])
        odo_err = rng.normal(0.0, [odometry_sigma * math.sqrt(d)] * 2 + [
            math.radians(2.0) * odometry_sigma * math.sqrt(d)
        ])  # fmt: skip
        truth = compose(u, -odo_err)  # the odometry u is the truth plus its error
        matched = compose(truth, rng.multivariate_normal(np.zeros(3), own))
        noise.learn(u, matched, own)
    assert noise.alpha_translation == pytest.approx(
        max(odometry_sigma, CFG.odometry_noise.min_translation_per_sqrt_m), rel=0.35
    )
    assert noise.better_than_matching is better


# -- the scan's own motion, which the noise is learned from --------------------------------------
def test_the_scan_s_own_motion_undoes_the_prior_s_pull() -> None:
    """A fit pulled toward its prior: :meth:`Uncertainty.scan_only` gives back the motion the
    points alone give (x_s = A⁻¹ (M x − P p)) with the points' covariance A⁻¹ G A⁻¹."""
    rng = np.random.default_rng(8)
    root = rng.normal(size=(3, 3))
    a = root @ root.T + np.diag([400.0, 300.0, 900.0])  # the points' information
    p_info = np.diag([1.0 / 0.002**2] * 2 + [1.0 / math.radians(0.05) ** 2])
    x_s, prior = np.array([0.31, -0.02, 0.05]), np.array([0.25, 0.01, 0.04])
    x_f = np.linalg.solve(a + p_info, a @ x_s + p_info @ prior)
    assert np.abs(x_f - x_s).max() > 0.01  # the prior pulled the fit far from the scan's motion
    g = 2.0 * np.linalg.inv(a)  # the points' gradient covariance (any positive definite)
    fit = Refinement(
        x_f, 100, 1.0, 1.0, information=a, prior_information=p_info, start=x_f, prior=prior,
        gradient_covariance=g,
    )  # fmt: skip
    unc = Uncertainty(CFG.covariance, CFG.gate)
    for t_prev in (np.zeros(3), np.array([0.4, -0.1, 0.7])):
        out = unc.scan_only(fit, t_prev)
        assert out is not None
        inc, cov = out
        np.testing.assert_allclose(inc, relative(t_prev, x_s), atol=1e-12)
        jb = compose_jacobians(t_prev, inc)[1]
        a_inv = np.linalg.inv(a)
        expected = local(jb.T @ (a_inv @ g @ a_inv) @ jb, float(inc[2])) + unc.floor
        np.testing.assert_allclose(cov, expected, rtol=1e-9, atol=1e-15)
    # a heading wrapped across ±π in the prior changes nothing
    wrapped = replace(fit, prior=prior + np.array([0.0, 0.0, 2.0 * math.pi]))
    out = unc.scan_only(wrapped, np.zeros(3))
    assert out is not None
    np.testing.assert_allclose(out[0], x_s, atol=1e-9)
    # where the points do not fix the motion (a corridor held, or no information): nothing
    assert unc.scan_only(replace(fit, hold_information=p_info), np.zeros(3)) is None
    assert unc.scan_only(replace(fit, information=np.diag([1e3, 0.0, 1e3])), np.zeros(3)) is None


def odometry_run(in_refinement: bool, n: int = 160) -> Positioner:
    """A robot on an arc in a furnished room with a precise 360° scanner and odometry noisier
    than the scans (1.5 cm and 0.3° per 0.1 m step), the learned prior everywhere or not."""
    world = sim.furnished_room(2)
    truth = sim.arc_path(Pose2D(-1.5, -0.8, 0.1), n, 0.1, 1.5)
    rng = np.random.default_rng(3)
    odom = sim.drifting_odometry(truth, noise_std=(0.015, 0.3), rng=rng)
    pos = Positioner(CFG.with_overrides({"odometry_noise": {"in_refinement": in_refinement}}))
    for k, (p, o) in enumerate(zip(truth, odom)):
        pos.update(sim.simulate_scan(world, p, scanner(0.005, 360, 360.0), rng, stamp=0.2 * k), o)
    return pos


def test_the_learned_prior_does_not_teach_the_odometry_its_own_weight() -> None:
    """With the learned odometry as the refinement's prior, the noise is still learned from
    the scan's own motion: it does not shrink toward its floor (the fused motion would agree
    with the odometry because it was pulled there), but stays where the prior-free run puts
    it, near the odometry's true noise (1.5 cm per 0.1 m step: 4.7 cm per √m)."""
    free, fused = odometry_run(False).odometry_noise, odometry_run(True).odometry_noise
    assert fused.warm and free.warm
    true_t = 0.015 / math.sqrt(0.1)
    assert free.alpha_translation == pytest.approx(true_t, rel=0.35)
    assert fused.alpha_translation == pytest.approx(free.alpha_translation, rel=0.2)
    assert fused.alpha_rotation == pytest.approx(free.alpha_rotation, rel=0.2)
    floor = CFG.odometry_noise.min_translation_per_sqrt_m
    assert fused.alpha_translation > 5.0 * floor
    assert not fused.better_than_matching and not fused.trusted  # the scans are the better


@given(
    st.lists(st.floats(allow_nan=False, allow_infinity=False, width=32), max_size=80),
    st.integers(1, 12),
)
def test_running_window_median_is_numpy_median(values, maxlen):
    from collections import deque

    from fuzzypos.pipeline._window import Window, median_of

    window, plain = Window(maxlen), deque(maxlen=maxlen)
    for v in values:
        window.append(v)
        plain.append(v)
        assert list(window) == list(plain)
        expected = float(np.median(np.array(plain)))
        assert window.median() == expected == median_of(plain)


@given(st.lists(st.one_of(st.floats(-10, 10), st.just(math.nan)), max_size=40), st.integers(1, 9))
def test_running_window_median_with_nan_is_the_sorted_median(values, maxlen):
    from collections import deque

    from fuzzypos.pipeline._window import Window, median_of

    window, plain = Window(maxlen), deque(maxlen=maxlen)
    for v in values:
        window.append(v)
        plain.append(v)
        np.testing.assert_equal(window.median(), median_of(plain))


@given(
    st.lists(st.floats(-10, 10), min_size=1, max_size=60),
    st.integers(1, 12),
    st.floats(0.0, 1.0),
)
def test_running_window_quantile_is_numpy_s_higher_quantile(values, maxlen, q):
    from collections import deque

    from fuzzypos.pipeline._window import Window, quantile_of

    window, plain = Window(maxlen), deque(maxlen=maxlen)
    for v in values:
        window.append(v)
        plain.append(v)
        expected = float(np.quantile(np.array(plain), q, method="higher"))
        assert window.quantile(q) == expected == quantile_of(plain, q)


def logger_stamps(n: int, period: float = 0.2, flush: float = 0.6) -> list[float]:
    """Scans taken every ``period`` s but stamped when a logger's buffer is written, every
    ``flush`` s (a millisecond apart within a write): steps of 1 ms and of ``flush`` s, the
    bursts of intel's logger stamps."""
    out = []
    for k in range(n):
        t = period * k
        written = math.ceil(t / flush + 1e-9) * flush
        out.append(written + 0.001 * (round(t / period) % round(flush / period)))
    return out


def test_bursts_of_logger_stamps_are_not_gaps_but_a_gap_is() -> None:
    """Stamps that come in bursts: the steps' spread is usual (the 90th percentile is the
    usual period), so the odometry is never stale; a 3 s gap after them still is. Taken as
    the median (1 ms), every write of the buffer would have looked like a gap."""
    from fuzzypos.pipeline import OdometryPrior

    stamps = logger_stamps(120)
    stamps += [stamps[-1] + 3.0 + 0.2 * k for k in range(3)]
    odo = [Pose2D(0.05 * k, 0.0, 0.0) for k in range(len(stamps))]

    def stale(quantile: float) -> list[float]:
        prior = OdometryPrior(CFG.odometry, CFG.odometry_noise.stale_periods, quantile)
        prior.start(stamps[0], odo[0])
        return [prior.predict(t, o).stale for t, o in zip(stamps[1:], odo[1:])]

    usual = stale(CFG.odometry_noise.stale_quantile)
    assert usual[-3] > 1.0 and not any(usual[:-3]) and not any(usual[-2:])
    assert sum(s > 0.0 for s in stale(0.5)[:-3]) > 30


def test_bursts_of_logger_stamps_leave_the_covariances_as_even_stamps_do() -> None:
    """The same simulated arc stamped evenly and by a logger's bursts: the covariance of each
    scan relative to its keyframe is the same, not that of odometry stale for half a second
    at every write."""
    world = sim.furnished_room(1)
    truth = sim.arc_path(Pose2D(-1.0, -0.5, 0.2), 60, 0.03, 1.0)
    rng = np.random.default_rng(0)
    scans = [sim.simulate_scan(world, p, scanner(0.005, 360, 360.0), rng) for p in truth]

    def spread(stamps: list[float], config: Config) -> float:
        pos = Positioner(config)
        est = [pos.update(replace(s, stamp=t), o) for s, t, o in zip(scans, stamps, truth)]
        return max(float(np.sqrt(e.keyframe_covariance[0, 0])) for e in est)

    even = spread([0.2 * k for k in range(60)], CFG)
    bursts = spread(logger_stamps(60), CFG)
    assert bursts == pytest.approx(even, rel=0.05)
    as_median = CFG.with_overrides({"odometry_noise": {"stale_quantile": 0.5}})
    assert spread(logger_stamps(60), as_median) > 3.0 * even
