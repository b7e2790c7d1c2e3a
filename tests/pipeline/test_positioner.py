"""Tests of the per-scan loop (:class:`fuzzypos.positioner.Positioner`) on simulated scans.

Motion recovery from two scans (the issue's accuracy targets), a trajectory with drifting
odometry, running without odometry, and bad input (degraded scans that fall back to the prior).
Every random draw comes from a fixed seed, so every number below is reproducible.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from functools import cache

import numpy as np
import pytest

from fuzzypos import sim
from fuzzypos.config import Config
from fuzzypos.geometry import Pose2D, compose, relative
from fuzzypos.pipeline import Estimate, Positioner, Reason
from fuzzypos.scan import LaserScan

WORLD = sim.furnished_room(0)


def scanner(noise: float = 0.0) -> sim.ScannerModel:
    """The 180-beam, 180° scanner of the tests (8 m range)."""
    return sim.ScannerModel(n_beams=180, range_max=8.0, range_noise_std=noise)


def config(name: str) -> Config:
    """``default``, a preset, or a variant of the default: ``points-first`` (the paper's
    point pairing first, lines refining its motion) or ``points-only`` (no line matching)."""
    if name == "points-first":
        return Config().with_overrides({"matching": {"lines_first": False}})
    if name == "points-only":
        return Config().with_overrides({"matching": {"match_lines": False}})
    return Config() if name == "default" else Config.preset(name)


def pose_error(true: np.ndarray, est: np.ndarray) -> tuple[float, float]:
    """(translational error in metres, |rotational error| in degrees) of ``est`` against
    ``true``."""
    e = relative(np.asarray(true, float), np.asarray(est, float))
    return float(math.hypot(e[0], e[1])), abs(math.degrees(float(e[2])))


# ---------------------------------------------------------------------------------------------
# 1. motion recovery from two scans
# ---------------------------------------------------------------------------------------------
N_TRIALS = 60
TRIAL_SEED = 20240601
NOISE_SEED = 7


@cache
def motion_trials(noise: float) -> tuple[sim.MotionTrial, ...]:
    """``N_TRIALS`` random rigid motions (|t| <= 0.5 m, |θ| <= 20°) from random start poses in
    the free central area (|x| <= 1.5, |y| <= 1, any heading) of ``furnished_room(0)``.

    Only motions where BOTH poses see at least two corners are kept:
    ``sim.visible_corners(world, pose, scanner)`` must have >= 2 rows for the start and the end
    pose (that is how these tests make sure the two poses see two corners;
    :func:`fuzzypos.sim.random_motions` does it). The odometry increment is the true increment
    composed with an error uniform within ±7 cm per axis (so at most 10 cm) and ±5°.
    """
    return tuple(sim.random_motions(WORLD, scanner(noise), N_TRIALS, TRIAL_SEED))


@dataclass(frozen=True)
class MotionErrors:
    trans: np.ndarray  # metres, per trial
    rot: np.ndarray  # degrees, per trial
    odo_trans: np.ndarray
    odo_rot: np.ndarray
    degraded: np.ndarray


@cache
def motion_errors(config_name: str, noise: float) -> MotionErrors:
    """Errors of the increment estimated from two scans, for every trial of
    :func:`motion_trials`."""
    sc = scanner(noise)
    cfg = config(config_name)
    out = []
    for i, tr in enumerate(motion_trials(noise)):
        rng = np.random.default_rng((NOISE_SEED, i))
        s0 = sim.simulate_scan(WORLD, tr.start, sc, rng, stamp=0.0)
        s1 = sim.simulate_scan(WORLD, tr.end, sc, rng, stamp=1.0)
        pos = Positioner(cfg)
        pos.update(s0, Pose2D(0.0, 0.0, 0.0))
        est = pos.update(s1, Pose2D.from_array(tr.odometry))
        et, er = pose_error(tr.increment, est.increment.as_array())
        ot, orot = pose_error(tr.increment, tr.odometry)
        out.append((et, er, ot, orot, est.degraded))
    a = np.array(out, dtype=float)
    return MotionErrors(a[:, 0], a[:, 1], a[:, 2], a[:, 3], a[:, 4].astype(bool))


def summary(e: MotionErrors) -> str:
    return (
        f"trans mm: median {1e3 * np.median(e.trans):.3f} "
        f"p90 {1e3 * np.percentile(e.trans, 90):.3f} "
        f"max {1e3 * e.trans.max():.3f}; rot deg: median {np.median(e.rot):.4f} "
        f"p90 {np.percentile(e.rot, 90):.4f} max {e.rot.max():.4f}"
    )


def test_trials_are_what_they_claim() -> None:
    for tr in motion_trials(0.0):
        assert abs(tr.start[0]) <= 1.5 and abs(tr.start[1]) <= 1.0
        assert math.hypot(tr.increment[0], tr.increment[1]) <= 0.5
        assert abs(tr.increment[2]) <= math.radians(20.0)
        np.testing.assert_allclose(relative(tr.start, tr.end), tr.increment, atol=1e-12)
        et, er = pose_error(tr.increment, tr.odometry)
        assert et <= 0.1 and er <= 5.0
        for pose in (tr.start, tr.end):
            assert len(sim.visible_corners(WORLD, pose, scanner())) >= 2


@pytest.mark.parametrize(
    ("noise", "max_trans", "max_rot_deg"),
    [(0.0, 0.001, 0.05), (0.01, 0.02, 0.5)],
    ids=["noise-free", "1cm-noise"],
)
def test_default_recovers_every_motion(noise: float, max_trans: float, max_rot_deg: float) -> None:
    """The issue's targets, for every trial: noise-free within 1 mm and 0.05°, with 1 cm range
    noise within 2 cm and 0.5°, and no trial degraded.

    The trials (:func:`motion_trials`) keep only motions where both poses see at least two
    corners: ``sim.visible_corners`` has >= 2 rows for the start and for the end pose.

    Measured (60 trials, the seeds above, default Config()): noise-free median 0.004 mm,
    max 0.072 mm and 0.0026°; with 1 cm noise median 5.6 mm / 0.062°, p90 10.2 mm / 0.19°,
    max 16.2 mm / 0.33°.
    """
    e = motion_errors("default", noise)
    assert not e.degraded.any(), summary(e)
    assert e.trans.max() < max_trans, summary(e)
    assert e.rot.max() < max_rot_deg, summary(e)


@pytest.mark.parametrize("noise", [0.0, 0.01])
def test_points_first_meets_the_same_targets(noise: float) -> None:
    """With the paper's point pairing first and line matching refining its motion, the
    targets hold too (the path the default takes where the lines give no motion)."""
    e = motion_errors("points-first", noise)
    limit = (0.001, 0.05) if noise == 0 else (0.02, 0.5)
    assert not e.degraded.any(), summary(e)
    assert e.trans.max() < limit[0] and e.rot.max() < limit[1], summary(e)


@pytest.mark.parametrize("noise", [0.0, 0.01])
def test_point_refinements_beat_the_paper_preset(noise: float) -> None:
    """Without line matching, the point features with our refinements (refined corners, no
    break points, consensus, least squares) beat the paper's way and odometry on average.
    Measured means: noise-free 4.4 mm / 0.36°, 1 cm noise 24.5 mm / 0.66° (paper 32.6 mm and
    35.7 mm; odometry 50.7 mm / 2.90°)."""
    e = motion_errors("points-only", noise)
    paper = motion_errors("paper", noise)
    assert e.trans.mean() < paper.trans.mean() < e.odo_trans.mean(), summary(e)
    assert e.rot.mean() < e.odo_rot.mean(), summary(e)


@pytest.mark.parametrize("noise", [0.0, 0.01])
def test_paper_preset_beats_odometry(noise: float) -> None:
    """The paper's method improves on the odometry it starts from, on average over the trials.

    Measured means: paper 36.5 mm, 0.55° noise-free and 34.9 mm, 0.61° with 1 cm noise;
    odometry 50.7 mm, 2.90°.
    """
    e = motion_errors("paper", noise)
    assert e.trans.mean() < e.odo_trans.mean(), summary(e)
    assert e.rot.mean() < e.odo_rot.mean(), summary(e)


@pytest.mark.parametrize("noise", [0.0, 0.01])
def test_default_beats_paper_preset(noise: float) -> None:
    """The default is the better configuration: lower mean error than the paper preset.

    Measured means: default 3.6 mm, 0.034° noise-free (paper 36.5 mm, 0.55°); with 1 cm noise
    default 34.2 mm, 0.45° against paper 34.9 mm, 0.61° -- a thin margin in translation,
    because of a few gross failures of the default (one of 744 mm).
    """
    d = motion_errors("default", noise)
    p = motion_errors("paper", noise)
    assert d.trans.mean() < p.trans.mean(), f"default {summary(d)}\npaper {summary(p)}"
    assert d.rot.mean() < p.rot.mean(), f"default {summary(d)}\npaper {summary(p)}"


# ---------------------------------------------------------------------------------------------
# 2. a trajectory with drifting odometry
# ---------------------------------------------------------------------------------------------
def arc_poses(
    n: int = 60,
    start: tuple[float, float, float] = (-1.6, -1.2, 0.0),
    step: float = 0.05,
    turn_deg: float = 1.0,
) -> list[np.ndarray]:
    """A gentle arc: ``step`` metres forward and ``turn_deg`` left per scan."""
    poses = [np.array(start, dtype=float)]
    for _ in range(n - 1):
        poses.append(compose(poses[-1], [step, 0.0, math.radians(turn_deg)]))
    return poses


def drifting_odometry(
    poses: list[np.ndarray], scale: float = 1.03, extra_turn_deg: float = 0.2
) -> list[Pose2D]:
    """Odometry from the first true pose whose every increment is the true one with its
    translation scaled by ``scale`` and ``extra_turn_deg`` more rotation."""
    odo = [poses[0]]
    for a, b in itertools.pairwise(poses):
        u = relative(a, b)
        odo.append(
            compose(odo[-1], [scale * u[0], scale * u[1], u[2] + math.radians(extra_turn_deg)])
        )
    return [Pose2D.from_array(o) for o in odo]


@cache
def arc_run(keep_features: bool) -> tuple[list[np.ndarray], list[Pose2D], list[Estimate]]:
    poses = arc_poses()
    scans = sim.simulate_scans(WORLD, poses, scanner(0.01), np.random.default_rng(11))
    odoms = drifting_odometry(poses)
    return poses, odoms, Positioner().run(scans, odoms, keep_features=keep_features)


def test_arc_stays_in_the_free_area() -> None:
    for p in arc_poses():
        assert abs(p[0]) <= 2.0 and abs(p[1]) <= 1.5


def test_trajectory_final_error_below_a_third_of_odometry() -> None:
    poses, odoms, ests = arc_run(False)
    assert len(ests) == len(poses) == 60
    est_err = math.hypot(*(ests[-1].pose.as_array()[:2] - poses[-1][:2]))
    odo_err = math.hypot(*(odoms[-1].as_array()[:2] - poses[-1][:2]))
    assert odo_err > 0.2  # the odometry really drifts
    assert est_err < odo_err / 3.0, (est_err, odo_err)
    assert sum(e.degraded for e in ests) <= 3


def test_trajectory_first_estimate_and_composition() -> None:
    _, odoms, ests = arc_run(False)
    first = ests[0]
    assert first.pose == odoms[0]
    assert first.increment == Pose2D(0.0, 0.0, 0.0)
    assert not first.degraded
    assert [e.stamp for e in ests] == [float(k) for k in range(len(ests))]
    pose = odoms[0].as_array()
    for e in ests[1:]:
        pose = compose(pose, e.increment.as_array())
        np.testing.assert_allclose(e.pose.as_array(), pose, rtol=0, atol=1e-9)
        if not e.degraded:
            assert e.n_pairs >= 2


def test_run_keep_features() -> None:
    _, _, without = arc_run(False)
    _, _, with_ = arc_run(True)
    assert all(e.features is None for e in without)
    assert all(e.features is not None for e in with_)
    assert all(e.features.stamp == e.stamp for e in with_)
    # keeping the features changes nothing else
    for a, b in zip(without, with_):
        assert a.pose == b.pose and a.increment == b.increment and a.degraded == b.degraded


def test_update_returns_features() -> None:
    scans = sim.simulate_scans(WORLD, arc_poses(2), scanner())
    pos = Positioner()
    assert pos.pose is None
    e0 = pos.update(scans[0])
    e1 = pos.update(scans[1])
    assert e0.features is not None and e1.features is not None
    assert pos.pose == e1.pose


# ---------------------------------------------------------------------------------------------
# 3. no odometry
# ---------------------------------------------------------------------------------------------
def straight_poses(
    n: int, step: float, start: tuple[float, float, float] = (-1.0, -0.5, 0.3)
) -> list[np.ndarray]:
    return [compose(np.array(start), [k * step, 0.0, 0.0]) for k in range(n)]


# Measured: at most 41 mm and 0.69° off over the 30 scans (20 mm, 0.53° at the last one).
NO_ODOM_MAX_TRANS = 0.06  # m
NO_ODOM_MAX_ROT = 1.0  # degrees


def test_no_odometry_slow_straight_motion() -> None:
    """Without odometry the prior is the last estimated increment; 2 cm per scan over 30 scans."""
    poses = straight_poses(30, 0.02)
    scans = sim.simulate_scans(WORLD, poses, scanner(0.01), np.random.default_rng(5))
    ests = Positioner().run(scans)
    assert ests[0].pose == Pose2D(0.0, 0.0, 0.0)  # no odometry: the trajectory starts at the origin
    assert ests[1].prior == Pose2D(0.0, 0.0, 0.0)
    for prev, e in itertools.pairwise(ests[1:]):
        assert e.prior == prev.increment
    assert not any(e.degraded for e in ests)
    # compare in the frame of the first scan
    for p, e in zip(poses, ests):
        t, r = pose_error(relative(poses[0], p), e.pose.as_array())
        assert t < NO_ODOM_MAX_TRANS and r < NO_ODOM_MAX_ROT, (t, r)


# ---------------------------------------------------------------------------------------------
# 4./5. bad input: degraded estimates that fall back to the prior
# ---------------------------------------------------------------------------------------------
def blank(ranges: np.ndarray | list[float], like: LaserScan | None = None) -> LaserScan:
    """A scan with the 180-beam scanner's metadata and the given ranges (any number of beams)."""
    sc = scanner()
    return LaserScan(
        np.asarray(ranges, dtype=float),
        angle_min=sc.angle_min,
        angle_increment=sc.angle_increment,
        range_min=sc.range_min,
        range_max=sc.range_max,
        stamp=0.0 if like is None else like.stamp,
    )


BAD_SCANS = {
    "all NaN": np.full(180, np.nan),
    "all +inf": np.full(180, np.inf),
    "all -inf": np.full(180, -np.inf),
    "alternating +-inf": np.where(np.arange(180) % 2 == 0, np.inf, -np.inf),
    "all zeros": np.zeros(180),
    "all below range_min": np.full(180, 0.01),
    "all range_max (no return)": np.full(180, 8.0),
    "empty (0 beams)": np.zeros(0),
    "one valid beam": np.array([2.0]),
    "one NaN beam": np.array([np.nan]),
}


def assert_fell_back(prev: Estimate, e: Estimate, odom_inc: np.ndarray | None = None) -> None:
    """A degraded estimate: increment == prior (== the odometry increment), pose = prev ⊕ prior."""
    assert e.degraded
    np.testing.assert_array_equal(e.increment.as_array(), e.prior.as_array())
    if odom_inc is not None:
        np.testing.assert_allclose(e.prior.as_array(), odom_inc, rtol=0, atol=1e-12)
    np.testing.assert_allclose(
        e.pose.as_array(), compose(prev.pose.as_array(), e.prior.as_array()), rtol=0, atol=1e-12
    )


@pytest.mark.parametrize("name", list(BAD_SCANS))
def test_bad_scan_in_the_middle_is_degraded_and_the_run_continues(name: str) -> None:
    poses = straight_poses(5, 0.05)
    good = sim.simulate_scans(WORLD, poses, scanner())
    scans = list(good)
    scans[2] = blank(BAD_SCANS[name], like=good[2])
    odoms = [Pose2D.from_array(p) for p in poses]
    ests = Positioner().run(scans, odoms, keep_features=True)
    assert len(ests) == 5
    assert not ests[1].degraded
    assert_fell_back(ests[1], ests[2], relative(poses[1], poses[2]))
    assert ests[2].features is not None and len(ests[2].features.points_of_interest) == 0
    # scan 3 has nothing to pair with; from scan 4 on the scans are estimated again
    assert not ests[4].degraded
    t, r = pose_error(relative(poses[3], poses[4]), ests[4].increment.as_array())
    assert t < 0.005 and r < 0.1, (t, r)


@pytest.mark.parametrize("name", list(BAD_SCANS))
def test_bad_first_scan_does_not_raise(name: str) -> None:
    poses = straight_poses(4, 0.05)
    scans = [blank(BAD_SCANS[name])] + sim.simulate_scans(WORLD, poses[1:], scanner())
    odoms = [Pose2D.from_array(p) for p in poses]
    ests = Positioner().run(scans, odoms)
    assert ests[0].pose == odoms[0] and ests[0].increment == Pose2D()
    assert_fell_back(ests[0], ests[1], relative(poses[0], poses[1]))
    assert not ests[3].degraded


def test_invalid_beams_in_a_good_scan_are_not_used() -> None:
    poses = straight_poses(2, 0.05)
    s0, s1 = sim.simulate_scans(WORLD, poses, scanner())
    r = s1.ranges.copy()
    bad_values = [np.nan, np.inf, -np.inf, 0.0, 0.01, 8.0]  # 0.01 < range_min, 8.0 = range_max
    bad = np.arange(4, 180, 10)
    r[bad] = [bad_values[k % len(bad_values)] for k in range(bad.size)]
    s1 = s1.with_ranges(r)
    pos = Positioner()
    pos.update(s0, Pose2D.from_array(poses[0]))
    e = pos.update(s1, Pose2D.from_array(poses[1]))
    assert not e.degraded
    assert e.features is not None
    assert not np.isin(bad, e.features.beam_index).any()
    assert np.all(np.isfinite(e.features.points))
    t, rot = pose_error(relative(poses[0], poses[1]), e.increment.as_array())
    assert t < 0.005 and rot < 0.1, (t, rot)


@pytest.mark.parametrize("noise", [0.0, 0.01])
@pytest.mark.parametrize("with_odometry", [True, False])
def test_blind_scans_in_the_middle(with_odometry: bool, noise: float) -> None:
    """Scans 10-14 see nothing (every beam at range_max): degraded, falling back to the prior
    (the odometry increment, or without odometry the last increment), the run goes on, and the
    scans after the gap are estimated again (at the latest from the second good one, 16)."""
    n = 24
    poses = straight_poses(n, 0.03, start=(-1.2, -0.6, 0.2))
    scans = sim.simulate_scans(WORLD, poses, scanner(noise), np.random.default_rng(3))
    for k in range(10, 15):
        scans[k] = blank(np.full(180, 8.0), like=scans[k])
    odoms = drifting_odometry(poses) if with_odometry else None
    ests = Positioner().run(scans, odoms)
    assert len(ests) == n
    assert not any(e.degraded for e in ests[:10])
    for k in range(10, 15):
        if with_odometry:
            assert_fell_back(
                ests[k - 1], ests[k], relative(odoms[k - 1].as_array(), odoms[k].as_array())
            )
        else:
            assert_fell_back(ests[k - 1], ests[k], ests[k - 1].increment.as_array())
    assert not any(e.degraded for e in ests[16:])
    # measured after the gap: noise-free <= 0.2 mm and 0.01°; 1 cm noise <= 28 mm and 0.32°
    max_t, max_r = (0.001, 0.05) if noise == 0.0 else (0.05, 1.0)
    for k in range(16, n):
        t, r = pose_error(relative(poses[k - 1], poses[k]), ests[k].increment.as_array())
        assert t < max_t and r < max_r, (k, t, r)


def test_update_rejects_a_non_scan() -> None:
    pos = Positioner()
    scan = sim.simulate_scan(WORLD, Pose2D(), scanner())
    for bad in (None, "scan", scan.ranges, {"ranges": scan.ranges}):
        with pytest.raises(TypeError):
            pos.update(bad)  # type: ignore[arg-type]
    assert pos.pose is None  # nothing was consumed
    with pytest.raises(TypeError):  # ((x, y, θ) is odometry: the test below)
        pos.update(scan, {"x": 0.0, "y": 0.0, "theta": 0.0})  # type: ignore[arg-type]
    assert pos.pose is None
    pos.update(scan)
    assert pos.pose == Pose2D()


def test_run_with_too_few_odometry_poses() -> None:
    poses = straight_poses(4, 0.05)
    scans = sim.simulate_scans(WORLD, poses, scanner())
    odoms = [Pose2D.from_array(p) for p in poses[:2]]
    with pytest.raises(ValueError, match="odom"):
        Positioner().run(scans, odoms)
    with pytest.raises(ValueError, match="odom"):
        Positioner().run(scans, [])


def test_office_corridor_does_not_drift_along_the_corridor() -> None:
    """Down the simulated office's corridor (15 m, 300 scans, 1 cm noise) with odometry that
    over-reads 3 % and turns 0.15° a scan too much: the corridor's walls fix the heading and
    the sideways position; doorways, jambs and furniture fix the rest, and where they do not,
    the odometry keeps its say along the corridor. Measured: final error 0.14 m against
    odometry's 5.8 m."""
    truth = sim.arc_path(Pose2D(-9.0, 0.0, 0.0), 300, 0.05, 0.0)
    rng = np.random.default_rng(0)
    odom = sim.drifting_odometry(truth, 1.03, 0.15, (0.002, 0.05), rng)
    scans = sim.simulate_scans(sim.office(), truth, sim.ScannerModel(range_noise_std=0.01), rng=rng)
    est = Positioner().run(scans, odom)
    final = np.hypot(*(truth[-1].as_array()[:2] - est[-1].pose.as_array()[:2]))
    odo_final = np.hypot(*(truth[-1].as_array()[:2] - odom[-1].as_array()[:2]))
    assert not any(e.degraded for e in est)
    assert final < 0.2
    assert final < odo_final / 20


def test_every_estimate_says_why_it_is_what_it_is() -> None:
    """The first scan, standing still, a match and a fall-back each carry their reason (a
    string enum, equal to its value)."""
    room = sim.rectangular_room(8.0, 6.0)
    scanner = sim.ScannerModel(
        n_beams=360, field_of_view_deg=360.0, angle_min_deg=-180.0, range_max=20.0
    )
    poses = [Pose2D(0.0, 0.0, 0.0), Pose2D(0.0, 0.0, 0.0), Pose2D(0.1, 0.0, 0.0)]
    scans = [sim.simulate_scan(room, p, scanner, stamp=0.1 * k) for k, p in enumerate(poses)]
    empty = LaserScan(np.full(360, np.inf), -math.pi, math.radians(1.0), stamp=0.3)
    est = Positioner().run([*scans, empty], [*poses, Pose2D(0.2, 0.0, 0.0)])
    assert [e.reason for e in est] == [
        Reason.FIRST_SCAN,
        Reason.STANDING_STILL,
        Reason.MATCHED,
        Reason.TOO_FEW_FEATURES,
    ]
    assert est[3].degraded and not any(e.degraded for e in est[:3])
    assert est[1].reason == "standing still" and str(est[2].reason) == "matched"


def test_a_refined_estimate_is_matched_even_where_the_point_pairs_were_too_few(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Where the feature points paired but gave no pose and the refinement then fitted the
    scan, the estimate is matched (not degraded, refined), not "too few pairs"."""
    from fuzzypos.pipeline import FeatureMatch

    room = sim.rectangular_room(8.0, 6.0)
    scanner = sim.ScannerModel(
        n_beams=360, field_of_view_deg=360.0, angle_min_deg=-180.0, range_max=20.0
    )
    poses = [Pose2D(0.0, 0.0, 0.0), Pose2D(0.1, 0.05, 0.02)]
    scans = [sim.simulate_scan(room, p, scanner, stamp=0.1 * k) for k, p in enumerate(poses)]
    pos = Positioner(fused=False)  # (the staged calls, where the matcher's match is called)
    monkeypatch.setattr(
        pos.feature_matcher, "match", lambda *_: FeatureMatch(None, 3, Reason.TOO_FEW_PAIRS)
    )
    est = pos.run(scans, poses)
    assert est[1].refined and not est[1].degraded and est[1].n_pairs == 3
    assert est[1].reason is Reason.MATCHED


def test_the_positioners_fast_estimate_is_the_constructors() -> None:
    """``Estimate._trusted`` (the positioner's way round the frozen ``__init__``) builds the
    very estimate the constructor does: the same fields, frozen, and ``replace`` works."""
    import dataclasses

    from fuzzypos.pipeline.estimate import Estimate, Reason

    values = dict(
        stamp=1.5, pose=Pose2D(1.0, 2.0, 0.5), increment=Pose2D(0.1, 0.0, 0.01),
        prior=Pose2D(0.1, 0.0, 0.0), n_pairs=7, degraded=False, features=None,
        reason=Reason.MATCHED, odometry_rejected=False, refined=True,
        covariance=np.eye(3), keyframe_covariance=2.0 * np.eye(3), gate=0.25, keyframe=True,
    )  # fmt: skip
    fast, slow = Estimate._trusted(**values), Estimate(**values)
    assert [f.name for f in dataclasses.fields(Estimate)] == list(values)
    for name in values:
        assert getattr(fast, name) is getattr(slow, name)
    assert vars(fast) == vars(slow)
    with pytest.raises(dataclasses.FrozenInstanceError):
        fast.n_pairs = 3  # type: ignore[misc]
    assert dataclasses.replace(fast, features=None).n_pairs == 7


def test_update_takes_the_odometry_as_x_y_theta() -> None:
    """Issue 35: ``update(scan, (x, y, θ))`` (a tuple, a list or a 1-D array) positions as a
    Pose2D does; anything else is refused, naming ``odom``."""
    room = sim.rectangular_room(8.0, 6.0)
    scanner = sim.ScannerModel(
        n_beams=360, field_of_view_deg=360.0, angle_min_deg=-180.0, range_max=20.0
    )
    poses = [Pose2D(0.0, 0.0, 0.0), Pose2D(0.1, 0.02, 0.05), Pose2D(0.2, 0.03, 0.1)]
    scans = [sim.simulate_scan(room, p, scanner, stamp=0.1 * k) for k, p in enumerate(poses)]
    want = [e.pose for e in Positioner().run(scans, poses)]
    for as_odometry in (tuple, list, np.array):
        pos = Positioner()
        got = [pos.update(s, as_odometry([p.x, p.y, p.theta])) for s, p in zip(scans, poses)]
        assert [e.pose for e in got] == want, as_odometry
        assert [e.reason for e in got] == [Reason.FIRST_SCAN, Reason.MATCHED, Reason.MATCHED]
    bad = [
        ("0.1", TypeError, r"odom must be a Pose2D or \(x, y, theta\), got str"),
        ({"x": 0.1}, TypeError, "got dict"),
        (np.zeros((3, 1)), TypeError, "got ndarray"),
        ((0.1, 0.2), ValueError, r"odom must be \(x, y, theta\), got 2 values"),
        ((0.1, math.nan, 0.0), ValueError, "odom: Pose2D.y must be finite"),
        ([0.1, "y", 0.0], ValueError, "odom: Pose2D.y must be a number"),
    ]
    for odom, error, message in bad:
        with pytest.raises(error, match=message):
            Positioner().update(scans[0], odom)  # type: ignore[arg-type]


def _section_reads(source: str) -> list[str]:
    """Where ``source`` reads a setting of a config section (``cfg.<section>.<name>`` or
    ``….config.<section>.<name>``, a section a field of :class:`Config`), as
    ``section.name``."""
    import ast
    import dataclasses

    sections = {f.name for f in dataclasses.fields(Config)}

    def is_config(node: ast.expr) -> bool:
        if isinstance(node, ast.Name):
            return node.id in ("cfg", "config")
        return isinstance(node, ast.Attribute) and node.attr == "config"

    return [
        f"{node.value.attr}.{node.attr}"
        for node in ast.walk(ast.parse(source))
        if isinstance(node, ast.Attribute)
        and isinstance(node.value, ast.Attribute)
        and node.value.attr in sections
        and is_config(node.value.value)
    ]


def test_the_positioner_reads_no_setting_of_its_stages_sections() -> None:
    """The positioner hands each config section to its stage (``cfg.gate``) and reads none
    of their settings itself (``cfg.gate.enabled``), nor does the step from the keyframe
    (which hands the features' sections on whole); the stages read their own."""
    import inspect

    from fuzzypos.pipeline import positioner, step

    assert _section_reads("Stage(cfg.gate, self.config.refinement, self.gate.enabled)") == []
    assert _section_reads("if self.config.gate.enabled and cfg.refinement.enabled: pass") == [
        "gate.enabled", "refinement.enabled",
    ]  # fmt: skip
    assert _section_reads(inspect.getsource(positioner)) == []
    assert _section_reads(inspect.getsource(step)) == []
